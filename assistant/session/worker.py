"""One background worker for long work, so the UI thread never blocks.

At most one long task runs at a time (the workflow's busy mode guarantees it); its
`Progress` forwards to the event bus and can be cancelled from any thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

from assistant.progress import Cancelled, Progress, ProgressEvent
from assistant.session.events import EventBus, ProgressChanged


class Worker:
    def __init__(self, bus: EventBus):
        self._bus = bus
        self._lock = threading.Lock()
        self._progress: Progress | None = None
        self._thread: threading.Thread | None = None
        self._active = False  # cleared before the caller's future resolves (no join race)

    @property
    def busy(self) -> bool:
        return self._active

    def cancel(self) -> bool:
        with self._lock:
            if self._progress is None:
                return False
            self._progress.cancel()
            return True

    def submit(self, task: str, fn: Callable[[Progress], Any],
               on_done: Callable[[Future], None] | None = None) -> Future:
        """Run fn(progress) in the background; the future holds its result or exception."""
        fut: Future = Future()

        def forward(ev: ProgressEvent) -> None:
            self._bus.emit(ProgressChanged(ev.task, ev.fraction, ev.message))

        progress = Progress(task, forward)

        def run() -> None:
            # The outcome is handed to `on_done` (which ends the busy/moving mode) *before* the
            # caller's future resolves, so `submit(...).result()` returns to a session that is
            # idle again and the next action is accepted.
            outcome: Future = Future()
            try:
                outcome.set_result(fn(progress))
            except BaseException as exc:  # noqa: BLE001 - delivered through the future
                outcome.set_exception(exc)
            with self._lock:
                self._progress = None
            cancelled = isinstance(outcome.exception(), Cancelled)
            self._bus.emit(ProgressChanged(task, 1.0 if not cancelled else progress.fraction,
                                           "cancelled" if cancelled else "done", done=True))
            try:
                if on_done is not None:
                    on_done(outcome)
            finally:
                with self._lock:
                    self._active = False
                error = outcome.exception()
                if error is None:
                    fut.set_result(outcome.result())
                else:
                    fut.set_exception(error)

        with self._lock:
            if self.busy:
                raise RuntimeError("another long task is still running")
            self._progress = progress
            self._active = True
            self._thread = threading.Thread(target=run, name=f"cellteach-{task}", daemon=True)
            self._thread.start()
        return fut

    def join(self, timeout: float | None = None) -> None:
        t = self._thread
        if t is not None:
            t.join(timeout)
