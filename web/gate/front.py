"""The authenticating front: aiohttp on the exposed address, viser behind it on loopback.

aiohttp is the one well-kept package with an HTTP server, an HTTP client and websockets on
both sides, all on asyncio (what viser's own server runs on): the front needs exactly those
four and nothing else. It runs its own event loop on a daemon thread.

Connections are admitted by `connections.Doorman` (per-address and total caps, head, handshake
and idle timeouts, the open-files limit raised). Every request then: a blocked address gets
429; a body announced larger than `max_body_bytes` gets 413 unread; without a valid cookie
nothing is served - a page request gets the sign-in form (`login.py`, 401), the websocket
handshake 401; the form POSTs the access code, the answer sets an HttpOnly cookie and sends
the browser back to a path on this site (303). An access code in the address is never taken
(the browser would keep it in its history). Anything but GET/HEAD (and the form's POST) 405.
The access log is off: nothing a browser sends may reach a log.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import secrets
import socket
import threading
from dataclasses import dataclass
from urllib.parse import urlsplit

import aiohttp
from aiohttp import web

from web.gate.banner import with_banner
from web.gate.config import GateConfig, shown_host
from web.gate.connections import (
    Doorman,
    connection_budget,
    listen,
    raise_open_files_limit,
)
from web.gate.limits import UploadSlots
from web.gate.login import CODE_IN_ADDRESS, LOGIN_PATH, WRONG_CODE, login_page, safe_path
from web.gate.messages import CloseConnection, MessageGuard
from web.gate.tokens import Role

log = logging.getLogger(__name__)

COOKIE = "cellteach_access"
CONN_HEADER = "X-Cellteach-Conn"
#: How many following ports are tried when the one asked for is taken (as viser does).
PORT_TRIES = 20
#: The sign-in form's body (a code and a path back): anything larger is not the form.
MAX_LOGIN_BYTES = 4096
#: Upstream connections for page requests (assets, index.html); websockets have their own.
PAGE_POOL = 16
NO_STORE = {"Cache-Control": "no-store", "Referrer-Policy": "no-referrer",
            "X-Content-Type-Options": "nosniff", "X-Frame-Options": "DENY"}


@dataclass(frozen=True)
class Peer:
    """One browser connection as the front admitted it."""

    role: Role
    address: str


class Front:
    """Start with `start()`; `peer(conn_id)` tells the app who is behind an upstream socket."""

    def __init__(self, cfg: GateConfig, upstream_port: int):
        self.cfg = cfg
        self.upstream = f"http://127.0.0.1:{upstream_port}"
        self.port = 0
        self.dropped = 0  # messages a role was not allowed to send (tests, diagnostics)
        self._peers: dict[str, Peer] = {}
        self._slots = UploadSlots(cfg.uploads_total)
        self._ssl = cfg.ssl_context()  # a bad certificate fails here, before anything runs
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._runner: web.AppRunner | None = None
        self._client: aiohttp.ClientSession | None = None
        self._ws_client: aiohttp.ClientSession | None = None
        self._sockets: set[web.WebSocketResponse] = set()
        self._listener: socket.socket | None = None
        self.doorman: Doorman | None = None

    # ------------------------------------------------------------------ lifetime
    def start(self) -> None:
        """Listen (blocking until bound); an OSError says why not."""
        ready = threading.Event()
        failure: list[BaseException] = []

        def main() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            try:
                loop.run_until_complete(self._listen())
            except BaseException as exc:  # noqa: BLE001 - handed to the starting thread
                failure.append(exc)
                ready.set()
                loop.close()
                return
            ready.set()
            loop.run_forever()
            loop.run_until_complete(self._cleanup())
            loop.close()

        self._thread = threading.Thread(target=main, name="cellteach-front", daemon=True)
        self._thread.start()
        ready.wait()
        if failure:
            raise failure[0]

    async def _listen(self) -> None:
        limits = self.cfg.limits
        app = web.Application(client_max_size=self.cfg.max_body_bytes)
        app.router.add_route("*", "/{tail:.*}", self._handle)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False,
                                     keepalive_timeout=limits.keepalive_timeout_s)
        await self._runner.setup()
        self._client = aiohttp.ClientSession(
            auto_decompress=False, connector=aiohttp.TCPConnector(limit=PAGE_POOL))
        self._ws_client = aiohttp.ClientSession(connector=aiohttp.TCPConnector(limit=0))
        last: OSError | None = None
        for port in ([self.cfg.port] if self.cfg.port == 0 else
                     range(self.cfg.port, self.cfg.port + PORT_TRIES)):
            try:
                self._listener = listen(self.cfg.host, port)
            except OSError as exc:
                last = exc
                continue
            self.port = self._listener.getsockname()[1]
            open_files = raise_open_files_limit()
            total = connection_budget(limits, open_files)
            if total < limits.total:
                log.info("the open-files limit (%d) leaves room for %d connections at once",
                         open_files, total)
            server = self._runner.server
            assert server is not None
            self.doorman = Doorman(limits, server, self._ssl, total)
            self.doorman.start(self._listener)
            return
        await self._cleanup()
        raise OSError(f"cannot listen on {self.cfg.host}:{self.cfg.port}: {last}")

    async def _cleanup(self) -> None:
        if self.doorman is not None:
            await self.doorman.stop()
        if self._listener is not None:
            self._listener.close()
        for ws in list(self._sockets):
            with contextlib.suppress(Exception):
                await ws.close(code=aiohttp.WSCloseCode.GOING_AWAY, message=b"server stops")
        if self._runner is not None:
            await self._runner.cleanup()
        for client in (self._client, self._ws_client):
            if client is not None:
                await client.close()

    def stop(self) -> None:
        if self._loop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._loop.stop)
        if self._thread is not None:
            self._thread.join(10.0)

    # ------------------------------------------------------------------ addresses
    @property
    def scheme(self) -> str:
        return "https" if self.cfg.tls else "http"

    @property
    def url(self) -> str:
        return f"{self.scheme}://{shown_host(self.cfg.host)}:{self.port}"

    def code(self, role: Role) -> str:
        """The access code that opens the page in `role` (print it, never log it)."""
        return self.cfg.tokens.operator if role == Role.OPERATOR else self.cfg.tokens.viewer

    def peer(self, conn_id: str | None) -> Peer | None:
        return None if conn_id is None else self._peers.get(conn_id)

    # ------------------------------------------------------------------ requests
    async def _handle(self, request: web.Request) -> web.StreamResponse:
        addr = request.remote or "unknown"
        wait = self.cfg.limiter.retry_after(addr)
        if wait > 0:
            return web.Response(status=429, text="Too many wrong access codes from this "
                                "address: try again later.\n",
                                headers={"Retry-After": str(int(wait) + 1)})
        if (request.content_length or 0) > self.cfg.max_body_bytes:
            return web.Response(status=413, text="Request body too large.\n")
        if request.path == LOGIN_PATH and request.method == "POST":
            return await self._login(request, addr)
        cookie = request.cookies.get(COOKIE)
        role = self.cfg.tokens.role_of(cookie)
        if role is None:
            if cookie is not None and self.cfg.limiter.failed(addr):
                log.warning("blocked %s after repeated wrong access codes", addr)
            return self._sign_in(request)
        if request.method not in ("GET", "HEAD"):
            return web.Response(status=405, headers={"Allow": "GET, HEAD"})
        if request.headers.get("Upgrade", "").lower() == "websocket":
            return await self._websocket(request, role, addr)
        if request.path == LOGIN_PATH:  # signed in already: back to the page
            return _see_other(safe_path(request.query.get("next")))
        return await self._page(request, role)

    def _sign_in(self, request: web.Request, message: str = "", status: int = 401
                 ) -> web.Response:
        """The sign-in form, coming back to what was asked for (never the websocket)."""
        if request.headers.get("Upgrade", "").lower() == "websocket" or \
                request.method not in ("GET", "HEAD", "POST"):
            return web.Response(status=401, text="Sign in first.\n", headers=NO_STORE)
        back = request.raw_path
        if "token" in request.query:
            message = message or CODE_IN_ADDRESS
            back = str(request.rel_url.with_query(
                {k: v for k, v in request.query.items() if k != "token"}))
        page = login_page(back, message=message,
                          unencrypted=self.cfg.exposed and not self.cfg.tls)
        return web.Response(status=status, text=page, content_type="text/html",
                            headers=NO_STORE)

    async def _login(self, request: web.Request, addr: str) -> web.Response:
        """The form's POST: the right code sets the cookie and goes back, a wrong one counts
        towards the address's block. Only a form from this site may sign in (another site's
        page could otherwise swap an operator's cookie for a viewer's)."""
        for header in ("Origin", "Referer"):
            seen = request.headers.get(header)
            if seen is not None and seen != "null" and urlsplit(seen).netloc != request.host:
                return web.Response(status=403, text="Sign in from this site's own page.\n")
        if (request.content_length or 0) > MAX_LOGIN_BYTES:
            return web.Response(status=413, text="Request body too large.\n")
        try:
            form = await request.post()
        except (ValueError, aiohttp.web.HTTPException):
            return web.Response(status=400, text="Not the sign-in form.\n")
        code, back = form.get("code"), safe_path(str(form.get("next") or "/"))
        role = self.cfg.tokens.role_of(code if isinstance(code, str) else None)
        if role is None:
            if self.cfg.limiter.failed(addr):
                log.warning("blocked %s after repeated wrong access codes", addr)
            page = login_page(back, message=WRONG_CODE,
                              unencrypted=self.cfg.exposed and not self.cfg.tls)
            return web.Response(status=401, text=page, content_type="text/html",
                                headers=NO_STORE)
        resp = _see_other(back)
        resp.set_cookie(COOKIE, str(code), httponly=True, samesite="Lax",
                        secure=self.cfg.tls, path="/")
        return resp

    async def _page(self, request: web.Request, role: Role) -> web.StreamResponse:
        assert self._client is not None
        path = request.raw_path.split("?", 1)[0]
        try:
            async with self._client.get(self.upstream + path,
                                        headers={"Accept-Encoding": "identity"}) as up:
                body = await up.read()
                ctype = up.headers.get("Content-Type", "application/octet-stream")
                status = up.status
        except aiohttp.ClientError as exc:
            log.warning("the page server behind the front did not answer: %s", exc)
            return web.Response(status=502, text="The assistant is not answering.\n")
        if ctype.startswith("text/html") and status == 200:
            body = with_banner(body, role=role, unencrypted=self.cfg.exposed and not
                               self.cfg.tls)
        resp = web.Response(status=status, body=body, headers={"Content-Type": ctype,
                                                               **NO_STORE})
        if len(body) > 1024:
            resp.enable_compression()
        return resp

    # ------------------------------------------------------------------ websocket
    async def _websocket(self, request: web.Request, role: Role, addr: str
                         ) -> web.StreamResponse:
        assert self._ws_client is not None
        origin = request.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc != request.host:
            return web.Response(status=403, text="Cross-site websocket refused.\n")
        offered = [p.strip() for p in request.headers.get("Sec-WebSocket-Protocol", "")
                   .split(",") if p.strip().startswith("viser-v")]
        conn_id = secrets.token_urlsafe(18)
        self._peers[conn_id] = Peer(role, addr)
        guard = MessageGuard(role, self._slots, self.cfg.max_upload_bytes,
                             self.cfg.uploads_per_connection)
        try:
            try:
                up = await self._ws_client.ws_connect(
                    self.upstream, protocols=offered, headers={CONN_HEADER: conn_id},
                    max_msg_size=0, compress=0, autoping=False)
            except (aiohttp.ClientError, OSError) as exc:
                log.warning("the page server behind the front refused a websocket: %s", exc)
                return web.Response(status=502, text="The assistant is not answering.\n")
            down = web.WebSocketResponse(
                protocols=[up.protocol] if up.protocol else (),
                max_msg_size=self.cfg.max_ws_message_bytes, compress=False,
                heartbeat=self.cfg.limits.ws_heartbeat_s, autoping=False)
            try:
                await down.prepare(request)
                self._sockets.add(down)
                await self._pump(down, up, guard)
            finally:
                self._sockets.discard(down)
                await up.close()
                if not down.closed:
                    await down.close()
            return down
        finally:
            guard.close()
            self.dropped += guard.dropped
            self._peers.pop(conn_id, None)

    async def _pump(self, down: web.WebSocketResponse,
                    up: aiohttp.ClientWebSocketResponse, guard: MessageGuard) -> None:
        # Pings pass through both ways: the page server's heartbeat (`web.heartbeat`) is
        # answered by the browser, not by this front.
        async def upwards() -> None:
            async for msg in down:
                if msg.type == aiohttp.WSMsgType.PONG:
                    await up.pong(msg.data)
                    continue
                if msg.type == aiohttp.WSMsgType.PING:
                    await down.pong(msg.data)
                    continue
                if msg.type != aiohttp.WSMsgType.BINARY:
                    continue  # viser speaks binary only
                try:
                    if guard.admit(msg.data):
                        await up.send_bytes(msg.data)
                except CloseConnection as exc:
                    await down.close(code=aiohttp.WSCloseCode.POLICY_VIOLATION,
                                     message=str(exc).encode())
                    return

        async def downwards() -> None:
            async for msg in up:
                if msg.type == aiohttp.WSMsgType.PING:
                    await down.ping(msg.data)
                elif msg.type == aiohttp.WSMsgType.BINARY:
                    await down.send_bytes(msg.data)
                elif msg.type == aiohttp.WSMsgType.TEXT:
                    await down.send_str(msg.data)

        tasks = [asyncio.ensure_future(upwards()), asyncio.ensure_future(downwards())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for t in tasks:
                t.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)


def _see_other(path: str) -> web.Response:
    """303 to a same-site path (`login.safe_path` made it)."""
    assert path.startswith("/") and not path.startswith("//")
    return web.Response(status=303, headers={"Location": path, **NO_STORE})
