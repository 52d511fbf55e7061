"""The enabling switch's wire: the holder's page must answer a websocket ping.

Every `PING_S` the page server pings the websocket of the page that holds motion authority (a
protocol-level ping: the browser answers it on its network thread, even while its page script
is busy drawing). A page that has not answered for `SILENT_S` is silent: the session's
`MotionHold` hears it and the robot stops; an answer later makes it present again (the holder
then resumes by hand - nothing starts by itself). A page that closes needs no ping: the
end of its websocket is the `left` event, told from here the moment the socket closes (before
viser tears the client down and calls its disconnect callbacks, a few steps later).

Behind the gate the front passes pings and pongs through (`web.gate.front`), so the ping
reaches the browser, not the front. Silence is counted in the time the server could have
heard an answer (`SilenceClock`): whenever the pinging loop runs late (a busy machine), that
lateness is the server's, not the page's, and is not counted - one stall or many small ones.
A page that is gone is still known silent `SILENT_S` after its last answer on an idle server.

This reads viser's live connections (a viser internal, like `web.uploads`): if they move, the
pings fail and the holder counts as silent - it fails safe (the robot does not move).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from dataclasses import dataclass
from typing import Any

from assistant.session.motion_hold import MotionHold

log = logging.getLogger(__name__)

#: How often the holder's page is pinged (s).
PING_S = 0.1
#: No answer for this long: the holder's page is silent and the robot stops (s).
SILENT_S = 0.5


@dataclass
class SilenceClock:
    """How long the holder's page has not answered, less the time the server itself was
    late (its loop could not have handled an answer then)."""

    #: When the page last answered (or became the holder), monotonic s.
    last: float
    #: The server loop's lateness since then (s).
    owed: float = 0.0

    def answered(self, now: float) -> None:
        self.last, self.owed = now, 0.0

    def server_late(self, by: float) -> None:
        self.owed += max(0.0, by)

    def silent_for(self, now: float) -> float:
        return now - self.last - self.owed


class Heartbeat:
    """Pings the holder's page on viser's event loop; tells `hold` when it falls silent."""

    def __init__(self, server: Any, hold: MotionHold):
        self._ws = server._websock_server  # noqa: SLF001 - see the module docstring
        self._hold = hold
        self._clock: dict[int, SilenceClock] = {}
        self._task: Any = None
        self._watched: int | None = None

    def start(self) -> None:
        loop = getattr(self._ws, "_background_event_loop", None)
        if loop is None:
            log.error("viser internals changed: no heartbeat (the holder counts as silent)")
            return
        self._task = asyncio.run_coroutine_threadsafe(self._run(), loop)

    def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()

    def _connection(self, client_id: int) -> Any:
        try:
            return self._ws._live_connections.get(client_id)  # noqa: SLF001
        except AttributeError:
            return None

    async def _run(self) -> None:
        last_tick = time.monotonic()
        while True:
            await asyncio.sleep(PING_S)
            now = time.monotonic()
            late = now - last_tick - PING_S
            last_tick = now
            holder = self._hold.state.holder
            if holder is None:
                self._clock.clear()
                continue
            if holder not in self._clock:
                self._clock = {holder: SilenceClock(now)}  # a new holder
            else:
                self._clock[holder].server_late(late)
            conn = self._connection(holder)
            if conn is not None and self._watched != holder:
                self._watched = holder
                asyncio.ensure_future(self._watch_close(holder, conn))
            if conn is not None:
                with contextlib.suppress(Exception):  # a closing socket: `left` comes next
                    waiter = await conn.ping()
                    waiter.add_done_callback(lambda f, h=holder: self._pong(h, f))
            clock = self._clock[holder]
            silent = clock.silent_for(now) > SILENT_S
            if silent and self._hold.state.present:
                log.warning("holder %s silent: no answer for %.2f s, %.2f s of it the server's",
                            holder, now - clock.last, clock.owed)
            self._hold.heard(holder, not silent)

    async def _watch_close(self, holder: int, conn: Any) -> None:
        """The holder's socket closed: tell the hold now (on a thread: the link's stop may
        talk to a controller, which must not stall the page server's loop)."""
        with contextlib.suppress(Exception):
            await conn.wait_closed()
            if self._hold.state.holder == holder:
                asyncio.get_running_loop().run_in_executor(None, self._hold.left, holder)

    def _pong(self, holder: int, answered: Any) -> None:
        clock = self._clock.get(holder)
        if clock is not None and not answered.cancelled() and answered.exception() is None:
            clock.answered(time.monotonic())  # (not a closed socket)
