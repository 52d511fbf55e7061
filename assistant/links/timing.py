"""Time along joint paths: clocks, and the slowest-joint (time-optimal per segment) timing.

Every link and emulator times a joint path the same way: each straight joint-space segment
takes as long as its slowest joint needs at its speed limit (times a speed scale), all joints
arriving together. That is what a synchronous PTP / MOV does on a real controller, minus the
acceleration ramps (an honest simplification: our emulated arms have infinite acceleration).

Clocks exist so the simulated robot can run on a virtual clock (deterministic tests, no
waiting) or on wall time sped up by `time_scale`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from assistant.links.link import LinkError
from assistant.robots.model import Robot

Array = np.ndarray


class Clock(Protocol):
    """Emulated seconds: `now()` and `sleep(dt)`, both in the robot's time."""

    def now(self) -> float: ...

    def sleep(self, dt: float) -> None: ...


class RealClock:
    """Wall time, optionally sped up: `time_scale=10` runs ten robot seconds per wall second."""

    def __init__(self, time_scale: float = 1.0):
        if time_scale <= 0.0:
            raise ValueError(f"time_scale must be > 0, got {time_scale}")
        self.time_scale = float(time_scale)
        self._t0 = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self._t0) * self.time_scale

    def sleep(self, dt: float) -> None:
        if dt > 0.0:
            time.sleep(dt / self.time_scale)


class VirtualClock:
    """Time that moves only when someone sleeps: a whole motion runs in no wall time."""

    def __init__(self, start: float = 0.0):
        self._t = float(start)
        self._lock = threading.Lock()

    def now(self) -> float:
        return self._t

    def sleep(self, dt: float) -> None:
        with self._lock:
            self._t += max(0.0, float(dt))


@dataclass(frozen=True)
class TimedPath:
    """Joint vertices `q` (N, dof) reached at cumulative times `t` (N,), t[0] = 0.

    `source[i]`: the caller's path index of vertex i (None: the same index). A hold (the arm
    standing at a vertex for a gripper action) is the vertex twice, both with one source.
    """

    q: Array
    t: Array
    source: Array | None = None

    def path_index(self, vertex: int) -> int:
        """The caller's path index of vertex (or segment) `vertex`."""
        return int(vertex if self.source is None else self.source[int(vertex)])

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def segment_at(self, t: float) -> int:
        """Index i of the segment q[i] -> q[i+1] that is under way at time t."""
        if len(self.t) < 2:
            return 0
        i = int(np.searchsorted(self.t, t, side="right")) - 1
        return int(np.clip(i, 0, len(self.t) - 2))

    def sample(self, t: float) -> tuple[Array, int]:
        """Configuration at time t (clamped to the path) and its segment index."""
        if len(self.t) < 2:
            return self.q[0].copy(), 0
        t = float(np.clip(t, 0.0, self.duration))
        i = self.segment_at(t)
        dt = self.t[i + 1] - self.t[i]
        f = 1.0 if dt <= 0.0 else (t - self.t[i]) / dt
        return self.q[i] + f * (self.q[i + 1] - self.q[i]), i

    def resample(self, period: float) -> tuple[Array, Array]:
        """Targets every `period` seconds (and the final vertex): (M, dof) and segment indices."""
        if period <= 0.0:
            raise ValueError("period must be > 0")
        n = max(1, int(np.ceil(self.duration / period - 1e-9)))
        times = np.minimum(np.arange(1, n + 1) * period, self.duration)
        out = np.empty((n, self.q.shape[1]))
        seg = np.empty(n, dtype=np.int64)
        for k, tk in enumerate(times):
            out[k], seg[k] = self.sample(float(tk))
        out[-1] = self.q[-1]
        return out, seg


def validate_path(robot: Robot, joint_path: Array) -> Array:
    """The path as an (N, dof) float array, or a `LinkError` naming the first bad point.

    Called before anything is sent: an out-of-limit or malformed target never reaches a robot.
    """
    try:
        P = np.array(joint_path, dtype=float)
    except (TypeError, ValueError) as exc:
        raise LinkError(f"joint path is not numeric: {exc}") from exc
    if P.ndim == 1:
        P = P[None]
    if P.ndim != 2 or P.shape[1] != robot.dof or len(P) == 0:
        raise LinkError(f"joint path must have shape (N, {robot.dof}), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise LinkError("joint path contains NaN or infinite values")
    bad = np.nonzero(~robot.limits.contains_batch(P))[0]
    if len(bad):
        i = int(bad[0])
        why = ", ".join(robot.limits.violations(P[i], robot.joint_names))
        raise LinkError(f"target {i} of the joint path is outside the joint limits ({why}); "
                        "nothing was sent")
    return P


def paced(path: Array, t: Array, hold: Array, override: float = 1.0) -> TimedPath:
    """The path at the program's pace: vertex i reached at `t[i]` and held `hold[i]` seconds,
    every time stretched by 1 / `override` (the pendant's speed override, in (0, 1])."""
    if not 0.0 < override <= 1.0:
        raise LinkError(f"speed override must be in (0, 1], got {override}")
    P = np.asarray(path, dtype=float)
    T = np.asarray(t, dtype=float)
    H = np.asarray(hold, dtype=float)
    if T.shape != (len(P),) or H.shape != (len(P),) or not (np.all(np.isfinite(T))
                                                           and np.all(np.isfinite(H))):
        raise LinkError(f"pace must give a finite time and hold per path point ({len(P)})")
    if np.any(np.diff(T) < 0.0) or np.any(H < 0.0):
        raise LinkError("pace times must not run backwards")
    rep = np.where(H > 0.0, 2, 1)
    src = np.repeat(np.arange(len(P)), rep)
    q = P[src]
    times = np.empty(len(src))
    k = 0
    for i in range(len(P)):
        times[k] = T[i]
        if rep[i] == 2:
            times[k + 1] = T[i] + H[i]
        k += rep[i]
    return TimedPath(q, (times - times[0]) / override, src)


def time_parametrize(path: Array, velocity: Array, speed_scale: float = 1.0) -> TimedPath:
    """Slowest-joint timing: each segment lasts max_i |dq_i| / (v_i * speed_scale)."""
    if not 0.0 < speed_scale <= 1.0:
        raise LinkError(f"speed_scale must be in (0, 1], got {speed_scale}")
    P = np.asarray(path, dtype=float)
    v = np.asarray(velocity, dtype=float) * speed_scale
    if len(P) < 2:
        return TimedPath(P.copy(), np.zeros(len(P)))
    seg = np.max(np.abs(np.diff(P, axis=0)) / v[None], axis=1)
    return TimedPath(P.copy(), np.concatenate([[0.0], np.cumsum(seg)]))
