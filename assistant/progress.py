"""Progress reporting and cancellation for long work (tables, roadmaps, planning, exploration).

Long functions take a `Progress` and call `progress.update(fraction, message)` now and then;
`update` raises `Cancelled` once someone called `cancel()`, so cancellation needs no extra
checks and the work unwinds through its normal `finally` blocks (the session stays
consistent). The UI maps these to viser progress bars; headless callers pass `Progress()`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass


class Cancelled(Exception):
    """Raised inside long work when the operator pressed Cancel."""


@dataclass(frozen=True)
class ProgressEvent:
    task: str
    fraction: float  # 0..1
    message: str


class Progress:
    """A cancellable progress sink; thread-safe; throttles callbacks to ~20 per second."""

    def __init__(self, task: str = "", callback: Callable[[ProgressEvent], None] | None = None,
                 *, min_interval_s: float = 0.05):
        self.task = task
        self._callback = callback
        self._cancel = threading.Event()
        self._last = 0.0
        self._min_interval = min_interval_s
        self.fraction = 0.0
        self.message = ""

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def check(self) -> None:
        if self._cancel.is_set():
            raise Cancelled(f"{self.task or 'work'} cancelled")

    def update(self, fraction: float, message: str = "", *, force: bool = False) -> None:
        self.check()
        self.fraction = max(0.0, min(1.0, float(fraction)))
        if message:
            self.message = message
        now = time.monotonic()
        if self._callback and (force or now - self._last >= self._min_interval
                               or self.fraction >= 1.0):
            self._last = now
            self._callback(ProgressEvent(self.task, self.fraction, self.message))

    def sub(self, start: float, end: float, task: str | None = None) -> Progress:
        """A child whose 0..1 maps onto [start, end] of this one; shares the cancel flag."""
        parent = self
        child = Progress(task or self.task, None)
        child._cancel = self._cancel

        def forward(ev: ProgressEvent) -> None:
            parent.update(start + (end - start) * ev.fraction, ev.message)

        child._callback = forward
        child._min_interval = 0.0
        return child
