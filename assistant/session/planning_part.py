"""Steps 5 and 6: the world model, exploration, planning and execution.

A part of the `Session`, composed (`Session.planning`): it owns the world model with its
planner, executor and explorer, and how the last run ended; it reaches the rest of the session
only through the parts' contract (`PartContract`)."""

from __future__ import annotations

import time
from concurrent.futures import Future
from dataclasses import replace
from typing import Any

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.links.link import RobotLink
from assistant.mission.motion import Trajectory
from assistant.progress import Progress
from assistant.session.contract import PartContract
from assistant.session.events import (
    CollisionRecorded,
    ExecutionFinished,
    Notice,
    PlanReady,
    SceneChanged,
)
from assistant.session.run_state import RunState, run_state
from assistant.session.types import (
    EDIT_MISSION,
    OccupiedCells,
    SessionError,
    _Backend,
    _report_json,
)
from assistant.session.world_settings import WorldSettings

Array = np.ndarray


class PlanningPart:
    """Steps 5 and 6: the world model, exploration, planning and execution."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: The planning back end (world model, roadmap, planner, executor, explorer), built
        #: on demand, and the obstacles it was built for (`world_ready`).
        self.backend: _Backend | None = None
        self.backend_key: tuple | None = None
        #: How the last run ended (`ExecutionFinished.summary`); None when planned since.
        self.last_run: dict | None = None
        #: The world model's and the run's settings (saved with the session).
        self.world_settings = WorldSettings()
        #: The plan and its report (saved with the session; an edit clears them: the
        #: core's `action`).
        self.trajectory: Trajectory | None = None
        self.plan_report: dict[str, Any] | None = None
        #: Every posture where a collision was indicated, in order: the one record of
        #: indications (saved with the session; a world model learns them, a rebuilt one
        #: again, and keeps only what they taught). Added to only by `record_collision`,
        #: taken from only by `forget_indication`.
        self.recorded_collisions: list[Array] = []

    def record_collision(self, q: Array, source: str, *, learnt_by_run: bool) -> None:
        """Record a collision indication at posture `q` (source "operator" or "robot"):
        counted, saved, then announced (`CollisionRecorded`, "Collision #n recorded").
        `learnt_by_run`: a run's executor or explorer reported it and has fed its world
        model already; else (the robot standing) the current world model learns it here."""
        q = np.asarray(q, float).copy()
        with self._core.lock:
            self.recorded_collisions.append(q)
            self._core.counters.collision_indications += 1
            if not learnt_by_run and self.backend is not None:
                self.backend.add_collision(q)
            self._core.saving.autosave()  # saved before the page says "Collision #n recorded"
        self._core.bus.emit(CollisionRecorded(q.copy(), self._core.counters.collision_indications,
                                              source))

    @property
    def world_ready(self) -> bool:
        """The world model is built for the current obstacles."""
        return self.backend is not None and self.backend_key == self._core.obstacles_key()

    # ================================================================== 5. explore / world
    def start_build_world(self) -> Future:
        """Reachability table (cached on disk), CAD rasterisation and the Voronoi roadmap."""
        return self._core.run_busy("build the world model", self._build_world,
                                   ("explore", "plan", "teach", "place"))

    def set_world_settings(self, **changes: Any) -> dict:
        """Change world settings (`WorldSettings`: resolution_mm, joint_samples, memory_mb,
        store, clearance_mm; the run's bound max_indications, planning_budget_s); the world
        model is rebuilt on the next build or plan (not for the run's bound)."""
        try:
            settings = self.world_settings.changed(**changes)
        except (TypeError, ValueError) as exc:
            raise SessionError(str(exc)) from None
        with self._core.lock:
            self.world_settings = settings
            self._core.saving.autosave()
        self._core.emit_state()
        return settings.to_json()

    def build_world(self) -> dict:
        return self.start_build_world().result()

    def _build_world(self, progress: Progress) -> dict:
        from assistant.roadmap.planner import RoadmapPlanner
        from assistant.world.model import WorldModel

        t0 = time.perf_counter()
        robot = self._core.robot
        obstacles = self._core.cell.collision_objects_in_base()
        key = self._core.obstacles_key()
        world = WorldModel(robot, obstacles, self.world_settings.world_config(robot))
        world.anchors = self._world_anchors()
        checker = CollisionChecker(robot, obstacles)
        roadmap = RoadmapPlanner(robot, checker, world)
        report = roadmap.build(progress.sub(0.0, 0.9))
        for q in self.recorded_collisions:  # what the operator taught us stays known
            progress.check()
            roadmap.add_collision(q)
        backend = _Backend(world, roadmap, checker)
        with self._core.lock:
            self.backend, self.backend_key = backend, key
        self._core.bus.emit(SceneChanged("world"))
        return {"seconds": time.perf_counter() - t0,
                "table_from_cache": report.world.table_from_cache,
                "road_cells": report.road_cells, "regions": report.regions,
                "free_cells": report.world.leaves_free}

    def _world_anchors(self) -> np.ndarray:
        """Postures the world's joint positions gather around: the current one and each
        taught location's (as taught from the robot, else by IK from the current one)."""
        from assistant.transforms import inv_T

        robot = self._core.robot
        q0 = self._core.current_joints()
        out = [q0]
        T_base_world = inv_T(self._core.T_world_base())
        for loc in self._core.locations.values():
            if loc.q_hint is not None and np.shape(loc.q_hint) == (robot.dof,):
                out.append(np.asarray(loc.q_hint, dtype=float))
                continue
            res = robot.ik(T_base_world @ np.asarray(loc.T_world_tool, dtype=float), seed=q0)
            if res.ok:
                out.append(np.asarray(res.best(q0), dtype=float))
        return np.array(out)

    def _backend(self, progress: Progress | None = None) -> _Backend:
        """The world model for the current obstacles, (re)built if stale."""
        if not self.world_ready:
            self._build_world(progress or Progress())
        assert self.backend is not None
        return self.backend

    def _mission_planner(self, backend: _Backend) -> Any:
        from assistant.planning import MissionPlanner

        config = self.planner_config()
        if backend.planner is None or backend.planner.config != config:
            backend.planner = MissionPlanner(self._core.robot,
                                             self._core.cell.collision_objects_in_base(),
                                             backend.world, backend.roadmap, backend.checker,
                                             config)
        return backend.planner

    def planner_config(self) -> Any:
        """The planner's defaults; Bezier chains become SPLINE moves when the export dialect
        writes splines (KRL SPLINE ... ENDSPLINE), else linear moves within the tolerance."""

        from assistant.export import get_dialect
        from assistant.planning.config import MissionPlannerConfig
        from assistant.trajectory.application import BezierMode

        config = MissionPlannerConfig()
        try:
            splines = bool(getattr(get_dialect(self._core.export_dialect), "spline", False))
        except (KeyError, ValueError):
            splines = False
        if splines:
            config = replace(config, application=replace(config.application,
                                                         bezier_mode=BezierMode.SPLINE))
        return config

    # ================================================================== 6. plan & execute
    def start_plan(self) -> Future:
        """Plan the mission in the known world (CAD + recorded collisions)."""
        return self._core.run_busy("plan the mission", self._plan, ("plan", "explore", "export"))

    def plan(self) -> dict:
        return self.start_plan().result()

    def _plan(self, progress: Progress) -> dict:
        t0 = time.perf_counter()
        self._core.start_posture.require_free()
        self.last_run = None  # planned again: the last run's outcome is history
        backend = self._backend(progress.sub(0.0, 0.3, "world model"))
        planner = self._mission_planner(backend)
        plan = planner.plan_mission(self._core.teaching.resolved_mission(),
                                    self._core.T_world_base(),
                                    self._core.current_joints(),
                                    progress.sub(0.3, 1.0, "plan"))
        with self._core.lock:
            self._core.counters.planning_time_s += time.perf_counter() - t0
            if not plan.ok:
                self.trajectory, self.plan_report, self._core.program = None, None, None
                raise SessionError(f"no plan: {plan.reason}")
        short = self._clearance_notes(plan, backend)
        with self._core.lock:
            self.trajectory = plan.trajectory
            self.plan_report = _report_json(plan.report)
            self.plan_report["clearance_required_mm"] = self.world_settings.clearance_mm
            self.plan_report["clearance_shortfalls"] = short
            if short:
                self.plan_report["description"] += "\n  clearance: " + "; ".join(short)
            self._core.program = None
            self._core.saving.autosave()  # saved before PlanReady shows it
        for line in short:
            self._core.bus.emit(Notice(f"Closer than the required clearance: {line}"))
        self._core.bus.emit(PlanReady(dict(self.plan_report)))
        return dict(self.plan_report)

    def _clearance_notes(self, plan: Any, backend: _Backend) -> list[str]:
        """Each transfer closer to a known obstacle than `WorldSettings.clearance_mm`: where
        and by how much (`planning.clearance`)."""
        from assistant.planning.clearance import clearance_shortfalls

        found = clearance_shortfalls(plan.pieces, backend.checker,
                                     self.world_settings.clearance_mm / 1000.0,
                                     self._core.T_world_base())
        return [f.describe() for f in found]

    def start_execute(self) -> Future:
        """Drive the mission on the robot; collisions (button or hidden obstacle) are learnt,
        the plan repaired and resumed. Ends with a verified final plan ready to export."""
        return self._core.run_busy("execute the mission", self._execute, ("plan",), moving=True)

    def execute(self) -> dict:
        return self.start_execute().result()

    def resume_execution(self) -> Future:
        """Continue after a lost link or a stop, re-planning from where the robot is."""
        return self._core.run_busy("resume the mission", self._resume, ("plan",), moving=True)

    def run_state(self) -> RunState:
        """The run's one state and its sentence (`session.run_state`)."""
        m = self._core.machine
        setup = self._core.setup
        halts = setup.halts_this_run if setup.halted and m.mode.value == "moving" else 0
        return run_state(m.mode.value, m.busy_task, halts, self.trajectory is not None,
                         self.last_run, self.final_driven())

    def start_drive_final(self) -> Future:
        """Drive the final program once on the robot, from where it stands to the program's
        start and through it (after a completed run; the operator starts it)."""
        return self._core.run_busy("drive the final program", self._drive_final, ("plan",),
                                   moving=True)

    def drive_final(self) -> dict:
        return self.start_drive_final().result()

    def final_driven(self) -> bool | None:
        """None without a final program to drive; else whether it was driven on the robot
        without an indication."""
        ex = self._backend_executor()
        rep = None if ex is None else ex.report
        if rep is None or rep.final_plan is None or not rep.final_plan.ok:
            return None
        return bool(rep.final_validated)

    def _drive_final(self, progress: Progress) -> dict:
        ex = self._backend_executor()
        if ex is None or ex.report.final_plan is None:
            raise SessionError("no final program to drive: execute the mission first")
        if ex.link is not self._core.setup.link():
            raise SessionError("the link changed since the run: execute the mission again")
        t0 = time.perf_counter()
        report = ex.drive_final(progress.sub(0.0, 1.0, "final program"))
        return self._after_execution(report, time.perf_counter() - t0)

    def _backend_executor(self) -> Any:
        """The executor of the last run, if the world it ran in is still the current one."""
        backend = self.backend if self.world_ready else None
        return None if backend is None else backend.executor

    def _executor(self, backend: _Backend, link: RobotLink) -> Any:
        from assistant.planning import MissionExecutor

        ex = backend.executor
        if ex is None or ex.link is not link:
            if ex is not None:
                ex.detach()
            ex = MissionExecutor(self._mission_planner(backend), link)
            backend.executor = ex
        ws = self.world_settings
        ex.config = replace(ex.config, max_indications=int(ws.max_indications),
                            max_planning_seconds=float(ws.planning_budget_s))
        return ex

    def forget_indication(self, number: int) -> dict:
        """Forget collision indication `number` (from 1): what it taught leaves the world
        model, so a plan may pass there again (the operator knows nothing is there), and the
        indications that taught it leave the record, so no world model learns them again.
        Numbered as a re-plan and `learnt_indications` name what the world model learnt;
        with no world model built for the cell, as the record holds them (a world built
        from it numbers them so)."""
        n = int(number)
        b = self.backend if self.world_ready else None
        count = len(self.recorded_collisions) if b is None else len(b.world.collisions)
        if not 1 <= n <= count:
            raise SessionError(f"no indication {number} to forget: {count} learnt")
        if self._core.machine.busy_task:
            raise SessionError(f"wait for '{self._core.machine.busy_task}' to finish first")
        with self._core.lock:
            if b is None:
                del self.recorded_collisions[n - 1]
            else:
                made = self._recorded_behind(b.world, n - 1)
                b.roadmap.forget_collision(n - 1)
                self.recorded_collisions[:] = [q for r, q in enumerate(self.recorded_collisions)
                                               if r not in made]
            left = len(self.recorded_collisions) if b is None else len(b.world.collisions)
            self._core.saving.autosave()
        self._core.bus.emit(SceneChanged("world"))
        return {"forgotten": n, "learnt": left}

    def _recorded_behind(self, world: Any, i: int) -> set[int]:
        """Indices into the record of the indications that made world entry `i` (its own
        and those that grew its region): each found by its posture, bit for bit, the k-th
        recorded at a posture matched to that posture's k-th entry (`learnt_from`)."""
        made = set()
        for r, q in enumerate(self.recorded_collisions):
            again = sum(np.array_equal(p, q) for p in self.recorded_collisions[:r])
            if world.learnt_from(q, again) == i:
                made.add(r)
        return made

    def _execute(self, progress: Progress) -> dict:
        backend = self._backend(progress.sub(0.0, 0.1, "world model"))
        link = self._core.setup.link()
        ex = self._executor(backend, link)
        t0 = time.perf_counter()
        report = ex.run(self._core.teaching.resolved_mission(), self._core.T_world_base(),
                        progress.sub(0.1, 1.0, "execute"))
        return self._after_execution(report, time.perf_counter() - t0)

    def _resume(self, progress: Progress) -> dict:
        backend = self._backend(progress.sub(0.0, 0.1, "world model"))
        ex = self._executor(backend, self._core.setup.link())
        t0 = time.perf_counter()
        report = ex.resume(progress.sub(0.1, 1.0, "resume"))
        return self._after_execution(report, time.perf_counter() - t0)

    def _after_execution(self, report: Any, seconds: float) -> dict:
        with self._core.lock:
            self._core.counters.replans += report.replans
            self._core.counters.replan_times_s += list(report.replan_seconds)
            self._core.counters.planning_time_s += sum(report.replan_seconds)
            final = report.final_plan
            if report.ok and final is not None and final.ok:
                self.trajectory = final.trajectory
                self.plan_report = _report_json(final.report)
                self._core.program = None
            self._core.saving.autosave()  # saved before ExecutionFinished / PlanReady show it
        self.last_run = summary = {
            "ok": report.ok, "end": report.end.value if report.end else None,
            "reason": report.reason, "collision_indications": report.collision_indications,
            "replans": report.replans, "backoffs": report.backoffs,
            "executed_tcp_length_m": report.executed_tcp_length,
            "median_replan_s": report.median_replan_seconds, "seconds": seconds,
            "resumable": report.resumable}
        self._core.bus.emit(ExecutionFinished(report.ok, dict(summary), report.resumable))
        if report.ok and self.plan_report is not None:
            self._core.bus.emit(PlanReady(dict(self.plan_report)))
        elif not report.ok:
            raise SessionError(f"execution ended: {report.reason}" + (
                " - press Resume to continue" if report.resumable else ""))
        return summary

    def start_explore(self, mode: str = "random", moves: int = 5, *, seed: int = 0) -> Future:
        """Explore the workspace with the robot: random moves, replay the plan, or the roads."""
        if mode not in ("random", "replay", "roads"):
            raise SessionError(f"unknown exploration mode {mode!r} (random, replay, roads)")
        return self._core.run_busy(f"explore ({mode})",
                                   lambda p: self._explore(p, mode, moves, seed),
                                   ("explore", "plan"), moving=True)

    def explore(self, mode: str = "random", moves: int = 5, *, seed: int = 0) -> dict:
        return self.start_explore(mode, moves, seed=seed).result()

    def _explore(self, progress: Progress, mode: str, moves: int, seed: int) -> dict:
        from assistant.planning import Explorer

        backend = self._backend(progress.sub(0.0, 0.2, "world model"))
        link = self._core.setup.link()
        if backend.explorer is None or backend.explorer.link is not link:
            if backend.explorer is not None:
                backend.explorer.detach()
            backend.explorer = Explorer(self._mission_planner(backend), link)
        ex = backend.explorer
        sub = progress.sub(0.2, 1.0, "explore")
        if mode == "random":
            rep = ex.random_moves(moves, seed=seed, progress=sub)
        elif mode == "roads":
            rep = ex.follow_roads(max_targets=moves, progress=sub)
        else:
            if self.trajectory is None:
                raise SessionError("nothing to replay: plan the mission first")
            rep = ex.replay(self.trajectory, progress=sub)
        return {"ok": rep.ok, "description": rep.describe()}

    def order_mission(self) -> list[str]:
        """Order the application paths (shortest transfers) - shown, and used by Plan."""

        from assistant.trajectory.ordering import order_mission

        with self._core.action("order the mission", EDIT_MISSION, scene="mission"):
            if self._core.mission.start is None or self._core.mission.goal is None:
                raise SessionError("The mission needs a start and a goal")
            ordering = order_mission(self._core.teaching.resolved_mission())
            self._core.mission = replace(self._core.mission, order=list(ordering.order))
        return [self._core.mission.paths[i].name for i in ordering.order]

    def occupancy_cells(self, min_p: float = 0.05) -> OccupiedCells | None:
        """Octree leaves with occupancy >= min_p, in the world frame."""
        b = self.backend
        if b is None:
            return None
        occ = np.asarray(b.world.occupancy())
        ijk = np.argwhere(occ >= min_p)
        grid = b.world.grid
        centres = grid.centres_of_ijk(ijk)
        T = self._core.T_world_base()
        return OccupiedCells(centres @ T[:3, :3].T + T[:3, 3], occ[tuple(ijk.T)].astype(float),
                             float(grid.leaf), T[:3, :3].copy())

    def learnt_cells(self) -> OccupiedCells | None:
        """The obstacle learnt from collision indications: occupied leaves that no CAD part
        explains (world frame), for display."""
        b = self.backend
        if b is None or not b.world.collisions:
            return None
        occ = np.asarray(b.world.occupancy())
        cad = np.asarray(b.world.cad_leaves()).reshape(occ.shape)
        ijk = np.argwhere((occ >= b.world.threshold) & ~cad)
        grid = b.world.grid
        T = self._core.T_world_base()
        return OccupiedCells(grid.centres_of_ijk(ijk) @ T[:3, :3].T + T[:3, 3],
                             occ[tuple(ijk.T)].astype(float), float(grid.leaf),
                             T[:3, :3].copy())

    def learnt_view(self) -> Any:
        """`learnt_cells` as the page draws them: cut into sub-cells, without those the arm
        stands in now or stood in at an indicated contact (`session.learnt_view`); None
        when nothing was learnt."""
        from assistant.session.learnt_view import learnt_view

        cells = self.learnt_cells()
        if cells is None:
            return None
        postures = np.array([self._core.current_joints(), *self.recorded_collisions])
        return learnt_view(cells, self._core.robot, postures, self._core.T_world_base())

    def road_cells(self) -> tuple[Array, float] | None:
        """Centres (world frame) of the Voronoi road cells and the leaf size."""
        b = self.backend
        if b is None or b.roadmap.voronoi is None:
            return None
        ijk = np.argwhere(b.roadmap.voronoi.roads())
        grid = b.world.grid
        T = self._core.T_world_base()
        return grid.centres_of_ijk(ijk) @ T[:3, :3].T + T[:3, 3], float(grid.leaf)

    def learnt_indications(self) -> list[str]:
        """The collision indications the world model holds, numbered as `forget_indication`
        takes them, in the operator's words: where the tool stood (world frame, mm) and
        what was learnt there."""
        b = self.backend if self.world_ready else None
        if b is None:
            return []
        out = []
        for i, rc in enumerate(b.world.collisions):
            x, y, z = (round(float(v)) for v in self._core.tcp_world(rc.q)[:3, 3] * 1000.0)
            out.append(f"{i + 1}: tool at ({x}, {y}, {z}) mm - "
                       f"{b.world.describe_region(i)}")
        return out
