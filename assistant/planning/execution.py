"""Executing a mission plan on any `RobotLink`, re-planning on collision indications (SPEC §6).

The loop of the thesis (003 Listing 6, L5583-5627), piece by piece:

* Drive the piece's dense joint path. A transfer that gets a COLLISION_INDICATED (the
  operator's button, or a hidden obstacle of the simulated robot) records the stopped posture
  as evidence (`RoadmapPlanner.add_collision`: fusion + local roadmap update), re-plans the
  rest of the transfer from there, backs off along the executed path to the last point the
  old and new plan share (`backoff`), and continues on the new plan.
* Before each later transfer, if the world changed since it was planned: re-plan it; keep the
  old one while it is still valid unless the new one is shorter by more than the hysteresis
  (absolute metres and a ratio, both configurable), so the robot does not flip between
  nearly equal paths.
* A collision on an application path ends the run: the work itself collides (move the part
  or re-teach the path); no re-plan can fix that.
* Once the goal is reached, the final plan (high shrink) is made with everything learnt and
  checked in simulation against it; the run ends there, at the goal. The robot never drives
  back over work already done unasked: driving the final plan once from the start is a step
  the operator starts (`drive_final`); an indication there is learnt, the final plan is made
  again and the drive ends with the robot standing - the operator starts the next one.
  (`ExecutionConfig.validate_final` makes `run` drive it in rounds by itself, for scripts.)

Budgets (indications, re-plans, final rounds) and the roadmap's/net's own budgets make every
run end with an `EndReason` and a sentence; every run ends within its bound of indications
and seconds of planning (`run_bounds`), which the progress line shows. With
`IndicationConfig.learn_regions` an indication on a 6- or 7-axis arm teaches the region the
arm's links swept into in the last step before the stop (`world.contact_region`), never where
a goal, a taught location or a path of the mission has the arm; when a re-plan finds no way
on, the run names the learnt regions nearest to where it had to go, to be forgotten if
nothing is there.

LINK_LOST, a stop on request and a cancellation leave a resumable state: the plan and the
world are kept, `resume()` re-plans from `link.current_joints()`. Progress is reported per
piece; `cancel()` (or cancelling the `Progress`) stops the robot at once.
"""

from __future__ import annotations

import contextlib
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.mission.model import ResolvedMission
from assistant.planning.backoff import leads_on, retreat_candidates, retreat_index, splice
from assistant.planning.config import ExecutionConfig
from assistant.planning.mission_planner import MissionPlan, MissionPlanner, TransferResult
from assistant.planning.pace_drive import PaceCache
from assistant.planning.pieces import PieceKind, PlanPiece
from assistant.planning.run_bounds import PlanningTimeUp, RunBounds
from assistant.progress import Cancelled, Progress

Array = np.ndarray


class EndReason(str, Enum):
    COMPLETED = "completed"
    PLAN_FAILED = "plan_failed"
    NO_PATH = "no_path"  # a re-plan after new evidence found no way on
    MISSION_COLLIDES = "mission_collides"  # contact on an application path
    INDICATION_BUDGET = "indication_budget"
    REPLAN_BUDGET = "replan_budget"
    PLANNING_BUDGET = "planning_budget"  # the run's seconds of planning are used up
    FINAL_NOT_VALIDATED = "final_not_validated"
    LINK_LOST = "link_lost"
    LINK_ERROR = "link_error"
    STOPPED = "stopped"
    CANCELLED = "cancelled"


#: Two stops this close in every joint (rad) are the same posture: the arm driven back over
#: the same path stops at the same check sample (1e-3 rad is ~1 mm at a 1 m reach, far
#: below the 5 mm motion samples; a stop elsewhere differs by a sample or more).
_SAME_STOP_RAD = 1e-3

#: Ends after which `resume()` may continue.
RESUMABLE = frozenset({EndReason.LINK_LOST, EndReason.STOPPED, EndReason.CANCELLED})


