"""Socket plumbing of the MELFA emulator: a line-buffered client connection (used by the
command port and the data links alike) and the Ethernet data-link ports (``COM2:`` ...) that
emulated programs open with ``OPEN "COM2:" AS #1``.

Kept apart from the controller logic in `melfa_emulator`, which owns one `DataLinkPort` per
configured COM number and serves its command port through `LineConnection`.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections import deque
from typing import TYPE_CHECKING

from assistant.emulators.melfa_program import ProgramError
from assistant.links import melfa_protocol as mp

if TYPE_CHECKING:
    from assistant.emulators.melfa_emulator import MelfaEmulator

POLL_S = 0.05  # seconds between checks of stop flags in blocking reads


class LineConnection:
    """A client socket with a line buffer; closed by the owner on drop."""

    def __init__(self, sock: socket.socket):
        self.sock = sock
        self.buf = b""
        self.closed = False

    def close(self) -> None:
        self.closed = True
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()

    def readline(self, stop: threading.Event) -> str | None:
        """Next CR/LF-terminated line, or None on EOF / stop."""
        while True:
            self.buf = self.buf.lstrip(b"\r\n")
            ends = [i for i in (self.buf.find(b"\r"), self.buf.find(b"\n")) if i >= 0]
            if ends:
                i = min(ends)
                line, self.buf = self.buf[:i], self.buf[i + 1:]
                return line.decode("ascii", errors="replace")
            if stop.is_set() or self.closed:
                return None
            try:
                chunk = self.sock.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return None
            if not chunk:
                return None
            self.buf += chunk


class DataLinkPort:
    """An Ethernet data-link port (one COMn:): a listener whose newest client is the channel."""

    def __init__(self, emulator: MelfaEmulator, com: int, host: str, port: int):
        self.emu = emulator
        self.com = com
        self._listener = socket.create_server((host, port))
        self._listener.settimeout(POLL_S)
        self.port = self._listener.getsockname()[1]
        self._conn: LineConnection | None = None
        self._cond = threading.Condition()
        self._closed = threading.Event()
        self._late: deque[tuple[float, LineConnection, bytes]] = deque()
        self._thread = threading.Thread(target=self._accept_loop, name=f"melfa-com{com}",
                                        daemon=True)
        self._thread.start()
        self._late_thread = threading.Thread(target=self._late_loop,
                                             name=f"melfa-com{com}-late", daemon=True)
        self._late_thread.start()

    def _accept_loop(self) -> None:
        while not self._closed.is_set():
            try:
                sock, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.settimeout(POLL_S)
            with self._cond:
                if self._conn is not None:
                    self._conn.close()
                self._conn = LineConnection(sock)
                self._cond.notify_all()

    def wait_connection(self, abort: threading.Event) -> LineConnection | None:
        with self._cond:
            while (self._conn is None or self._conn.closed) and not abort.is_set() \
                    and not self._closed.is_set():
                self._cond.wait(POLL_S)
            return self._conn if self._conn is not None and not self._conn.closed else None

    def readline(self, abort: threading.Event) -> str:
        conn = self.wait_connection(abort)
        if conn is None:
            return ""
        line = conn.readline(abort)
        if line is None:
            if abort.is_set():
                return ""
            raise ProgramError(mp.ERR_DATALINK_LOST, f"COM{self.com}: connection closed")
        self.emu.log_received(f"COM{self.com}", line)
        return line

    def write(self, text: str, abort: threading.Event) -> None:
        """Send a line; a reply delay (fault) holds it back without blocking the program,
        as a controller's output buffer would."""
        with self._cond:
            conn = self._conn
        if conn is None or conn.closed:
            raise ProgramError(mp.ERR_DATALINK_LOST, f"COM{self.com}: not connected")
        out, delay = self.emu.faults.take_reply(text)
        data = (out + mp.TERMINATOR).encode("ascii", errors="replace")
        if delay > 0:
            with self._cond:
                self._late.append((time.monotonic() + delay, conn, data))
                self._cond.notify_all()
            return
        try:
            conn.sock.sendall(data)
        except OSError:
            raise ProgramError(mp.ERR_DATALINK_LOST, f"COM{self.com}: send failed") from None

    def _late_loop(self) -> None:
        """Sends held-back lines when they are due (in order)."""
        while not self._closed.is_set():
            with self._cond:
                while not self._late and not self._closed.is_set():
                    self._cond.wait(POLL_S)
                if self._closed.is_set():
                    return
                due, conn, data = self._late[0]
                wait = due - time.monotonic()
                if wait > 0:
                    self._cond.wait(min(wait, POLL_S))
                    continue
                self._late.popleft()
            if not conn.closed:
                with contextlib.suppress(OSError):
                    conn.sock.sendall(data)

    def drop(self) -> None:
        """Close the channel's connection; unread data and held-back lines are discarded."""
        with self._cond:
            if self._conn is not None:
                self._conn.close()
            self._conn = None
            self._late.clear()

    def close(self) -> None:
        self._closed.set()
        self.drop()
        self._listener.close()
        with self._cond:
            self._cond.notify_all()
        self._thread.join(timeout=2.0)
        self._late_thread.join(timeout=2.0)
