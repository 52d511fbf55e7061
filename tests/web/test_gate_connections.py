"""Connection hygiene at the front, with real sockets: a connection that never finishes its
request head is closed, one address holds at most its share while others still get in, a
stalled request is closed as idle while a live websocket (pinged) stays, and the budget keeps
the connections below the open-files limit."""

from __future__ import annotations

import asyncio
import socket

import aiohttp
from gate_helpers import (  # noqa: F401
    CAMERA,
    VISER_PROTOCOL,
    client,
    encode,
    gated_fixture,
    local_url,
    run,
    sign_in,
    wait_for,
)

from assistant.session import Session
from web.gate import AccessTokens
from web.gate.connections import (
    FD_RESERVE,
    FDS_PER_CONNECTION,
    ConnectionLimits,
    connection_budget,
)

#: Generous: the front closes within its own timeouts (1-3 s here); this only bounds a
#: failure on a busy machine.
DEADLINE_S = 30.0


def _closed(sock: socket.socket, deadline: float) -> bool:
    """Block until the peer closes `sock` (EOF or reset); False if it is still open."""
    sock.settimeout(deadline)
    try:
        while sock.recv(4096):
            pass
        return True
    except (ConnectionResetError, BrokenPipeError):
        return True
    except TimeoutError:
        return False


def test_a_connection_that_never_finishes_its_request_head_is_closed(gated):
    app = gated(Session(), limits=ConnectionLimits(head_timeout_s=1.0))
    door = app.access.front.doorman
    port = app.access.front.port
    silent = socket.create_connection(("127.0.0.1", port))
    partial = socket.create_connection(("127.0.0.1", port))
    partial.sendall(b"GET / HTTP/1.1\r\nHost: x\r\nX-Slow: ")  # and then nothing more
    try:
        assert _closed(silent, DEADLINE_S) and _closed(partial, DEADLINE_S)
    finally:
        silent.close()
        partial.close()
    assert door.head_timeouts == 2
    assert run(wait_for(lambda: door.open == 0))


def test_one_address_holds_its_share_and_others_still_get_in(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens, limits=ConnectionLimits(per_address=4))
    door = app.access.front.doorman
    port = app.access.front.port
    flood = []
    try:
        for _ in range(12):
            s = socket.socket()
            s.bind(("127.0.0.2", 0))
            s.connect(("127.0.0.1", port))
            flood.append(s)
        assert run(wait_for(lambda: door.refused == 8 and door.held_by("127.0.0.2") == 4))
        assert sum(_closed(s, 2.0) for s in flood[4:]) == 8  # refused at once (a reset)

        async def operator() -> int:
            url = local_url(app)
            async with client(source="127.0.0.3") as c:
                assert (await sign_in(c, url, tokens.operator)).status == 303
                async with c.get(url + "/") as r:
                    return r.status

        assert run(operator()) == 200
    finally:
        for s in flood:
            s.close()
    assert run(wait_for(lambda: door.open == 0))


def test_a_stalled_request_is_closed_as_idle_but_a_live_websocket_stays(gated):
    tokens = AccessTokens.new()
    # Pings every 4 s (aiohttp closes a socket whose pong is 2 s late: room for a busy
    # machine); 5 s of silence closes anything else.
    limits = ConnectionLimits(idle_timeout_s=5.0, ws_heartbeat_s=4.0, keepalive_timeout_s=60)
    app = gated(Session(), tokens=tokens, limits=limits)
    door = app.access.front.doorman
    url = local_url(app)

    async def go() -> None:
        async with client() as c:
            await sign_in(c, url, tokens.operator)
            cookie = next(m.value for m in c.cookie_jar if m.key == "cellteach_access")
            async with c.ws_connect(url, protocols=[VISER_PROTOCOL]) as ws:
                # The page reads its stream all along (and so answers the pings, as a
                # browser does).
                got: list[aiohttp.WSMsgType] = []
                reader = asyncio.ensure_future(_drain(ws, got))
                await ws.send_bytes(encode(CAMERA))
                # A request that starts, completes its head, then never sends its body.
                r, w = await asyncio.open_connection("127.0.0.1", app.access.front.port)
                w.write(b"GET / HTTP/1.1\r\nHost: x\r\nCookie: cellteach_access=" +
                        cookie.encode() + b"\r\n\r\nGET / HTTP/1.1\r\nHost:")
                await w.drain()
                await asyncio.wait_for(r.read(), DEADLINE_S)  # until the front closes it
                assert door.idle_closed >= 1
                # The page sends nothing for longer than the idle time.
                await asyncio.sleep(1.5 * limits.idle_timeout_s)
                assert not ws.closed and not reader.done()
                n = len(got)
                app.server.gui.add_markdown("still here")  # reaches every live page
                assert await wait_for(lambda: len(got) > n, DEADLINE_S)
                reader.cancel()
                w.close()

    run(go())


async def _drain(ws: aiohttp.ClientWebSocketResponse, got: list) -> None:
    async for msg in ws:
        got.append(msg.type)


def test_the_connection_budget_stays_below_the_open_files_limit():
    limits = ConnectionLimits(total=512)
    assert connection_budget(limits, 1024) == (1024 - FD_RESERVE) // FDS_PER_CONNECTION
    assert connection_budget(limits, 1024) * FDS_PER_CONNECTION + FD_RESERVE <= 1024
    assert connection_budget(limits, 1_000_000) == 512
    assert connection_budget(limits, 0) == 512  # no limit known