@dataclass
class ExecutionReport:
    """How a run ended and what it took; counters accumulate over `run` and `resume`."""

    end: EndReason | None = None
    reason: str = ""
    collision_indications: int = 0
    replans: int = 0
    #: Switches to a shorter (still valid) path past the hysteresis.
    switches: int = 0
    backoffs: int = 0
    resumes: int = 0
    #: Indication -> verified new trajectory (s): add_collision + roadmap + smoothing.
    replan_seconds: list[float] = field(default_factory=list)
    #: Indication -> new roadmap joint path (s): add_collision + roadmap query only.
    replan_roadmap_seconds: list[float] = field(default_factory=list)
    executed_tcp_length: float = 0.0  # m, everything the TCP moved, back-offs included
    backoff_tcp_length: float = 0.0
    first_plan: MissionPlan | None = None
    #: The final plan (offered for export when `end` is COMPLETED).
    final_plan: MissionPlan | None = None
    final_validated: bool = False
    final_rounds: int = 0
    log: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.end == EndReason.COMPLETED

    @property
    def resumable(self) -> bool:
        return self.end in RESUMABLE

    @property
    def median_replan_seconds(self) -> float | None:
        return statistics.median(self.replan_seconds) if self.replan_seconds else None

    @property
    def median_replan_roadmap_seconds(self) -> float | None:
        return (statistics.median(self.replan_roadmap_seconds)
                if self.replan_roadmap_seconds else None)

    def describe(self) -> str:
        head = f"{self.end.value if self.end else 'running'}: {self.reason}"
        med = self.median_replan_seconds
        figs = (f"{self.collision_indications} collision indication(s), {self.replans} "
                f"re-plan(s), {self.backoffs} back-off(s), {self.switches} switch(es); "
                f"TCP moved {self.executed_tcp_length * 1000:.0f} mm"
                + (f"; median re-plan {med * 1000:.0f} ms" if med is not None else ""))
        return "\n".join([head, figs] + [f"  {line}" for line in self.log])


class _Phase(str, Enum):
    EXPLORE = "explore"
    FINAL = "final"
    DONE = "done"


@dataclass
class _Item:
    """A piece in the drive queue; `repairable` transfers may be re-planned on contact."""

    piece: PlanPiece
    repairable: bool
    world_version: tuple[int, int]
    #: Part of the program: driven at its pace. The way to the program's start is not (no
    #: program contains it): timed by the joints' limits at the run's speed.
    in_program: bool = True


class _End(Exception):
    """Ends the run from deep inside the loop with a reason."""

    def __init__(self, reason: EndReason, message: str):
        super().__init__(message)
        self.reason = reason
        self.message = message


class _RoundFailed(Exception):
    """An indication during a final validation run: keep the evidence, start a new round."""


