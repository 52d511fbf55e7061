"""Connection hygiene at the front: how many sockets an address may hold, and for how long.

The front accepts every TCP connection itself (`Doorman`), not through aiohttp's listener, so
a flood is cut at the door, before a TLS handshake or a request costs anything:

- at most `ConnectionLimits.per_address` connections from one address and `total` in all;
  one over is closed at once (RST), so the open-files limit is never reached and accept()
  never fails for the next person;
- the TLS handshake must end within `handshake_timeout_s` and the first request's head must
  arrive within `head_timeout_s` of the connection, else it is closed;
- a connection that neither sends nor has anything left to receive for `idle_timeout_s` is
  closed (a stalled half-sent request, a dead peer); idle keep-alive connections close after
  `keepalive_timeout_s` (aiohttp), and websockets are pinged every `ws_heartbeat_s` (a live
  browser answers, so a page left open is never idle);
- `raise_open_files_limit` lifts the soft open-files limit to the hard one where the OS
  allows, and `total` is kept below what that limit leaves (`connection_budget`).

So while one address floods, everyone else - the operator opening a page to press Stop - still
gets in, and an operator already connected keeps the websocket they have.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import socket
import ssl
import struct
from collections.abc import Callable
from dataclasses import dataclass

log = logging.getLogger(__name__)

#: File descriptors one admitted connection may cost this process: the browser's socket and
#: both ends of its upstream websocket to viser (which runs in this process).
FDS_PER_CONNECTION = 3
#: Descriptors kept for everything else: viser, the page pool, files, cameras, the robot link.
FD_RESERVE = 160
#: accept() failing for want of descriptors (another part of the process used them up): wait
#: this long and try again rather than spin.
STARVED_WAIT_S = 0.05
#: A request head longer than this without its end is not a browser's (aiohttp refuses it).
_HEAD_END = b"\r\n\r\n"


@dataclass(frozen=True)
class ConnectionLimits:
    """Bounds on the front's connections (see the module docstring)."""

    #: A browser opens at most 6 connections a host plus one websocket a tab: 32 leaves room
    #: for several tabs from one computer.
    per_address: int = 32
    total: int = 512
    handshake_timeout_s: float = 10.0
    head_timeout_s: float = 10.0
    idle_timeout_s: float = 60.0
    keepalive_timeout_s: float = 15.0
    ws_heartbeat_s: float = 20.0


def raise_open_files_limit() -> int:
    """Lift the soft open-files limit to the hard one (where the OS allows); the soft limit
    in force afterwards (0: none)."""
    try:
        import resource
    except ImportError:  # not a POSIX system
        return 0
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        return 0
    target = hard if hard != resource.RLIM_INFINITY else max(soft, 65536)
    if soft < target:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
            soft = target
        except (ValueError, OSError):
            log.info("the open-files limit stays at %d", soft)
    return soft


