"""A robot that exists only in the model, with obstacles the planner does not know.

`SimulatedRobot` moves along joint paths in (emulated) time at the robot's speed limits,
emits MOVED events at a fixed rate and can be stopped from any thread. Its **hidden
obstacles** stand for the parts of a real cell that no CAD model shows: before every step the
swept arm is checked against them (FCL) and on contact the robot stops at the last free
configuration and reports COLLISION_INDICATED - exactly what the operator's button does in
the thesis workflow, so scripted sessions and tests exercise re-planning without a person.

Deterministic: with a `VirtualClock` the same path gives the same events every run.
"""

from __future__ import annotations

import itertools
import re
import threading
from collections.abc import Callable, Iterable

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import ObstacleView
from assistant.links.arm_motion import PathFollower
from assistant.links.link import Halt, LinkError, LinkEvent, LinkEventKind, RobotLink
from assistant.links.timing import (
    Clock,
    RealClock,
    TimedPath,
    paced,
    time_parametrize,
    validate_path,
)
from assistant.robots.model import Robot

Array = np.ndarray

#: Wall seconds per step of the motion loop at most: how soon a stop takes (and how often the
#: pose is told) however slow the simulation runs.
MAX_WALL_STEP_S = 0.02
#: A motion step makes up at most this much wall time when the process fell behind (the
#: page's listeners on a loaded machine: 0.1-0.2 s); a longer stall is not made up, so the
#: arm never jumps further than a real one moves in that time.
CATCH_UP_WALL_S = 0.5


