"""The marker pointer running live for the UI: a thread stepping `vision.PointerSystem`.

With the synthetic camera (the default of the sample cells) a `SyntheticHand` holds the ball:
the UI moves it to a point (the stand-in for the operator's hand), the cameras render it and
the real pipeline - detection, triangulation, tracking, dwell - measures it, so a taught
point carries real measurement error, exactly as with real cameras.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable, Sequence

import numpy as np

from vision.dwell import TaughtPoint
from vision.pointer import PointerState, PointerSystem
from vision.scene import PointerScene

Array = np.ndarray


def _min_jerk(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


#: Where the simulated hand starts, relative to its first target (m): 12 cm above it.
ENTER_FROM = np.array([0.0, 0.0, 0.12])


class SyntheticHand:
    """Where the simulated operator holds the ball, as a function of camera time."""

    def __init__(self, start: Array | None = None, move_s: float = 0.8,
                 tremor: float = 0.0003, seed: int = 0):
        self._lock = threading.Lock()
        self._from = None if start is None else np.asarray(start, float)
        self._to = self._from
        self._t0 = 0.0
        self._move_s = move_s
        self._now = 0.0
        rng = np.random.default_rng(seed)
        self._freqs = rng.uniform(0.5, 3.0, size=(3, 3))
        self._phases = rng.uniform(0, 2 * np.pi, size=(3, 3))
        self._tremor = tremor

    def move_to(self, p: Array | None) -> None:
        """Bring the ball to p (None: take the pointer out of view)."""
        with self._lock:
            here = self._position(self._now)
            # Out of view before: the hand brings the ball in from above, as an operator
            # does - the pointer offers a fresh track only once it has moved (a still blob
            # may be a look-alike in the background).
            self._from = here if here is not None else (None if p is None else
                                                       np.asarray(p, float) + ENTER_FROM)
            self._to = None if p is None else np.asarray(p, float)
            self._t0 = self._now

    def path(self, t: float) -> Array | None:
        with self._lock:
            self._now = max(self._now, t)
            p = self._position(t)
        if p is None:
            return None
        wobble = np.sin(2 * np.pi * self._freqs * t + self._phases).sum(axis=1) / np.sqrt(1.5)
        return p + self._tremor * wobble

    def _position(self, t: float) -> Array | None:
        if self._to is None:
            return None
        if self._from is None:
            return self._to
        s = _min_jerk((t - self._t0) / self._move_s)
        return self._from + (self._to - self._from) * s


def shown_state(state: PointerState) -> PointerState:
    """The state as the page may show it: the position only while measured (the measurement
    itself when it is fit to teach), or coasting for at most `coast_s`; and as the mode the
    status word when it is not a teaching fix ("coasting", "not measured", "single view",
    "unconfirmed"), so nothing unmeasured is drawn or read as the pointer. `state.taught` is
    untouched (it is made from measured frames only)."""
    if state.offered:
        return dataclasses.replace(state, position_world=state.offered_position)
    return dataclasses.replace(state, position_world=state.drawn_position, mode=state.status)


class LivePointer:
    """Runs the pointer pipeline at up to `rate_hz`; calls `on_state` with every state."""

    def __init__(self, models: Sequence, *, on_state: Callable[[PointerState], None],
                 seed: int = 0, rate_hz: float = 20.0, start: Array | None = None):
        self.hand = SyntheticHand(start, seed=seed)
        self.scene = PointerScene(self.hand.path)
        self.system = PointerSystem.synthetic(list(models), self.scene, seed=seed)
        self._on_state = on_state
        self._period = 1.0 / rate_hz
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.last_state: PointerState | None = None
        self.last_taught: TaughtPoint | None = None
        self.errors = 0

    def start(self) -> None:
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="cellteach-pointer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self.system.close()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        while not self._stop.is_set():
            t0 = time.monotonic()
            try:
                state = self.system.step()
            except Exception:  # noqa: BLE001 - a camera hiccup must not kill the loop
                self.errors += 1
                self._stop.wait(0.2)
                continue
            self.last_state = state
            if state.taught is not None:
                self.last_taught = state.taught
            self._on_state(shown_state(state))
            self._stop.wait(max(0.0, self._period - (time.monotonic() - t0)))