def connection_budget(limits: ConnectionLimits, open_files: int) -> int:
    """How many connections the front admits at once under an open-files limit."""
    if open_files <= 0:
        return limits.total
    fit = max(1, (open_files - FD_RESERVE) // FDS_PER_CONNECTION)
    return min(limits.total, fit)


class _Ticket:
    """One admitted connection's place, given back exactly once."""

    __slots__ = ("addr", "door", "given")

    def __init__(self, door: Doorman, addr: str):
        self.door, self.addr, self.given = door, addr, False

    def give_back(self) -> None:
        if not self.given:
            self.given = True
            self.door._give(self.addr)  # noqa: SLF001


class Guard(asyncio.Protocol):
    """Sits between the transport and aiohttp's protocol: times the request head and idle
    spells, gives the connection's place back when it closes."""

    def __init__(self, inner: asyncio.Protocol, ticket: _Ticket, limits: ConnectionLimits):
        self._inner = inner
        self._ticket = ticket
        self._limits = limits
        self._transport: asyncio.Transport | None = None
        self._head_timer: asyncio.TimerHandle | None = None
        self._idle_timer: asyncio.TimerHandle | None = None
        self._tail = b""
        self._heard = 0.0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._transport = transport  # type: ignore[assignment]
        loop = asyncio.get_running_loop()
        self._heard = loop.time()
        self._head_timer = loop.call_later(self._limits.head_timeout_s, self._head_late)
        self._idle_timer = loop.call_later(self._limits.idle_timeout_s, self._idle_check)
        self._inner.connection_made(transport)

    def data_received(self, data: bytes) -> None:
        self._heard = asyncio.get_running_loop().time()
        if self._head_timer is not None:
            seen = self._tail + data
            if _HEAD_END in seen:
                self._head_timer.cancel()
                self._head_timer = None
                self._tail = b""
            else:
                self._tail = seen[-3:]
        self._inner.data_received(data)

    def eof_received(self) -> bool | None:
        return self._inner.eof_received()

    def pause_writing(self) -> None:
        self._inner.pause_writing()

    def resume_writing(self) -> None:
        self._inner.resume_writing()

    def connection_lost(self, exc: Exception | None) -> None:
        for timer in (self._head_timer, self._idle_timer):
            if timer is not None:
                timer.cancel()
        self._ticket.give_back()
        self._inner.connection_lost(exc)

    # ------------------------------------------------------------------ timers
    def _head_late(self) -> None:
        self._head_timer = None
        self._ticket.door.head_timeouts += 1
        self._close()

    def _idle_check(self) -> None:
        t = self._transport
        if t is None or t.is_closing():
            return
        loop = asyncio.get_running_loop()
        quiet_until = self._heard + self._limits.idle_timeout_s
        if loop.time() < quiet_until or t.get_write_buffer_size() > 0:
            # heard from lately, or still sending to it: not idle
            self._idle_timer = loop.call_at(max(quiet_until, loop.time() + 1.0),
                                            self._idle_check)
            return
        self._ticket.door.idle_closed += 1
        self._close()

    def _close(self) -> None:
        if self._transport is not None and not self._transport.is_closing():
            self._transport.abort()


class Doorman:
    """The accept loop: admits a connection if its address and the total are under their
    bounds, and hands it (TLS first, if any) to aiohttp's protocol behind a `Guard`."""

    def __init__(self, limits: ConnectionLimits, protocol: Callable[[], asyncio.Protocol],
                 ssl_context: ssl.SSLContext | None, total: int):
        self.limits = limits
        self.total = total
        self._protocol = protocol
        self._ssl = ssl_context
        self._by_addr: dict[str, int] = {}
        self._open = 0
        self._tasks: set[asyncio.Task] = set()
        self._accepting: asyncio.Task | None = None
        # Counters for tests and diagnostics.
        self.refused = 0
        self.head_timeouts = 0
        self.idle_closed = 0
        self.handshake_failed = 0
        self.starved = 0

    @property
    def open(self) -> int:
        return self._open

    def held_by(self, addr: str) -> int:
        return self._by_addr.get(addr, 0)

    def start(self, listener: socket.socket) -> None:
        listener.setblocking(False)
        self._accepting = asyncio.get_running_loop().create_task(self._accept(listener))

    async def stop(self) -> None:
        if self._accepting is not None:
            self._accepting.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._accepting
        for t in list(self._tasks):
            t.cancel()

    # ------------------------------------------------------------------ accounting
    def _take(self, addr: str) -> bool:
        held = self._by_addr.get(addr, 0)
        if held >= self.limits.per_address or self._open >= self.total:
            return False
        self._by_addr[addr] = held + 1
        self._open += 1
        return True

    def _give(self, addr: str) -> None:
        self._open -= 1
        left = self._by_addr.get(addr, 1) - 1
        if left > 0:
            self._by_addr[addr] = left
        else:
            self._by_addr.pop(addr, None)

    # ------------------------------------------------------------------ the loop
    async def _accept(self, listener: socket.socket) -> None:
        loop = asyncio.get_running_loop()
        while True:
            try:
                conn, peer = await loop.sock_accept(listener)
            except OSError as exc:
                if exc.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    self.starved += 1
                    if self.starved == 1 or self.starved % 1000 == 0:
                        log.warning("the front cannot accept connections: %s", exc.strerror)
                    await asyncio.sleep(STARVED_WAIT_S)
                    continue
                if listener.fileno() < 0:
                    return
                log.debug("accept failed: %s", exc)
                continue
            addr = str(peer[0])
            if not self._take(addr):
                self.refused += 1
                _reset(conn)
                continue
            task = loop.create_task(self._open_connection(conn, _Ticket(self, addr)))
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)

    async def _open_connection(self, conn: socket.socket, ticket: _Ticket) -> None:
        loop = asyncio.get_running_loop()
        try:
            conn.setblocking(False)
            await loop.connect_accepted_socket(
                lambda: Guard(self._protocol(), ticket, self.limits), conn, ssl=self._ssl,
                ssl_handshake_timeout=self.limits.handshake_timeout_s if self._ssl else None)
        except (OSError, ssl.SSLError, asyncio.TimeoutError, ConnectionError) as exc:
            self.handshake_failed += 1
            log.debug("a connection ended before its first request: %s", exc)
            conn.close()
            ticket.give_back()
        except asyncio.CancelledError:
            conn.close()
            ticket.give_back()
            raise


def _reset(conn: socket.socket) -> None:
    """Close at once with a reset: no FIN handshake and no TIME_WAIT kept for a refused
    connection."""
    with contextlib.suppress(OSError):
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    conn.close()


def listen(host: str, port: int, backlog: int = 512) -> socket.socket:
    """A listening socket on host:port (the first address the name resolves to); OSError if
    it cannot bind."""
    infos = socket.getaddrinfo(host or None, port, type=socket.SOCK_STREAM,
                               flags=socket.AI_PASSIVE)
    family, kind, proto, _, addr = infos[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(addr)
        sock.listen(backlog)
    except OSError:
        sock.close()
        raise
    return sock
