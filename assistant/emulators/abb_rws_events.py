"""The RWS emulator's subscriptions: ``POST /subscription`` and the websocket that follows.

A client posts the resources it wants (``resources=1&1=/rw/rapid/execution;ctrlexecstate&
1-p=1``; the execution state and the event log are offered); the answer is 201 with the
websocket's address in ``Location`` and in a ``rel="self"`` link of the body, the way
abb-robot-client reads it. ``GET /poll/<n>`` with ``Upgrade: websocket`` and the version's
subprotocol opens it; events go out as the XHTML fragments RWS sends
(``<li class="rap-ctrlexecstate-ev">`` ... ``<span class="ctrlexecstate">stopped</span>``).
"""

from __future__ import annotations

import contextlib
import itertools
import threading
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler
from urllib.parse import parse_qs

from assistant.links import websocket as ws

OFFERED = ("/rw/rapid/execution;ctrlexecstate", "/rw/elog/0")


@dataclass
class _Sub:
    resources: tuple[str, ...]
    sockets: list = field(default_factory=list)


def exec_event(state: str) -> str:
    return ('<?xml version="1.0" encoding="utf-8"?><html xmlns="http://www.w3.org/1999/xhtml">'
            '<head><title>event</title></head><body><div class="state"><ul>'
            '<li class="rap-ctrlexecstate-ev" title="ctrlexecstate">'
            '<a href="/rw/rapid/execution;ctrlexecstate" rel="self"/>'
            f'<span class="ctrlexecstate">{state}</span></li></ul></div></body></html>')


def elog_event(seqnum: int) -> str:
    return ('<?xml version="1.0" encoding="utf-8"?><html xmlns="http://www.w3.org/1999/xhtml">'
            '<body><div class="state"><ul><li class="elog-message-ev" title="message">'
            f'<a href="/rw/elog/0/{seqnum}" rel="self"/><span class="seqnum">{seqnum}</span>'
            '</li></ul></div></body></html>')


class SubscriptionHub:
    """Open subscriptions and their websockets; `publish` sends to every interested one."""

    def __init__(self, subprotocol: str):
        self.subprotocol = subprotocol
        self._subs: dict[int, _Sub] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self.closing = threading.Event()

    def create(self, body: str) -> int:
        """A subscription for the posted resources; ValueError names one we do not offer."""
        form = parse_qs(body)
        keys = form.get("resources", [])
        if not keys:
            raise ValueError("a subscription needs resources=1&1=<resource>&1-p=<priority>")
        res = []
        for k in keys:
            r = form.get(k.strip(), [""])[-1]
            if r not in OFFERED:
                raise ValueError(f"cannot subscribe to {r!r}; offered: {', '.join(OFFERED)}")
            res.append(r)
        n = next(self._ids)
        with self._lock:
            self._subs[n] = _Sub(tuple(res))
        return n

    def publish(self, resource: str, text: str) -> None:
        with self._lock:
            socks = [(s, lock) for sub in self._subs.values() if resource in sub.resources
                     for s, lock in sub.sockets]
        data = ws.frame(text.encode("utf-8"))
        for s, lock in socks:
            with lock, contextlib.suppress(OSError):
                s.sendall(data)

    def serve(self, h: BaseHTTPRequestHandler, n: int) -> None:
        """Upgrade the request to a websocket and hold it until the client closes it."""
        with self._lock:
            sub = self._subs.get(n)
        key = h.headers.get("Sec-WebSocket-Key")
        protocols = [p.strip() for p in h.headers.get("Sec-WebSocket-Protocol", "").split(",")]
        if sub is None or not key or self.subprotocol not in protocols:
            h.send_error(404 if sub is None else 400, "no such subscription or protocol")
            return
        h.send_response(101, "Switching Protocols")
        h.send_header("Upgrade", "websocket")
        h.send_header("Connection", "Upgrade")
        h.send_header("Sec-WebSocket-Accept", ws.accept_key(key))
        h.send_header("Sec-WebSocket-Protocol", self.subprotocol)
        h.end_headers()
        h.wfile.flush()
        sock, lock = h.connection, threading.Lock()
        with self._lock:
            sub.sockets.append((sock, lock))
        sock.settimeout(0.5)
        try:
            while not self.closing.is_set():
                try:
                    op, data = ws.read_frame(sock)
                except TimeoutError:
                    continue
                if op == ws.OP_CLOSE:
                    with lock, contextlib.suppress(OSError):
                        sock.sendall(ws.frame(b"", ws.OP_CLOSE))
                    break
                if op == ws.OP_PING:
                    with lock:
                        sock.sendall(ws.frame(data, ws.OP_PONG))
        except OSError:
            pass
        finally:
            with self._lock:
                sub.sockets.remove((sock, lock))
            h.close_connection = True
