"""The emulated controller's servo loop: the model moving through queued motions in time.

Both emulators own an `EmulatedArm`. A background thread ticks at the controller cycle
(7.1 ms by default), advances the head motion by the elapsed wall time times `time_scale`,
checks the swept arm against the emulator's hidden obstacles, and wakes whoever waits for a
motion. Queued motions run back to back without stopping, which is how MELFA's CNT blending
looks from outside (minus the corner rounding).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import ObstacleView
from assistant.emulators.faults import Faults
from assistant.links.arm_motion import Advance, PathFollower
from assistant.links.timing import time_parametrize
from assistant.robots.model import IKFailure, Robot
from assistant.transforms import rotation_angle

Array = np.ndarray

#: Wire formats round poses (MELFA: 0.01 deg). A 5-axis arm cannot take an orientation that is
#: off its arm plane by even that much, so targets within this angle are projected first.
WIRE_ORIENTATION_TOL_RAD = np.radians(0.05)


@dataclass
class Motion:
    """One queued move: joint waypoints (not including the start) at a fraction of full speed."""

    waypoints: Array
    speed: float
    tag: str = ""
    done: threading.Event = field(default_factory=threading.Event)
    outcome: str = ""  # reached | stopped | collision | dropped
    #: Robot seconds the motion takes at its speed, from where the arm was when it started.
    duration_s: float = 0.0


@dataclass(frozen=True)
class CollisionInfo:
    q_free: Array
    obstacles: tuple[str, ...]
    description: str


class EmulatedArm:
    """Moves a robot model through queued joint motions in (scaled) wall time."""

    def __init__(
        self,
        robot: Robot,
        *,
        hidden_obstacles: Iterable[ObstacleView] = (),
        time_scale: float = 1.0,
        tick_s: float = 0.0071,
        start_q: Array | None = None,
        faults: Faults | None = None,
        on_collision: Callable[[CollisionInfo], None] | None = None,
        on_drop: Callable[[], None] | None = None,
    ):
        if time_scale <= 0.0 or tick_s <= 0.0:
            raise ValueError("time_scale and tick_s must be > 0")
        self.robot = robot
        self.time_scale = float(time_scale)
        self.tick_s = float(tick_s)
        self.faults = faults or Faults()
        self.on_collision = on_collision
        self.on_drop = on_drop
        hidden = list(hidden_obstacles)
        self._checker = (CollisionChecker(robot, hidden, self_collision=False)
                         if hidden else None)
        q0 = np.zeros(robot.dof) if start_q is None else np.asarray(start_q, dtype=float)
        self._q = np.clip(q0, robot.limits.lower, robot.limits.upper)
        self._queue: deque[Motion] = deque()
        self._follower: PathFollower | None = None
        self._cond = threading.Condition()
        self._closed = threading.Event()
        self._thread: threading.Thread | None = None
        self._moved_total = 0.0
        self._drop_base: float | None = None
        self.last_collision: CollisionInfo | None = None
        #: Set by a collision: new motions end at once with outcome "collision" until
        #: `clear_fault()` (the alarm reset), as on a controller in error.
        self._faulted = False

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name="emulated-arm", daemon=True)
            self._thread.start()

    def close(self) -> None:
        self._closed.set()
        self.stop_all("stopped")
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    # ------------------------------------------------------------------ state
    @property
    def q(self) -> Array:
        with self._cond:
            return self._q.copy()

    def set_q(self, q: Array) -> None:
        with self._cond:
            self._q = np.asarray(q, dtype=float).copy()

    @property
    def moving(self) -> bool:
        with self._cond:
            return bool(self._queue)

    def queue_length(self) -> int:
        with self._cond:
            return len(self._queue)

    def planned_end(self) -> Array:
        """Where the arm will be once the queue is done (start of the next queued motion)."""
        with self._cond:
            return (self._queue[-1].waypoints[-1] if self._queue else self._q).copy()

    # ------------------------------------------------------------------ commands
    def enqueue(self, waypoints: Array, speed: float = 1.0, tag: str = "") -> Motion:
        W = np.atleast_2d(np.asarray(waypoints, dtype=float))
        m = Motion(W, float(np.clip(speed, 1e-3, 1.0)), tag)
        with self._cond:
            if self._faulted:
                m.outcome = "collision"
                m.done.set()
                return m
            self._queue.append(m)
            self._cond.notify_all()
        return m

    @property
    def faulted(self) -> bool:
        with self._cond:
            return self._faulted

    @property
    def faulted_now(self) -> bool:
        """`faulted` without waiting for the motion lock (a state stream at 500 Hz must not
        queue behind the motion loop; reading one bool needs no lock)."""
        return self._faulted

    def clear_fault(self) -> None:
        with self._cond:
            self._faulted = False

    def stop_all(self, outcome: str = "stopped") -> None:
        with self._cond:
            self._halt(outcome)
            self._cond.notify_all()

    def wait(self, motion: Motion, timeout: float | None = None,
             abort: threading.Event | None = None) -> str:
        """Block until the motion ends (or `abort` is set); returns its outcome ('' if not)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while not motion.done.is_set():
                if abort is not None and abort.is_set():
                    break
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                self._cond.wait(0.05 if left is None else min(left, 0.05))
            return motion.outcome

    def wait_queue_at_most(self, n: int, abort: threading.Event) -> None:
        with self._cond:
            while len(self._queue) > n and not abort.is_set() and not self._closed.is_set():
                self._cond.wait(0.05)

    # ------------------------------------------------------------------ servo loop
    def _halt(self, outcome: str) -> None:
        while self._queue:
            m = self._queue.popleft()
            m.outcome = outcome
            m.done.set()
        self._follower = None

    def _loop(self) -> None:
        last = time.monotonic()
        next_tick = last + self.tick_s
        while not self._closed.is_set():
            delay = next_tick - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            next_tick += self.tick_s
            now = time.monotonic()
            if now - next_tick > 10 * self.tick_s:  # fell far behind (debugger, load)
                next_tick = now + self.tick_s
            dt = (now - last) * self.time_scale
            last = now
            hit: CollisionInfo | None = None
            dropped = False
            with self._cond:
                before = self._moved_total
                if self._queue:
                    hit = self._step(dt)
                # A streamed target is often reached within one tick: the queue is empty at
                # every check although the arm never stops, so "moving" is "moved this tick".
                dropped = self._check_drop(bool(self._queue) or self._moved_total > before)
                self._cond.notify_all()
            if hit is not None and self.on_collision is not None:
                self.on_collision(hit)
            if dropped:
                # A pulled cable: the peers lose the wire before anything on it could report
                # the halted arm or the ended program (else a client may read "stopped").
                if self.on_drop is not None:
                    self.on_drop()
                with self._cond:
                    self._halt("dropped")
                    self._cond.notify_all()

    def _step(self, dt: float) -> CollisionInfo | None:
        budget = dt
        while budget > 1e-12 and self._queue:
            m = self._queue[0]
            if self._follower is None:
                path = np.vstack([self._q[None], m.waypoints])
                timed = time_parametrize(path, self.robot.limits.velocity, m.speed)
                m.duration_s = timed.duration
                self._follower = PathFollower(timed, self._checker)
            adv: Advance = self._follower.advance(budget)
            budget -= adv.used_s
            self._moved_total += adv.used_s
            self._q = adv.q
            if adv.collision is not None:
                info = CollisionInfo(adv.q.copy(), tuple(adv.contact_names()),
                                     adv.describe_contact())
                self.last_collision = info
                self._faulted = True
                self._halt("collision")
                return info
            if adv.finished:
                self._queue.popleft()
                self._follower = None
                m.outcome = "reached"
                m.done.set()
            elif adv.used_s <= 0.0:
                break
        return None

    def _check_drop(self, moving: bool) -> bool:
        if not self.faults.drop_armed:
            self._drop_base = None
            return False
        if self._drop_base is None:
            self._drop_base = self._moved_total
        if moving and self.faults.should_drop(self._moved_total - self._drop_base):
            self._drop_base = None
            return True
        return False