class SimulatedRobot(RobotLink):
    """The robot model moving in time, with hidden obstacles that trigger collision indications.

    Args:
        robot: the kinematic/collision model (shared, immutable).
        hidden_obstacles: obstacles the planner does not know; touching one stops the arm.
        known_obstacles: the cell the planner knows; checked only if `check_known` (a planner
            bug would then show up as a collision instead of a crash into CAD).
        time_scale: robot seconds per wall second when no `clock` is given.
        clock: a `Clock`; `VirtualClock()` for deterministic tests without waiting.
        start_q: initial joints (default: all zero, clipped into the limits).
        event_period_s: MOVED events are emitted every this many robot seconds.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        hidden_obstacles: Iterable[ObstacleView] = (),
        known_obstacles: Iterable[ObstacleView] = (),
        check_known: bool = False,
        time_scale: float = 1.0,
        clock: Clock | None = None,
        start_q: Array | None = None,
        event_period_s: float = 0.02,
    ):
        super().__init__()
        if event_period_s <= 0.0:
            raise ValueError("event_period_s must be > 0")
        self.robot = robot
        self.clock: Clock = clock if clock is not None else RealClock(time_scale)
        self.event_period_s = float(event_period_s)
        self._hidden = tuple(hidden_obstacles)
        self._known = tuple(known_obstacles)
        self._check_known = check_known
        self._checker = self._make_checker()
        q0 = np.zeros(robot.dof) if start_q is None else np.asarray(start_q, dtype=float)
        self._q = np.clip(q0, robot.limits.lower, robot.limits.upper)
        self._connected = False
        self._stop = threading.Event()
        self._indicate = threading.Event()
        self._indicate_msg = ""
        self._moving = threading.Lock()
        self._programs: dict[str, dict[str, bytes]] = {}
        self._upload_seq = itertools.count(1)
        #: The page's robot: touching a hidden obstacle halts the arm (as a real robot's
        #: collision detection would) and waits for the operator's Collision! (or Stop);
        #: scripts and tests keep the self-reporting robot (False).
        self.wait_for_operator = False

    def _make_checker(self) -> CollisionChecker | None:
        obstacles = list(self._hidden) + (list(self._known) if self._check_known else [])
        if not obstacles:
            return None
        # Self-collision is the planner's business; the hidden world is what this checks.
        return CollisionChecker(self.robot, obstacles, self_collision=False)

    # ------------------------------------------------------------------ configuration
    @property
    def hidden_obstacles(self) -> tuple[ObstacleView, ...]:
        return self._hidden

    def set_hidden_obstacles(self, obstacles: Iterable[ObstacleView]) -> None:
        """Replace the hidden world (e.g. a scripted session moves a box); not while moving."""
        with self._moving:
            self._hidden = tuple(obstacles)
            self._checker = self._make_checker()

    @property
    def programs(self) -> dict[str, dict[str, bytes]]:
        """Programs uploaded so far, by the unique name they were stored under."""
        return dict(self._programs)

    def set_joints(self, q: Array) -> None:
        """Stand the simulated arm at q (the session's posture when the link is made again,
        e.g. after the hidden obstacles changed): within the limits, not while moving."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (self.robot.dof,) or not np.isfinite(q).all():
            raise ValueError(f"set_joints needs {self.robot.dof} finite joint values")
        self._q = np.clip(q, self.robot.limits.lower, self.robot.limits.upper)

    # ------------------------------------------------------------------ RobotLink
    def connect(self) -> None:
        self._connected = True

    def close(self) -> None:
        self.stop()
        self._connected = False

    @property
    def connected(self) -> bool:
        return self._connected

    def current_joints(self) -> Array:
        return self._q.copy()

    def stop(self) -> None:
        self._stop.set()

    def indicate_collision(self, message: str = "operator pressed Collision!") -> None:
        """The human button: stop now and report COLLISION_INDICATED at the current posture.

        While moving, the motion loop reports it (with the path index); when idle the event
        is emitted at once.
        """
        self._indicate_msg = message
        if self._moving.acquire(blocking=False):
            try:
                self._emit(LinkEvent(LinkEventKind.COLLISION_INDICATED, self._q.copy(),
                                     self.clock.now(), message, None, {"source": "operator"}))
            finally:
                self._moving.release()
        else:
            self._indicate.set()

    def move_path(self, joint_path: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        path = validate_path(self.robot, joint_path)
        time_parametrize(path[:1], self.robot.limits.velocity, speed_scale)  # checks the scale
        return self._drive(path, lambda full: time_parametrize(
            full, self.robot.limits.velocity, speed_scale))

    def move_paced(self, joint_path: Array, t: Array, hold: Array, *,
                   speed_scale: float = 1.0) -> LinkEvent:
        """Follows the program's pace at 100 % override (`speed_scale` is for controllers,
        which time their own motions); the way in from where the arm stands, if any, at the
        joints' speed limits."""
        path = validate_path(self.robot, joint_path)
        timed = paced(path, t, hold)

        def with_lead(full: Array) -> TimedPath:
            if len(full) == len(path):
                return timed
            lead = time_parametrize(full[:2], self.robot.limits.velocity, 1.0).duration
            return TimedPath(np.vstack([full[:1], timed.q]), np.r_[0.0, timed.t + lead],
                             np.r_[0, timed.source + 1])
        return self._drive(path, with_lead)

    def _drive(self, path: Array, timing: Callable[[Array], TimedPath]) -> LinkEvent:
        if not self._connected:
            raise LinkError("simulated robot is not connected; call connect() first")
        # Cleared before taking the lock, so a stop or button press racing the start counts.
        self._stop.clear()
        self._indicate.clear()
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        try:
            return self._run(path, timing)
        finally:
            self._moving.release()

    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Stores the files under a unique name (base name + sequence number)."""
        base = re.sub(r"[^A-Za-z0-9_]", "_", name).strip("_") or "program"
        unique = f"{base}_{next(self._upload_seq):03d}"
        while unique in self._programs:
            unique = f"{base}_{next(self._upload_seq):03d}"
        self._programs[unique] = {k: bytes(v) for k, v in files.items()}
        return unique

    # ------------------------------------------------------------------ motion loop
    def _run(self, path: Array, timing: Callable[[Array], TimedPath]) -> LinkEvent:
        # The robot first goes from where it is to the path's first point (index 0).
        lead = 0 if np.allclose(path[0], self._q, atol=1e-9) else 1
        full = path if lead == 0 else np.vstack([self._q[None], path])
        timed = timing(full)
        follower = PathFollower(timed, self._checker)

        def index(seg: int) -> int:
            return int(max(0, timed.path_index(min(seg, len(timed.q) - 1)) - lead))

        start_hit = follower.check_start()
        if start_hit is not None:
            return self._finish_collision(follower.q, 0, start_hit.report, started=True)
        # The arm is where the clock says: each step waits for its due time and then moves
        # as far as the clock went, so the loop's own work (checks, listeners) does not slow
        # the run down (a 1x run lasts its time); a stalled process catches up at most
        # CATCH_UP_WALL_S at once.
        t_start = self.clock.now()
        catch_up = CATCH_UP_WALL_S * float(getattr(self.clock, "time_scale", 1.0))
        while True:
            if self._stop.is_set():
                return self._finish(LinkEventKind.STOPPED, index(follower.segment),
                                    "stopped on request")
            if self._indicate.is_set():
                return self._finish(LinkEventKind.COLLISION_INDICATED, index(follower.segment),
                                    self._indicate_msg, {"source": "operator"})
            left = follower.timed.duration - follower.t
            step = min(self._step_s(), left) if left > 0.0 else self._step_s()
            wait = t_start + follower.t + step - self.clock.now()
            if wait > 0.0:
                self.clock.sleep(wait)
            behind = self.clock.now() - t_start - follower.t
            adv = follower.advance(min(max(behind, step), max(catch_up, step)))
            if behind > catch_up:  # too far behind: the clock restarts here
                t_start = self.clock.now() - follower.t
            self._q = adv.q
            if adv.collision is not None:
                if self.wait_for_operator:
                    return self._halt_for_operator(adv.q, index(adv.segment),
                                                   adv.collision.report)
                return self._finish_collision(adv.q, index(adv.segment), adv.collision.report)
            if adv.finished:
                return self._finish(LinkEventKind.REACHED, len(path) - 1, "reached")
            self._emit(LinkEvent(LinkEventKind.MOVED, adv.q, self.clock.now(), "",
                                 index(adv.segment)))

    def _step_s(self) -> float:
        """Robot seconds per step of the motion loop: the event period, but never more than
        `MAX_WALL_STEP_S` of wall time - a slowed-down simulation (0.05x) still answers a stop
        and reports its pose at a human rate, as a real controller does."""
        scale = getattr(self.clock, "time_scale", None)
        return self.event_period_s if scale is None else \
            min(self.event_period_s, MAX_WALL_STEP_S * scale)

    def _halt_for_operator(self, q: Array, path_index: int, report) -> LinkEvent:
        """Halted against something: wait for the operator's Collision! (recorded here, where
        the arm touched) or Stop. A MOVED event now and then keeps Cancel working."""
        self._q = np.asarray(q, dtype=float).copy()
        what = report.describe() if report is not None else "contact"
        self._emit(LinkEvent(LinkEventKind.MOVED, self._q.copy(), self.clock.now(),
                             f"halted, touching something: {what}", path_index,
                             {"halted": True}, Halt(what)))
        while True:
            if self._indicate.wait(0.5):
                contacts = report.contacts if report is not None else ()
                return self._finish(LinkEventKind.COLLISION_INDICATED, path_index,
                                    f"{self._indicate_msg} (touching: {what})",
                                    {"source": "operator",
                                     "obstacles": sorted({c.other for c in contacts}),
                                     "links": sorted({c.link for c in contacts}),
                                     "started_in_contact": False})
            if self._stop.is_set():
                return self._finish(LinkEventKind.STOPPED, path_index, "stopped on request")
            self._emit(LinkEvent(LinkEventKind.MOVED, self._q.copy(), self.clock.now(),
                                 "halted", path_index, {"halted": True}))

    def _finish(self, kind: LinkEventKind, path_index: int, message: str,
                details: dict | None = None) -> LinkEvent:
        ev = LinkEvent(kind, self._q.copy(), self.clock.now(), message, path_index,
                       details or {})
        self._emit(ev)
        return ev

    def _finish_collision(self, q: Array, path_index: int, report, started: bool = False,
                          ) -> LinkEvent:
        contacts = report.contacts if report is not None else ()
        details = {
            "source": "hidden_obstacle",
            "obstacles": sorted({c.other for c in contacts}),
            "links": sorted({c.link for c in contacts}),
            "started_in_contact": started,
        }
        what = report.describe() if report is not None else "contact"
        self._q = np.asarray(q, dtype=float).copy()
        return self._finish(LinkEventKind.COLLISION_INDICATED, path_index,
                            f"collision indicated: {what}", details)
