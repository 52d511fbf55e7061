"""The enabling switch's wire: the holder's page must answer a websocket ping.

Every `PING_S` the page server pings the websocket of the page that holds motion authority (a
protocol-level ping: the browser answers it on its network thread, even while its page script
is busy drawing). A page that has not answered for `SILENT_S` is silent: the session's
`MotionHold` hears it and the robot stops; an answer later makes it present again (the holder
then resumes by hand - nothing starts by itself). A page that closes needs no ping: the
end of its websocket is the `left` event, told from here the moment the socket closes (before
viser tears the client down and calls its disconnect callbacks, a few steps later).

Behind the gate the front passes pings and pongs through (`web.gate.front`), so the ping
reaches the browser, not the front. If the page server itself was stalled (a busy machine:
the pinging loop ran late), the silence is the server's, not the page's: the clock restarts.

This reads viser's live connections (a viser internal, like `web.uploads`): if they move, the
pings fail and the holder counts as silent - it fails safe (the robot does not move).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import Any

from assistant.session.motion_hold import MotionHold

log = logging.getLogger(__name__)

#: How often the holder's page is pinged (s).
PING_S = 0.1
#: No answer for this long: the holder's page is silent and the robot stops (s).
SILENT_S = 0.5
#: The pinging loop itself ran this late: the server was stalled, not the page (s).
STALL_S = 0.25


class Heartbeat:
    """Pings the holder's page on viser's event loop; tells `hold` when it falls silent."""

    def __init__(self, server: Any, hold: MotionHold):
        self._ws = server._websock_server  # noqa: SLF001 - see the module docstring
        self._hold = hold
        self._last_pong: dict[int, float] = {}
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
            stalled = now - last_tick > STALL_S
            last_tick = now
            holder = self._hold.state.holder
            if holder is None:
                self._last_pong.clear()
                continue
            if stalled or holder not in self._last_pong:
                self._last_pong = {holder: now}  # a new holder, or our own late tick
            conn = self._connection(holder)
            if conn is not None and self._watched != holder:
                self._watched = holder
                asyncio.ensure_future(self._watch_close(holder, conn))
            if conn is not None:
                with contextlib.suppress(Exception):  # a closing socket: `left` comes next
                    waiter = await conn.ping()
                    waiter.add_done_callback(lambda f, h=holder: self._pong(h, f))
            age = now - self._last_pong.get(holder, now)
            silent = age > SILENT_S
            if silent and self._hold.state.present:
                log.warning("holder %s silent: no answer for %.2f s (loop tick %.2f s late)",
                            holder, age, late)
            self._hold.heard(holder, not silent)

    async def _watch_close(self, holder: int, conn: Any) -> None:
        """The holder's socket closed: tell the hold now (on a thread: the link's stop may
        talk to a controller, which must not stall the page server's loop)."""
        with contextlib.suppress(Exception):
            await conn.wait_closed()
            if self._hold.state.holder == holder:
                asyncio.get_running_loop().run_in_executor(None, self._hold.left, holder)

    def _pong(self, holder: int, answered: Any) -> None:
        if not answered.cancelled() and answered.exception() is None:  # not a closed socket
            self._last_pong[holder] = time.monotonic()