class MissionExecutor:
    """Runs missions on a link with the re-planning loop (module docstring).

    Args:
        planner: the mission planner (owns the world model and roadmap it updates).
        link: any `RobotLink` (simulated, MELFA, KUKA), connected.
        config: speeds, budgets, hysteresis, back-off tolerance, final validation.
    """

    def __init__(self, planner: MissionPlanner, link: RobotLink,
                 config: ExecutionConfig | None = None):
        self.planner = planner
        self.link = link
        self.config = config or ExecutionConfig()
        self.robot = planner.robot
        self._paces = PaceCache(planner.robot)
        self.radii = self.robot.arm_radii()
        self.report = ExecutionReport()
        self._mission: ResolvedMission | None = None
        self._T_wb: Array | None = None
        self._phase = _Phase.DONE
        self._queue: list[_Item] | None = None
        self._index = 0
        self._final: MissionPlan | None = None
        self._progress: Progress | None = None
        self._resume_pending = False
        self._running = False
        self._given_plan: MissionPlan | None = None
        self._last_indication_s = 0.0
        #: Where this run's indications stopped the arm (`_record`).
        self._stops: list[Array] = []
        self.bounds = self._new_bounds()
        link.subscribe(self._on_event)

    def _new_bounds(self) -> RunBounds:
        return RunBounds(self.config.max_indications, self.config.max_planning_seconds)

    # ------------------------------------------------------------------ public
    def run(self, mission: ResolvedMission, T_world_base: Array, progress: Progress | None = None,
            *, plan: MissionPlan | None = None) -> ExecutionReport:
        """Plan (exploring), drive with re-planning, then plan and validate the final plan.

        Args:
            mission: what to do (world frame).
            T_world_base: where the robot base stands.
            progress: reports per piece; cancelling it stops the robot.
            plan: an exploring plan already made for this mission in this world (e.g. shown
                to the operator first); planned here if None.
        """
        self.report = ExecutionReport()
        self._stops = []
        self.bounds = self._new_bounds()
        self._mission, self._T_wb = mission, np.asarray(T_world_base, dtype=float)
        self._phase, self._queue, self._index, self._final = _Phase.EXPLORE, None, 0, None
        self._resume_pending = False
        self._given_plan = plan
        return self._go(progress)

    def resume(self, progress: Progress | None = None) -> ExecutionReport:
        """Continue a run that ended resumably (link lost, stopped, cancelled), re-planning
        the interrupted piece from `link.current_joints()`."""
        if self._mission is None or self.report.end not in RESUMABLE:
            raise RuntimeError("nothing to resume: the last run "
                               + ("ended with " + self.report.end.value
                                  if self.report.end else "has not started"))
        if not self.link.connected:
            try:
                self.link.connect()
            except LinkError as exc:
                self.report.end, self.report.reason = EndReason.LINK_LOST, (
                    f"still no connection to the robot: {exc}")
                return self.report
        self.report.resumes += 1
        self.report.log.append(f"resumed from {self._where()}")
        if self._phase == _Phase.FINAL:
            self._queue = None  # a validation round must run uninterrupted: start it again
        elif self._queue is not None and self._index < len(self._queue):
            self._resume_pending = True
        return self._go(progress)

    def detach(self) -> None:
        """Stop listening to the link's events (before replacing this executor)."""
        self.link.unsubscribe(self._on_event)

    def cancel(self) -> None:
        """Stop the robot now; the run ends CANCELLED (resumable)."""
        if self._progress is not None:
            self._progress.cancel()
        self.link.stop()

    # ------------------------------------------------------------------ main loop
    def _go(self, progress: Progress | None) -> ExecutionReport:
        self._progress = progress or Progress("execute mission")
        return self._ended(self._explore_and_finish, "end")

    def _explore_and_finish(self) -> None:
        rep = self.report
        if self._resume_pending:
            self._resume_pending = False
            self._resume_piece()
        if self._phase == _Phase.EXPLORE:
            if self._queue is None:
                self._start_explore()
            self._drive_queue(final=False)
            self._phase, self._queue = _Phase.FINAL, None
            rep.log.append("goal reached with the exploring plan")
        if self._phase == _Phase.FINAL and self.config.plan_final:
            self._final_phase()
        rep.end = EndReason.COMPLETED
        rep.reason = "mission executed; " + self._final_words()
        self._phase = _Phase.DONE

    def _ended(self, body: Callable[[], None], what: str) -> ExecutionReport:
        """Run `body` while this executor drives; every way out ends the report with a
        reason (an `_End`, a cancellation) and a log line."""
        rep = self.report
        rep.end, rep.reason = None, ""
        self._running = True
        try:
            body()
        except _End as end:
            rep.end, rep.reason = end.reason, end.message
        except PlanningTimeUp:
            rep.end, rep.reason = EndReason.PLANNING_BUDGET, self._time_up_words()
        except Cancelled:
            self._safe_stop()
            rep.end, rep.reason = EndReason.CANCELLED, f"cancelled at {self._where()}"
        finally:
            self._running = False
        rep.log.append(f"{what}: {rep.end.value} - {rep.reason}")
        return rep

    def drive_final(self, progress: Progress | None = None) -> ExecutionReport:
        """Drive the final plan once, from where the arm stands to its start and through it
        (the operator's step after a completed run). An indication on the way is learnt and
        the final plan made again; the drive then ends with the robot standing (reason
        FINAL_NOT_VALIDATED, resumable by another `drive_final`)."""
        rep = self.report
        if self._mission is None or rep.final_plan is None or not rep.final_plan.ok:
            raise RuntimeError("nothing to drive: plan and run the mission first")
        if not self.link.connected:
            self.link.connect()
        self.bounds = self._new_bounds()  # a run of its own
        self._progress = progress or Progress("drive the final program")
        return self._ended(self._drive_final_once, "final drive end")

    def _drive_final_once(self) -> None:
        rep = self.report
        final = rep.final_plan
        assert final is not None
        items = self._approach(self._current_joints(), final.pieces[0].q_start,
                               "to the final program's start")
        self._queue = items + [_Item(p, False, self._world_version()) for p in final.pieces]
        self._index, self._phase = 0, _Phase.FINAL
        try:
            self._drive_queue(final=True)
        except _RoundFailed:
            self._queue = None
            self._plan_final()
            raise _End(EndReason.FINAL_NOT_VALIDATED,
                       "the robot met something new on the final program: it is learnt "
                       "and the final program planned again round it - drive it again "
                       "to check it") from None
        rep.final_validated = True
        rep.end, rep.reason = EndReason.COMPLETED, "mission executed; " + self._final_words()
        self._phase = _Phase.DONE

    def _final_words(self) -> str:
        rep = self.report
        if rep.final_validated:
            return "final trajectory validated on the robot"
        if rep.final_plan is not None:
            return ("final trajectory planned with everything learnt and checked in "
                    "simulation (not driven; drive it once to validate it on the robot)")
        return "no final plan requested"

    def _start_explore(self) -> None:
        assert self._mission is not None and self._T_wb is not None
        prog = self._progress
        assert prog is not None
        q_now = self._current_joints()
        with self.bounds.planning():
            plan = self._given_plan or self.planner.plan_mission(
                self._mission, self._T_wb, q_now,
                self._bounded(prog.sub(0.0, 0.1, "planning"), "planning"), exploring=True)
        self._given_plan = None
        self.report.first_plan = plan
        if not plan.ok:
            raise _End(EndReason.PLAN_FAILED, plan.report.reason
                       + (f" ({plan.report.failed_piece})" if plan.report.failed_piece else ""))
        self.report.log.append(f"planned (exploring) in {plan.report.planning_seconds:.2f} s")
        items = self._approach(q_now, plan.pieces[0].q_start, "approach")
        items += [_Item(p, p.kind == PieceKind.TRANSFER, self._world_version())
                  for p in plan.pieces]
        self._queue, self._index = items, 0

    def _final_phase(self) -> None:
        assert self._mission is not None and self._T_wb is not None
        cfg, rep = self.config, self.report
        while True:
            if self._queue is None:
                if rep.final_rounds >= cfg.max_final_rounds:
                    raise _End(EndReason.FINAL_NOT_VALIDATED,
                               f"the final trajectory met new evidence in each of "
                               f"{rep.final_rounds} validation runs")
                rep.final_rounds += 1
                q_now = self._current_joints()
                final = self._plan_final()
                if not cfg.validate_final:
                    return
                items = self._approach(q_now, final.pieces[0].q_start, "back to the start")
                items += [_Item(p, False, self._world_version()) for p in final.pieces]
                self._queue, self._index = items, 0
            try:
                self._drive_queue(final=True)
            except _RoundFailed:
                self._queue = None
                continue
            rep.final_validated = True
            return

    def _plan_final(self) -> MissionPlan:
        """The final (high-shrink) plan with everything learnt, checked in simulation."""
        assert self._mission is not None and self._T_wb is not None
        rep = self.report
        # seeded with the first plan's start: the same arm branch at every location
        first = rep.first_plan
        seed = first.pieces[0].q_start if first is not None and first.pieces else \
            self._current_joints()
        with self.bounds.planning():
            final = self.planner.plan_mission(
                self._mission, self._T_wb, seed,
                self._bounded(self._sub(0.8, 0.85, "final plan"), "final plan"),
                exploring=False)
        if not final.ok:
            raise _End(EndReason.PLAN_FAILED, f"final plan: {final.report.reason}")
        self._final = rep.final_plan = final
        rep.log.append(f"final plan (round {rep.final_rounds}) in "
                       f"{final.report.planning_seconds:.2f} s: "
                       f"{final.report.primitives} primitives")
        return final

    def _approach(self, q_now: Array, q_start: Array, label: str) -> list[_Item]:
        """A transfer from where the arm is to where the plan starts (if it is elsewhere)."""
        if float(np.abs(q_now - q_start).max()) <= 1e-6:
            return []
        with self.bounds.planning():
            tr = self.planner.plan_transfer(q_now, q_start, exploring=True, label=label,
                                            progress=self._bounded(self._sub_here(label),
                                                                   label))
        if not tr.ok:
            raise _End(EndReason.PLAN_FAILED, f"{label}: {tr.report.reason}"
                       + self._blockers(q_start))
        assert tr.piece is not None
        return [_Item(tr.piece, True, self._world_version(), in_program=False)]

    # ------------------------------------------------------------------ pieces
    def _drive_queue(self, *, final: bool) -> None:
        assert self._queue is not None
        while self._index < len(self._queue):
            item = self._queue[self._index]
            n = len(self._queue)
            span = (0.85, 1.0) if final else (0.1, 0.8)
            frac = span[0] + (span[1] - span[0]) * self._index / n
            assert self._progress is not None
            self._progress.update(frac, self.bounds.line(f"driving {item.piece.label}",
                                                         self.report.collision_indications))
            if item.repairable and item.world_version != self._world_version():
                self._refresh(item)
            if item.piece.kind == PieceKind.APPLICATION:
                self._drive_application(item, final)
            else:
                self._drive_transfer(item, final)
            self._index += 1

    def _drive_application(self, item: _Item, final: bool) -> None:
        path = item.piece.dense()
        ev = self._move(path, final, item)
        if ev.kind == LinkEventKind.COLLISION_INDICATED:
            with self.bounds.planning():
                self._record(ev, item.piece, self._executed(path, ev))
            raise _End(EndReason.MISSION_COLLIDES,
                       f"collision on application path {item.piece.label} ({ev.message}): the "
                       "work itself collides - move the part or re-teach the path")
        self._other_end(ev)

    def _drive_transfer(self, item: _Item, final: bool) -> None:
        cfg, rep = self.config, self.report
        path = item.piece.dense()
        # Every posture driven on this transfer so far, over all its drives. The retreat
        # after an indication may have to go back further than the current drive: if that
        # drive never left the previous indication's box before meeting the next one, a
        # retreat to its beginning would end inside that box, the re-plan would start there
        # (exempt from it, to be able to leave) and could lead through the very same posture
        # again - the robot would shuttle between two indications until the budget ends.
        history: Array | None = None
        while True:
            ev = self._move(path, final, item)
            if ev.kind == LinkEventKind.REACHED:
                return
            if ev.kind != LinkEventKind.COLLISION_INDICATED:
                self._other_end(ev)
            t0 = time.perf_counter()
            drive = self._executed(path, ev)
            history = drive if history is None else np.concatenate([history, drive[1:]])
            executed = history
            with self.bounds.planning():
                q_stop = self._record(ev, item.piece, executed)
                if not item.repairable:
                    raise _RoundFailed()
                if rep.replans >= cfg.max_replans:
                    raise _End(EndReason.REPLAN_BUDGET, f"re-plan budget of "
                               f"{cfg.max_replans} used up at {item.piece.label}")
                rep.replans += 1
                self.bounds.check()
                tr, i_r = self._replan(item, executed, q_stop)
            t1 = time.perf_counter()
            rep.replan_seconds.append(t1 - t0)
            rep.replan_roadmap_seconds.append(self._last_indication_s + tr.roadmap_seconds)
            retreat = executed[i_r:][::-1]
            sp = splice(executed[:i_r + 1], tr.piece.dense(), self.radii, cfg.common_tolerance)
            back = np.concatenate([retreat, sp.backoff[1:]]) if sp.backs_off else retreat
            go = np.concatenate([back, sp.continuation[1:]]) if len(back) > 1 \
                else sp.continuation
            if len(back) > 1:
                rep.backoffs += 1
                rep.backoff_tcp_length += self._tcp_length(back)
            rep.log.append(f"{item.piece.label}: re-planned in {(t1 - t0) * 1000:.0f} ms "
                           f"(roadmap {rep.replan_roadmap_seconds[-1] * 1000:.0f} ms), backing "
                           f"off {self._tcp_length(back) * 1000:.0f} mm along the executed path")
            item.piece = tr.piece
            item.world_version = self._world_version()
            path = go

    def _replan(self, item: _Item, executed: Array, q_stop: Array,
                ) -> tuple[TransferResult, int]:
        """After an indication: retreat out of the indication's posture box and re-plan from
        there (or from further back); only then from the stop, and not on into the contact.
        Returns the new transfer and the index of executed it starts from."""
        blocked = self.planner.world.near_recorded_collision(executed)
        tr = None
        i_r = len(executed) - 1
        for i_try in retreat_candidates(executed, retreat_index(executed, blocked),
                                        self.radii):
            tr = self.planner.plan_transfer(
                executed[i_try], item.piece.q_end, exploring=True, label=item.piece.label,
                progress=self._bounded(self._sub_here("re-planning"), "re-planning"))
            i_r = i_try
            if tr.ok:
                break
        assert tr is not None
        if not tr.ok and i_r < len(executed) - 1:  # e.g. no way out backwards: try on
            i_r = len(executed) - 1
            on = self.planner.plan_transfer(
                q_stop, item.piece.q_end, exploring=True, label=item.piece.label,
                progress=self._bounded(self._sub_here("re-planning"), "re-planning"))
            if on.ok and on.piece is not None and \
                    leads_on(executed, on.piece.dense(), self.radii):
                raise _End(EndReason.NO_PATH, f"{item.piece.label}: no way on after the "
                           f"collision indication - {tr.report.reason}; the only way on "
                           "from where the robot stopped leads on into the contact"
                           + self._blockers(item.piece.q_end))
            tr = on
        if not tr.ok or tr.piece is None:
            raise _End(EndReason.NO_PATH, f"{item.piece.label}: no way on after the "
                       f"collision indication - {tr.report.reason}"
                       + self._blockers(item.piece.q_end))
        return tr, i_r

    def _refresh(self, item: _Item) -> None:
        """The world changed since this transfer was planned: re-plan; switch if it is no
        longer valid, or if the new one is shorter past the hysteresis."""
        cfg, rep = self.config, self.report
        q_now = self._current_joints()
        old = item.piece.dense()
        old = np.concatenate([q_now[None], old]) if np.abs(old[0] - q_now).max() > 1e-6 \
            else old
        with self.bounds.planning():
            valid = self.planner.verifier.check_path(list(old)) is None
            if rep.replans >= cfg.max_replans:
                if valid:
                    item.world_version = self._world_version()
                    return
                raise _End(EndReason.REPLAN_BUDGET,
                           f"re-plan budget of {cfg.max_replans} used up at {item.piece.label}")
            rep.replans += 1
            self.bounds.check()
            tr: TransferResult = self.planner.plan_transfer(
                q_now, item.piece.q_end, exploring=True, label=item.piece.label,
                progress=self._bounded(self._sub_here("re-planning"), "re-planning"))
        item.world_version = self._world_version()
        if not valid:
            if not tr.ok or tr.piece is None:
                raise _End(EndReason.NO_PATH, f"{item.piece.label}: the planned path crosses "
                           f"new evidence and no other was found - {tr.report.reason}"
                           + self._blockers(item.piece.q_end))
            rep.log.append(f"{item.piece.label}: re-planned (the old path crosses new evidence)")
            item.piece = tr.piece
            return
        if tr.ok and tr.piece is not None:
            old_len = self._tcp_length(old)
            new_len = self._tcp_length(tr.piece.dense())
            gain = old_len - new_len
            if gain > cfg.hysteresis_m and gain > cfg.hysteresis_ratio * old_len:
                rep.switches += 1
                rep.log.append(f"{item.piece.label}: switched to the re-planned path (TCP "
                               f"{old_len * 1000:.0f} -> {new_len * 1000:.0f} mm)")
                item.piece = tr.piece
                return
        rep.log.append(f"{item.piece.label}: re-checked against new evidence, still valid: "
                       "kept")

    def _resume_piece(self) -> None:
        """Re-plan the interrupted piece from where the arm is now."""
        assert self._queue is not None
        item = self._queue[self._index]
        q_now = self._current_joints()
        if item.piece.kind == PieceKind.TRANSFER:
            target, insert = item.piece.q_end, False
        else:  # redo the application path from its start
            target, insert = item.piece.q_start, True
        if float(np.abs(q_now - target).max()) <= 1e-6:
            if not insert:
                self._index += 1
            return
        with self.bounds.planning():
            tr = self.planner.plan_transfer(
                q_now, target, exploring=True, label=f"resume -> {item.piece.label}",
                progress=self._bounded(self._sub_here("re-planning"), "re-planning"))
        if not tr.ok or tr.piece is None:
            raise _End(EndReason.NO_PATH, f"resume: {tr.report.reason}"
                       + self._blockers(target))
        new = _Item(tr.piece, True, self._world_version())
        if insert:
            self._queue.insert(self._index, new)
        else:
            self._queue[self._index] = new

    # ------------------------------------------------------------------ link
    def _move(self, path: Array, final: bool, item: _Item) -> LinkEvent:
        """Drive `path` (ending on the item's piece) at the program's pace where it is the
        piece (`pace_drive`); a controller link times it itself at the run's speed."""
        speed = self.config.speed_final if final else self.config.speed_exploring
        assert self._progress is not None
        self._progress.check()
        path = np.asarray(path, dtype=float)
        pace = self._paces.drive_pace(path, item.piece, speed) if item.in_program else None
        try:
            if pace is None:
                ev = self.link.move_path(path, speed_scale=speed)
            else:
                ev = self.link.move_paced(path, pace.t, pace.hold, speed_scale=speed)
        except LinkLost as exc:
            raise _End(EndReason.LINK_LOST, f"connection lost: {exc}") from exc
        except LinkError as exc:
            raise _End(EndReason.LINK_ERROR, f"the robot refused the motion: {exc}") from exc
        moved = self._executed(path, ev)
        self.report.executed_tcp_length += self._tcp_length(moved)
        return ev

    def _other_end(self, ev: LinkEvent) -> None:
        """REACHED returns; everything else ends the run with its reason."""
        if ev.kind == LinkEventKind.REACHED:
            return
        if ev.kind == LinkEventKind.LINK_LOST:
            raise _End(EndReason.LINK_LOST, f"connection lost at {self._where()}: "
                       f"{ev.message or 'no reply'}; resume when it is back")
        if ev.kind == LinkEventKind.STOPPED:
            if self._progress is not None and self._progress.cancelled:
                raise _End(EndReason.CANCELLED, f"cancelled at {self._where()}")
            raise _End(EndReason.STOPPED, f"stopped at {self._where()}: {ev.message}")
        raise _End(EndReason.LINK_ERROR, f"the robot reported an error at {self._where()}: "
                   f"{ev.message}")

    def _on_event(self, ev: LinkEvent) -> None:
        # Cancelling the progress stops the arm within one event period - only while this
        # executor drives (the link may outlive it and serve others).
        if (self._running and ev.kind == LinkEventKind.MOVED and self._progress is not None
                and self._progress.cancelled):
            self.link.stop()

    def _safe_stop(self) -> None:
        with contextlib.suppress(LinkError):
            self.link.stop()

    # ------------------------------------------------------------------ evidence
    def _record(self, ev: LinkEvent, piece: PlanPiece, executed: Array | None = None,
                ) -> Array:
        """Count the indication (within budget) and put it into the world and roads: on a
        6- or 7-axis arm the region `executed` (the postures driven, ending at the stop)
        swept into last, never where the mission's own postures have the arm."""
        rep, cfg = self.report, self.config
        rep.collision_indications += 1
        q = np.asarray(ev.q if ev.q is not None else self._current_joints(), dtype=float)
        t0 = time.perf_counter()
        approach = None
        if executed is not None and len(executed) >= 2:
            approach = np.concatenate([np.asarray(executed, dtype=float)[:-1], q[None]])
        self.planner.roadmap.add_collision(q, approach=approach, protected=self._protected())
        self._last_indication_s = time.perf_counter() - t0
        p = self.robot.fk(q)[:3, 3] * 1000.0
        rep.log.append(f"{piece.label}: collision indicated at TCP ({p[0]:.0f}, {p[1]:.0f}, "
                       f"{p[2]:.0f}) mm - {ev.message}")
        learnt = self.planner.world.last_learnt
        if learnt:
            rep.log.append(f"  learnt {learnt}")
        if rep.collision_indications > cfg.max_indications:
            raise _End(EndReason.INDICATION_BUDGET,
                       f"more than {cfg.max_indications} collision indications; the last at "
                       f"{piece.label}")
        self._same_stop_again(q, piece)
        return q

    def _same_stop_again(self, q: Array, piece: PlanPiece) -> None:
        """End the run when the arm was stopped again where it was stopped before and what
        was learnt still lets it stand there: the evidence had to be left out next to a
        protected posture (`contact_region`: never where a goal or taught location has the
        arm), so every re-plan would lead back into the same contact until the indication
        budget is spent. Something is where the mission itself puts the arm."""
        w = self.planner.world
        again = any(np.abs(q - s).max() <= _SAME_STOP_RAD for s in self._stops)
        self._stops.append(q.copy())
        if not again or w.near_recorded_collision(q[None])[0]:
            return
        near = sorted({name for rc in w.collisions if rc.region is not None
                       for name in rc.region.cut_for})
        where = ", ".join(near) if near else "a posture of the mission"
        raise _End(EndReason.NO_PATH,
                   f"{piece.label}: stopped again at the same posture, and nothing can be "
                   f"learnt there without making {where} unreachable - something is where "
                   f"the arm must pass next to {where}: remove it, or re-teach {where} away "
                   "from it")

    def _protected(self) -> list[tuple[str, Array]]:
        """What an inference must never make unreachable: the ends of every piece of the
        run (the goal and the taught locations), the application paths' postures (the
        operator's paths) and the postures the world was built around (the taught ones)."""
        out: list[tuple[str, Array]] = []
        for it in self._queue or []:
            pc = it.piece
            if pc.kind == PieceKind.APPLICATION:
                D = pc.dense()
                out.append((f"path {pc.label}", D[::max(1, len(D) // 50)]))
            else:
                ends = pc.label.split("->")
                out.append((ends[0].strip() or pc.label, pc.q_start))
                out.append((ends[-1].strip() or pc.label, pc.q_end))
        anchors = self.planner.world.anchors
        if anchors is not None and len(anchors):
            out.append(("a taught location", np.atleast_2d(anchors)))
        return out

    def _blockers(self, q_target: Array, within: float = 0.15) -> str:
        """Which learnt regions lie nearest the arm at the posture a re-plan had to reach
        (within `within` m), in the operator's words, with how to forget them."""
        near = [(i, d) for i, d in self.planner.world.region_distances(q_target)
                if d <= within]
        if not near:
            return ""
        words = "; ".join(f"indication {i + 1} ({self.planner.world.describe_region(i)}) "
                          f"was learnt {d * 1000:.0f} mm from the arm there" for i, d in near)
        first = near[0][0] + 1
        return (f". What may block it: {words}. If nothing is there, forget it "
                f"(forget indication {first}) and run again")

    def _time_up_words(self) -> str:
        b, rep = self.bounds, self.report
        return (f"the run's {b.seconds:.0f} s of planning are used up at {self._where()} "
                f"after {rep.collision_indications} collision indication(s) and "
                f"{rep.replans} re-plan(s); the robot stands - resume or run again with a "
                "larger bound")

    def _world_version(self) -> tuple[int, int]:
        w = self.planner.world
        return len(w.collisions), hash(w.occupied().tobytes())

    # ------------------------------------------------------------------ helpers
    def _executed(self, path: Array, ev: LinkEvent) -> Array:
        """Configurations the arm went through on this drive, ending where it stopped."""
        path = np.asarray(path, dtype=float)
        if ev.kind == LinkEventKind.REACHED:
            return path
        k = len(path) - 1 if ev.path_index is None else int(np.clip(ev.path_index, 0,
                                                                      len(path) - 1))
        q = np.asarray(ev.q, dtype=float)[None] if ev.q is not None else path[k:k + 1]
        return np.concatenate([path[:k + 1], q])

    def _tcp_length(self, Q: Array) -> float:
        Q = np.asarray(Q, dtype=float)
        if len(Q) < 2:
            return 0.0
        P = self.robot.batch_fk(Q).positions
        return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())

    def _current_joints(self) -> Array:
        try:
            return np.asarray(self.link.current_joints(), dtype=float)
        except LinkLost as exc:
            raise _End(EndReason.LINK_LOST, f"connection lost: {exc}") from exc
        except LinkError as exc:
            raise _End(EndReason.LINK_ERROR, f"cannot read the robot's joints: {exc}") from exc

    def _where(self) -> str:
        if self._queue is not None and self._index < len(self._queue):
            return f"{self._queue[self._index].piece.label} ({self._phase.value})"
        return self._phase.value

    def _sub(self, a: float, b: float, task: str) -> Progress:
        assert self._progress is not None
        return self._progress.sub(a, b, task)

    def _bounded(self, parent: Progress, what: str) -> Progress:
        """`parent` for one planning call within the run's bound (`run_bounds`)."""
        return self.bounds.progress(parent, what, lambda: self.report.collision_indications)

    def _sub_here(self, task: str) -> Progress:
        assert self._progress is not None
        f = self._progress.fraction
        return self._progress.sub(f, f, task)
