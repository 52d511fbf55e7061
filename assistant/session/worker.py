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

    @property
    def busy(self) -> bool:
        t = self._thread
        return t is not None and t.is_alive()

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
            try:
                fut.set_result(fn(progress))
            except BaseException as exc:  # noqa: BLE001 - delivered through the future
                fut.set_exception(exc)
            finally:
                with self._lock:
                    self._progress = None
                cancelled = isinstance(fut.exception(), Cancelled)
                self._bus.emit(ProgressChanged(task, 1.0 if not cancelled else progress.fraction,
                                               "cancelled" if cancelled else "done", done=True))
                if on_done is not None:
                    on_done(fut)

        with self._lock:
            if self.busy:
                raise RuntimeError("another long task is still running")
            self._progress = progress
            self._thread = threading.Thread(target=run, name=f"cellteach-{task}", daemon=True)
            self._thread.start()
        return fut

    def join(self, timeout: float | None = None) -> None:
        t = self._thread
        if t is not None:
            t.join(timeout)
