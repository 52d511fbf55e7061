"""The UR emulator's RTDE port (30004): handshake, output recipes, the data stream.

One thread per client: it answers control packages (protocol version, controller version,
output setup, start, pause; input setup is answered ``NOT_FOUND``-free only for nothing -
this controller model takes no RTDE inputs, and says so) and, once started, sends one data
package per period of the recipe's frequency (at most 500 Hz on an e-Series, 125 Hz on a
CB3: software 3.x). Faults: a
reply delay stalls every package by that long; a garbled reply replaces one package's bytes.
"""

from __future__ import annotations

import contextlib
import select
import socket
import struct
import threading
import time
from collections.abc import Callable

from assistant.emulators.faults import Faults
from assistant.links import ur_rtde_wire as w
from assistant.links.errors import ProtocolError

MAX_HZ = 500.0


class RtdeServer:
    """Listens for RTDE clients; `snapshot()` gives the controller's values by name."""

    def __init__(self, snapshot: Callable[[], dict], faults: Faults, *, host: str = "127.0.0.1",
                 port: int = 0, version: tuple[int, int, int, int] = (5, 11, 1, 108318)):
        self.snapshot = snapshot
        self.faults = faults
        self.version = version
        self.max_hz = 125.0 if version[0] < 5 else MAX_HZ
        self._srv = socket.create_server((host, port))
        self._srv.settimeout(0.05)
        self._stop = threading.Event()
        self._clients: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._accept, name="ur-rtde-server", daemon=True)
        #: Control packages received (type letter), for tests.
        self.received: list[str] = []

    @property
    def port(self) -> int:
        return self._srv.getsockname()[1]

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self.drop_clients()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self._srv.close()

    def drop_clients(self) -> None:
        with self._lock:
            clients, self._clients = list(self._clients), set()
        for c in clients:
            with contextlib.suppress(OSError):
                c.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                c.close()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                sock, _ = self._srv.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self._clients.add(sock)
            threading.Thread(target=self._serve, args=(sock,), name="ur-rtde-client",
                             daemon=True).start()

    # ------------------------------------------------------------------ one client
    def _serve(self, sock: socket.socket) -> None:
        reader = w.PackageReader()
        recipe: tuple[list[str], struct.Struct, float] | None = None
        period, next_t, streaming = 0.002, 0.0, False
        try:
            while not self._stop.is_set():
                wait = max(0.0, next_t - time.monotonic()) if streaming else 0.05
                readable, _, _ = select.select([sock], [], [], wait)
                if readable:
                    data = sock.recv(65536)
                    if not data:
                        return
                    for cmd, body in reader.feed(data):
                        out, recipe_new, start = self._control(cmd, body, recipe)
                        recipe = recipe_new
                        if start is not None:
                            streaming = start and recipe is not None
                            next_t = time.monotonic()
                        if out:
                            sock.sendall(out)
                    if recipe is not None:
                        period = 1.0 / recipe[2]
                if streaming and recipe is not None and time.monotonic() >= next_t:
                    self._send_data(sock, recipe)
                    next_t += period
                    if time.monotonic() - next_t > 10 * period:  # fell far behind
                        next_t = time.monotonic() + period
        except (OSError, ValueError, ProtocolError):  # ValueError: closed by a drop
            return
        finally:
            with self._lock:
                self._clients.discard(sock)
            with contextlib.suppress(OSError):
                sock.close()

    def _control(self, cmd: int, body: bytes, recipe):  # noqa: ANN001, ANN202
        """Reply bytes, the (possibly new) recipe, and True/False to start/pause (or None)."""
        self.received.append(chr(cmd))
        if cmd == w.Cmd.REQUEST_PROTOCOL_VERSION:
            ok = len(body) == 2 and struct.unpack(">H", body)[0] in (1, 2)
            return w.pack(cmd, bytes([1 if ok else 0])), recipe, None
        if cmd == w.Cmd.GET_URCONTROL_VERSION:
            return w.pack(cmd, struct.pack(">IIII", *self.version)), recipe, None
        if cmd == w.Cmd.SETUP_OUTPUTS:
            if len(body) < 8:
                return w.text_message("output setup without frequency", level=2), recipe, None
            (hz,) = struct.unpack_from(">d", body)
            names = [n for n in body[8:].decode("ascii", errors="replace").split(",") if n]
            if not 0.0 < hz <= self.max_hz:
                return (w.text_message(f"Requested frequency {hz} Hz is outside "
                                       f"0-{self.max_hz:g}",
                                       level=2), recipe, None)
            types = [w.OUTPUTS.get(n, "NOT_FOUND") for n in names]
            reply = w.pack(cmd, bytes([1]) + ",".join(types).encode())
            if "NOT_FOUND" in types or not names:
                return reply, None, None
            return reply, (names, w.recipe_struct(types), hz), None
        if cmd == w.Cmd.SETUP_INPUTS:
            names = [n for n in body.decode("ascii", errors="replace").split(",") if n]
            return w.pack(cmd, bytes([0]) + ",".join("NOT_FOUND" for _ in names).encode()), \
                recipe, None
        if cmd == w.Cmd.START:
            return w.pack(cmd, bytes([1 if recipe is not None else 0])), recipe, \
                recipe is not None
        if cmd == w.Cmd.PAUSE:
            return w.pack(cmd, bytes([1])), recipe, False
        # A data package from the client: this controller has no input recipe.
        return w.text_message("no input recipe is set up", level=1), recipe, None

    def _send_data(self, sock: socket.socket, recipe) -> None:  # noqa: ANN001
        names, st, _ = recipe
        garbage, delay = self.faults.take_reply("")
        if delay > 0.0:
            time.sleep(delay)
        if garbage:
            sock.sendall(garbage.encode("utf-8", errors="replace"))
            return
        snap = self.snapshot()
        types = [w.OUTPUTS[n] for n in names]
        values = w.flatten_values([snap.get(n, _zero(w.OUTPUTS[n])) for n in names], types)
        sock.sendall(w.pack(w.Cmd.DATA_PACKAGE, bytes([1]) + st.pack(*values)))


def _zero(t: str) -> object:
    code = w.TYPE_CODES[t]
    if len(code) > 1:
        return [0] * int(code[:-1])
    return False if code == "?" else 0
