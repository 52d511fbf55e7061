"""An RWS subscription to the RAPID execution state: the controller pushes a change instead
of the link asking 100 times a second.

``POST /subscription`` with the resource ``/rw/rapid/execution;ctrlexecstate`` (priority 1)
answers 201 with the websocket's address (``Location`` header, and a ``rel="self"`` link in
the body); the link opens it (`websocket`) with its session cookie and reads events such as
``<li class="rap-ctrlexecstate-ev">...<span class="ctrlexecstate">stopped</span>``
(RWS manual, "Subscription service"). Each change is numbered, so a waiter can ask for "a
stop after the start I sent" and never mistake an old event for a new one. RWS says events
may lag by hundreds of milliseconds; the link still reads the state directly now and then.
"""

from __future__ import annotations

import contextlib
import re
import ssl
import threading
import time

from assistant.links import websocket as ws
from assistant.links.wirelog import NULL, WireLog

_EXEC = re.compile(r'class="ctrlexecstate">\s*([a-z]+)\s*<')
_WS_URL = re.compile(r'(wss?://[^"\s<>]+/poll/[^"\s<>]+)')
EXEC_RESOURCE = "/rw/rapid/execution;ctrlexecstate"


def subscription_form() -> dict[str, str]:
    return {"resources": "1", "1": EXEC_RESOURCE, "1-p": "1"}


def websocket_url(location: str | None, body: str) -> str | None:
    if location and location.startswith(("ws://", "wss://")):
        return location
    m = _WS_URL.search(body)
    return m.group(1) if m else None


def parse_exec_events(text: str) -> list[str]:
    return _EXEC.findall(text)


class ExecutionSubscription:
    """Reads execution-state events from an open websocket on a thread."""

    def __init__(self, url: str, *, subprotocol: str, headers: dict[str, str],
                 timeout_s: float, tls: ssl.SSLContext | None = None, wire: WireLog = NULL):
        self.wire = wire
        self._sock = ws.connect(url, subprotocol=subprotocol, headers=headers,
                                timeout_s=timeout_s, tls=tls)
        self._sock.settimeout(0.5)
        self._cond = threading.Condition()
        self.seq = 0
        self.state: str | None = None
        self.alive = True
        self._closing = False
        self._thread = threading.Thread(target=self._read, name="abb-rws-subscription",
                                        daemon=True)
        self._thread.start()
        wire.note("subscription", f"open {url}")

    def _read(self) -> None:
        while not self._closing:
            try:
                op, data = ws.read_frame(self._sock)
            except TimeoutError:
                continue
            except OSError:
                break
            if op == ws.OP_CLOSE:
                break
            if op == ws.OP_PING:
                with contextlib.suppress(OSError):
                    self._sock.sendall(ws.frame(data, ws.OP_PONG, mask=True))
                continue
            text = data.decode("utf-8", errors="replace")
            states = parse_exec_events(text)
            if states:
                self.wire.received("subscription", f"ctrlexecstate {states[-1]}")
                with self._cond:
                    for st in states:
                        self.seq += 1
                        self.state = st
                    self._cond.notify_all()
        with self._cond:
            self.alive = False
            self._cond.notify_all()

    def mark(self) -> int:
        with self._cond:
            return self.seq

    def wait_change(self, after: int, timeout_s: float) -> tuple[int, str | None]:
        """(seq, state) of the newest event after `after`, or (after, None) at the timeout."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self.seq <= after and self.alive:
                left = deadline - time.monotonic()
                if left <= 0:
                    return after, None
                self._cond.wait(left)
            return (self.seq, self.state) if self.seq > after else (after, None)

    def close(self) -> None:
        self._closing = True
        with contextlib.suppress(OSError):
            self._sock.sendall(ws.frame(b"", ws.OP_CLOSE, mask=True))
        with contextlib.suppress(OSError):
            self._sock.close()
        self._thread.join(timeout=2.0)
