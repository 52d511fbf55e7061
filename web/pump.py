"""One UI thread between the session's events and the viser handles.

Session events arrive on worker, link and camera threads that must never wait for the page,
so the subscriber only queues them; this thread applies them in order. Bursts of robot and
pointer updates are coalesced to the newest, so a 50 Hz robot never floods the page.

Each item is applied inside `settled()` (the session's `Session.settled`: its lock), so the
page reads the session only between actions - an action saves before it lets go of the lock,
so nothing the page shows can be lost by a crash (`assistant.session.saving`).
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

from assistant.session.events import Event, EventBus, PointerUpdated, RobotMoved

log = logging.getLogger(__name__)

#: Events of which only the newest in a burst matters.
COALESCED: tuple[type, ...] = (RobotMoved, PointerUpdated)
#: A burst that starts with a coalesced event waits this long to gather the rest (~30 Hz).
BURST_S = 1.0 / 30.0

_STOP = object()


class EventPump:
    """Queues session events (and posted jobs) and runs them on one daemon thread."""

    def __init__(self, dispatch: Callable[[Event], None], *, on_queue: Callable[[Event], None]
                 | None = None,
                 settled: Callable[[], AbstractContextManager[Any]] | None = None):
        self._dispatch = dispatch
        self._on_queue = on_queue
        self._settled = settled or contextlib.nullcontext
        self._q: queue.Queue[Any] = queue.Queue()
        self._unsubscribe: Callable[[], None] | None = None
        self._idle = threading.Event()
        self._idle.set()
        #: Set by `stop`: items still queued or in a batch are dropped, not drawn - after
        #: the page stops, its handles must not be touched.
        self._halt = threading.Event()
        self._pending = 0
        self._lock = threading.Lock()
        self.errors: list[str] = []
        self._thread = threading.Thread(target=self._run, name="cellteach-ui", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ input
    def attach(self, bus: EventBus) -> None:
        """Subscribe to a session's bus (once; a later attach replaces it)."""
        self.detach()
        self._unsubscribe = bus.subscribe(self._enqueue)

    def detach(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def _enqueue(self, ev: Event) -> None:
        if self._on_queue is not None:
            self._on_queue(ev)  # must be cheap: runs on the emitting thread
        self._put(ev)

    def post(self, job: Callable[[], None]) -> None:
        """Run `job` on the UI thread after everything queued before it."""
        self._put(job)

    def _put(self, item: Any) -> None:
        with self._lock:
            self._pending += 1
            self._idle.clear()
        self._q.put(item)

    # ------------------------------------------------------------------ UI thread
    def _run(self) -> None:
        last = 0.0
        while True:
            batch = [self._q.get()]
            if isinstance(batch[0], COALESCED):
                # A fast robot (simulated at 20x) emits hundreds of poses a second: draw at
                # most ~30 per second, the page cannot show more anyway.
                wait = last + BURST_S - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            last = time.monotonic()
            while True:
                try:
                    batch.append(self._q.get_nowait())
                except queue.Empty:
                    break
            if any(item is _STOP for item in batch):
                return
            for item in _coalesce(batch):
                if self._halt.is_set():
                    return
                try:
                    with self._settled():
                        if isinstance(item, Event):
                            self._dispatch(item)
                        else:
                            item()
                except Exception as exc:  # noqa: BLE001 - one bad redraw must not stop the page
                    log.exception("UI update failed")
                    self.errors.append(f"{type(item).__name__}: {exc!r}")
            with self._lock:
                self._pending -= len(batch)
                if self._pending == 0:
                    self._idle.set()

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until every queued event has been applied (tests and benchmarks)."""
        return self._idle.wait(timeout)

    def stop(self) -> None:
        """Stop drawing: the item being drawn finishes (up to 2 s), nothing after it runs."""
        self.detach()
        self._halt.set()
        self._q.put(_STOP)
        self._thread.join(2.0)


def _coalesce(batch: list[Any]) -> list[Any]:
    """Keep order, but only the last of each coalesced event type."""
    last: dict[type, int] = {}
    for i, item in enumerate(batch):
        if isinstance(item, COALESCED):
            last[type(item)] = i
    return [item for i, item in enumerate(batch)
            if not isinstance(item, COALESCED) or last[type(item)] == i]
