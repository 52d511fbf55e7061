"""Automatic workspace exploration (thesis Listing 6 step 2, SPEC §1): move the robot through
the cell while the operator (or the simulated robot's hidden obstacles) indicates collisions,
so the world model learns what no CAD shows before the mission is planned.

Three modes, each with the same indication handling - record the stopped posture
(`RoadmapPlanner.add_collision`), retreat along the executed path out of the indication's
posture box, go on with the next target - and the same budgets and end reasons:

* `random_moves`: targets sampled uniformly in the joint limits, kept if valid in the known
  world (FCL against CAD, not near a recorded collision, TCP in a free leaf); each reached
  along the roadmap's joint path (exploring needs no smoothing, and it is much cheaper).
* `replay`: drive a given joint path or trajectory (an existing program); after a collision,
  skip to the next posture past the indicated region and rejoin the path there.
* `follow_roads`: visit road cells of the Voronoi roadmap in a tour (spread-out targets by
  farthest-point sampling, then a nearest-neighbour order), driving the roadmap's joint
  paths without smoothing - the thesis' "following the Voronoi lines".
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field

import numpy as np

from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.mission.motion import Trajectory
from assistant.planning.backoff import retreat_index
from assistant.planning.execution import EndReason
from assistant.planning.known_world import KnownValidity, WorldAllowed
from assistant.planning.mission_planner import MissionPlanner
from assistant.progress import Cancelled, Progress
from assistant.roadmap.voronoi import ROAD
from assistant.trajectory.assemble import joint_interpolation

Array = np.ndarray


@dataclass(frozen=True)
class ExplorationConfig:
    speed: float = 0.3  # fraction of the joint speed limits
    max_indications: int = 20
    #: Random configurations tried per random target before giving up.
    max_samples: int = 2000
    #: Dense path step (m of arm travel) for paths driven without smoothing.
    step: float = 0.005


@dataclass
class ExplorationReport:
    mode: str
    end: EndReason | None = None
    reason: str = ""
    targets: int = 0
    reached: int = 0
    unplannable: int = 0
    collision_indications: int = 0
    executed_tcp_length: float = 0.0
    seconds: float = 0.0
    log: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.end == EndReason.COMPLETED

    def describe(self) -> str:
        return (f"{self.mode}: {self.end.value if self.end else 'running'} - {self.reason}; "
                f"{self.reached}/{self.targets} targets reached, {self.collision_indications} "
                f"collision indication(s), TCP moved {self.executed_tcp_length * 1000:.0f} mm")


class _Stop(Exception):
    def __init__(self, end: EndReason, reason: str):
        super().__init__(reason)
        self.end, self.reason = end, reason


class Explorer:
    """Exploration runs on a link, feeding indications into the planner's world and roads."""

    def __init__(self, planner: MissionPlanner, link: RobotLink,
                 config: ExplorationConfig | None = None):
        self.planner = planner
        self.link = link
        self.config = config or ExplorationConfig()
        self.robot = planner.robot
        self._progress = Progress("explore")
        self._running = False
        link.subscribe(self._on_event)

    def detach(self) -> None:
        """Stop listening to the link's events (before replacing this explorer)."""
        self.link.unsubscribe(self._on_event)

    # ------------------------------------------------------------------ modes
    def random_moves(self, n: int, *, seed: int = 0, progress: Progress | None = None,
                     ) -> ExplorationReport:
        """Drive to `n` random valid configurations (fixed seed: the same targets each run)."""
        rng = np.random.default_rng(seed)
        rep = ExplorationReport("random moves")

        def body() -> None:
            for k in range(n):
                self._progress.update(k / max(1, n), f"random target {k + 1} of {n}")
                q_t = self._sample(rng)
                if q_t is None:
                    raise _Stop(EndReason.NO_PATH, f"no valid configuration found in "
                                f"{self.config.max_samples} samples")
                rep.targets += 1
                path = self._road_path(q_t, rep, f"random target {k + 1}")
                if path is not None and self._drive(path, rep):
                    rep.reached += 1
            rep.reason = f"{rep.reached} of {rep.targets} random targets reached"

        return self._run(rep, body, progress)

    def replay(self, program: Trajectory | Array, *, progress: Progress | None = None,
               ) -> ExplorationReport:
        """Drive an existing joint path / trajectory; skip past indicated regions."""
        rep = ExplorationReport("replay")
        if isinstance(program, Trajectory):
            P = program.dense_joint_path()
        else:
            P = np.atleast_2d(np.asarray(program, dtype=float))
        P = _densify(self.robot, P, self.config.step)

        def body() -> None:
            i = 0
            rep.targets = 1
            if float(np.abs(self._q() - P[0]).max()) > 1e-6:
                self._go_to(P[0], rep, "replay start")
            while i < len(P) - 1:
                self._progress.update(i / (len(P) - 1), "replaying")
                ev = self._move(P[i:], rep)
                if ev.kind == LinkEventKind.REACHED:
                    break
                # rejoin the path past the indicated region; each failed attempt is new
                # evidence (or moves the rejoin point on), so this ends within budget
                k = i + int(ev.path_index or 0)
                while True:
                    j = self._next_clear(P, k + 1)
                    if j is None:
                        rep.reason = ("replayed up to a collision; the rest of the path is "
                                      "blocked")
                        return
                    path = self._road_path(P[j], rep, f"rejoin the path at {j}")
                    if path is None:
                        k = j
                        continue
                    rep.log.append(f"skipping from path index {k} to {j}")
                    if self._drive(path, rep):
                        i = j
                        break
            rep.reached = 1
            rep.reason = "the path was replayed to its end"

        return self._run(rep, body, progress)

    def follow_roads(self, *, max_targets: int = 12, progress: Progress | None = None,
                     ) -> ExplorationReport:
        """Visit up to `max_targets` spread-out road cells along the roadmap's joint paths."""
        rep = ExplorationReport("follow roads")
        rp, w = self.planner.roadmap, self.planner.world
        if rp.voronoi is None:
            raise RuntimeError("build the roadmap first (RoadmapPlanner.build)")

        def body() -> None:
            cells, offsets, Q = w.cell_positions()
            lab = rp.voronoi.label.reshape(-1)
            road = (lab[cells] == ROAD) & w.free().reshape(-1)[cells]
            idx = np.flatnonzero(road)
            if not len(idx):
                raise _Stop(EndReason.NO_PATH, "the roadmap has no road cells to follow")
            centres = w.grid.centres_of_ijk(w.grid.ijk_of_flat(cells[idx]))
            here = self.robot.fk(self._q())[:3, 3]
            chosen = _farthest_points(centres, here, max_targets)
            order = _nearest_tour(centres[chosen], here)
            weights = self.robot.arm_radii()
            for n, t in enumerate(chosen[order]):
                self._progress.update(n / len(chosen), f"road target {n + 1} of {len(chosen)}")
                c = idx[t]
                Qc = Q[offsets[c]:offsets[c + 1]]
                q_now = self._q()
                q_t = Qc[int(np.argmin(np.abs(Qc - q_now) @ weights))]
                rep.targets += 1
                path = self._road_path(q_t, rep, f"road target {n + 1}")
                if path is not None and self._drive(path, rep):
                    rep.reached += 1
            rep.reason = f"{rep.reached} of {rep.targets} road targets reached"

        return self._run(rep, body, progress)

    # ------------------------------------------------------------------ machinery
    def _run(self, rep: ExplorationReport, body, progress: Progress | None,
             ) -> ExplorationReport:
        self._progress = progress or Progress(f"explore: {rep.mode}")
        t0 = time.perf_counter()
        self._running = True
        try:
            body()
            if rep.end is None:
                rep.end = EndReason.COMPLETED
        except _Stop as stop:
            rep.end, rep.reason = stop.end, stop.reason
        except Cancelled:
            with contextlib.suppress(LinkError):
                self.link.stop()
            rep.end, rep.reason = EndReason.CANCELLED, "exploration cancelled"
        finally:
            self._running = False
        rep.seconds = time.perf_counter() - t0
        return rep

    def _drive(self, path: Array, rep: ExplorationReport) -> bool:
        """Drive a path; on an indication record it and retreat. True if the end was reached."""
        ev = self._move(path, rep)
        return ev.kind == LinkEventKind.REACHED

    def _go_to(self, q: Array, rep: ExplorationReport, label: str) -> None:
        path = self._road_path(q, rep, label)
        if path is None:
            raise _Stop(EndReason.NO_PATH, f"{label}: {rep.log[-1]}")
        if not self._drive(path, rep):
            raise _Stop(EndReason.NO_PATH, f"{label}: blocked by a collision on the way")

    def _road_path(self, q: Array, rep: ExplorationReport, label: str) -> Array | None:
        """The roadmap's joint path to q, densified, unsmoothed (None: logged why not)."""
        plan = self.planner.roadmap.plan(self._q(), q)
        if not plan.ok:
            rep.unplannable += 1
            rep.log.append(f"{label}: {plan.reason}")
            return None
        return _densify(self.robot, np.array(plan.joint_path), self.config.step)

    def _move(self, path: Array, rep: ExplorationReport) -> LinkEvent:
        self._progress.check()
        try:
            ev = self.link.move_path(path, speed_scale=self.config.speed)
        except LinkLost as exc:
            raise _Stop(EndReason.LINK_LOST, f"connection lost: {exc}") from exc
        except LinkError as exc:
            raise _Stop(EndReason.LINK_ERROR, f"the robot refused the motion: {exc}") from exc
        executed = _executed(path, ev)
        rep.executed_tcp_length += _tcp_length(self.robot, executed)
        if ev.kind == LinkEventKind.REACHED:
            return ev
        if ev.kind == LinkEventKind.COLLISION_INDICATED:
            rep.collision_indications += 1
            q = np.asarray(ev.q, dtype=float)
            self.planner.roadmap.add_collision(q)
            p = self.robot.fk(q)[:3, 3] * 1000.0
            rep.log.append(f"collision indicated at TCP ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm")
            if rep.collision_indications > self.config.max_indications:
                raise _Stop(EndReason.INDICATION_BUDGET,
                            f"more than {self.config.max_indications} collision indications")
            blocked = self.planner.world.near_recorded_collision(executed)
            back = executed[retreat_index(executed, blocked):][::-1]
            if len(back) > 1:
                ev2 = self.link.move_path(back, speed_scale=self.config.speed)
                rep.executed_tcp_length += _tcp_length(self.robot, _executed(back, ev2))
                if ev2.kind != LinkEventKind.REACHED:
                    raise _Stop(EndReason.LINK_ERROR, f"retreat failed: {ev2.message}")
            return ev
        if ev.kind == LinkEventKind.LINK_LOST:
            raise _Stop(EndReason.LINK_LOST, f"connection lost: {ev.message}")
        if ev.kind == LinkEventKind.STOPPED:
            if self._progress.cancelled:
                raise Cancelled("exploration cancelled")
            raise _Stop(EndReason.STOPPED, f"stopped: {ev.message}")
        raise _Stop(EndReason.LINK_ERROR, f"the robot reported an error: {ev.message}")

    def _sample(self, rng: np.random.Generator) -> Array | None:
        lim = self.robot.limits
        validity = KnownValidity(self.planner.checker, self.planner.world)
        allowed = WorldAllowed(self.planner.world)
        left = self.config.max_samples
        while left > 0:
            m = min(256, left)
            left -= m
            Q = rng.uniform(lim.lower, lim.upper, size=(m, self.robot.dof))
            ok = allowed(self.robot.batch_fk(Q).positions)
            if ok.any():
                ok[ok] = validity.is_valid_batch(Q[ok])
            if ok.any():
                return Q[int(np.argmax(ok))]
        return None

    def _next_clear(self, P: Array, start: int) -> int | None:
        """First index >= start whose posture is valid in the known world (past the box)."""
        if start >= len(P):
            return None
        validity = KnownValidity(self.planner.checker, self.planner.world)
        ok = validity.is_valid_batch(P[start:])
        hit = np.flatnonzero(ok)
        return None if not len(hit) else start + int(hit[0])

    def _q(self) -> Array:
        try:
            return np.asarray(self.link.current_joints(), dtype=float)
        except LinkError as exc:
            raise _Stop(EndReason.LINK_LOST, f"cannot read the robot's joints: {exc}") from exc

    def _on_event(self, ev: LinkEvent) -> None:
        if self._running and ev.kind == LinkEventKind.MOVED and self._progress.cancelled:
            self.link.stop()