def solve_wire_pose(robot: Robot, T_base_tool: Array, seed: Array,
                    accept: Callable[[Array], bool], *,
                    project_tol_rad: float = WIRE_ORIENTATION_TOL_RAD,
                    ) -> tuple[Array | None, str]:
    """IK for a pose that came over the wire: the accepted solution nearest `seed`.

    Orientation errors up to `project_tol_rad` (default: the wire's rounding) are projected
    onto the reachable set first; interpolated Cartesian paths pass `np.pi`, because a
    5-axis controller keeps the tool in the arm plane along a line or arc.
    Returns (q, "") or (None, reason).
    """
    res = robot.ik(T_base_tool, seed)
    if not res.ok and res.failure == IKFailure.ORIENTATION and \
            res.nearest_T_base_tool is not None:
        R_err = res.nearest_T_base_tool[:3, :3].T @ np.asarray(T_base_tool)[:3, :3]
        angle = rotation_angle(R_err)
        if angle <= project_tol_rad:
            res = robot.ik(res.nearest_T_base_tool, seed)
    if not res.ok:
        return None, res.message or "no inverse kinematics solution"
    good = [q for q in res.solutions if accept(q)]
    if not good:
        return None, "no solution with the requested arm configuration"
    seed = np.asarray(seed, dtype=float)
    return min(good, key=lambda q: float(np.linalg.norm(q - seed))), ""