def _executed(path: Array, ev: LinkEvent) -> Array:
    path = np.asarray(path, dtype=float)
    if ev.kind == LinkEventKind.REACHED or ev.q is None:
        return path
    k = int(np.clip(ev.path_index or 0, 0, len(path) - 1))
    return np.concatenate([path[:k + 1], np.asarray(ev.q, dtype=float)[None]])


def _tcp_length(robot, Q: Array) -> float:
    if len(Q) < 2:
        return 0.0
    P = robot.batch_fk(np.asarray(Q, dtype=float)).positions
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def _densify(robot, P: Array, step: float) -> Array:
    if len(P) < 2:
        return P
    parts = [joint_interpolation(robot, a, b, step)[:-1] for a, b in zip(P[:-1], P[1:],
                                                                        strict=True)]
    return np.concatenate(parts + [P[-1:]])


def _farthest_points(X: Array, start: Array, k: int) -> Array:
    """Indices of up to k rows of X, each the farthest from those chosen before (and start)."""
    d = np.linalg.norm(X - start, axis=1)
    chosen: list[int] = []
    for _ in range(min(k, len(X))):
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.linalg.norm(X - X[i], axis=1))
    return np.array(chosen, dtype=int)


def _nearest_tour(X: Array, start: Array) -> Array:
    """Greedy nearest-neighbour order of the rows of X from `start`."""
    left = list(range(len(X)))
    here, out = start, []
    while left:
        j = min(left, key=lambda i: float(np.linalg.norm(X[i] - here)))
        out.append(j)
        left.remove(j)
        here = X[j]
    return np.array(out, dtype=int)
