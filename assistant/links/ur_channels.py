"""The UR link's text and package channels: the primary / secondary client interface
(URScript out; robot messages, robot mode and the calibrated kinematics in, `ur_primary`)
and the dashboard server (one command, one reply line).

Both have deadlines on every read; a dead peer is `LinkLost`, an answer outside the protocol
a `ProtocolError` quoting it. Both write what they send and hear to the link's wire log.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from dataclasses import dataclass

from assistant.links import ur_primary as up
from assistant.links.errors import ProtocolError
from assistant.links.link import LinkError, LinkLost
from assistant.links.wirelog import NULL, WireLog


@dataclass(frozen=True)
class Heard:
    """A robot message and when it arrived (monotonic)."""

    t: float
    message: up.RobotMessage


class ScriptChannel:
    """A primary (30001) or secondary (30002) interface connection: sends URScript, keeps the
    robot messages, robot mode and kinematics info the controller sends back."""

    def __init__(self, host: str, port: int, connect_timeout_s: float,
                 wire: WireLog = NULL, name: str = "primary"):
        self.host, self.port = host, int(port)
        self.connect_timeout_s = connect_timeout_s
        self.wire, self.name = wire, name
        self.kinematics: up.KinematicsInfo | None = None
        self.robot_mode: up.RobotModeData | None = None
        self._sock: socket.socket | None = None
        self._send_lock = threading.Lock()
        self._cond = threading.Condition()
        self.heard: list[Heard] = []
        self.failure: LinkError | None = None
        self._thread: threading.Thread | None = None
        self._closing = False

    def connect(self) -> None:
        self.close()
        self._closing, self.failure = False, None
        try:
            self._sock = socket.create_connection((self.host, self.port), self.connect_timeout_s)
        except OSError as exc:
            raise LinkLost(f"cannot reach the UR {self.name} interface at {self.host}:"
                           f"{self.port}: {exc}") from None
        self._sock.settimeout(0.2)
        self.wire.note(f"{self.name}:{self.port}", "connected")
        self._thread = threading.Thread(target=self._read, daemon=True, name=f"ur-{self.name}")
        self._thread.start()

    def send(self, text: str) -> float:
        """Send a script; returns the send time. LinkLost if the socket is gone."""
        with self._send_lock:
            if self._sock is None or self.failure is not None:
                raise self.failure or LinkLost(f"UR {self.name} interface is not connected")
            try:
                t = time.monotonic()
                self.wire.sent(f"{self.name}:{self.port}", text)
                self._sock.sendall(text.encode("utf-8"))
                return t
            except OSError as exc:
                raise LinkLost(f"UR {self.name} interface {self.host}:{self.port}: {exc}") \
                    from None

    def messages_since(self, t: float) -> list[up.RobotMessage]:
        with self._cond:
            return [h.message for h in self.heard if h.t >= t]

    def wait_kinematics(self, timeout_s: float) -> up.KinematicsInfo | None:
        """The kinematics info of the first robot state package (10 Hz), or None."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self.kinematics is None and self.failure is None:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cond.wait(min(left, 0.05))
            return self.kinematics

    def _read(self) -> None:
        sock, reader = self._sock, up.PrimaryReader()
        assert sock is not None
        why: LinkError | None = None
        while not self._closing:
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as exc:
                why = LinkLost(f"UR {self.name} interface: {exc}")
                break
            if not data:
                why = LinkLost(f"the UR closed the {self.name} interface connection (an "
                               "e-Series in Local control does that)")
                break
            try:
                items = list(reader.feed(data))
            except ProtocolError as exc:
                self.wire.received(f"{self.name}:{self.port}", exc.raw)
                why = exc
                break
            now = time.monotonic()
            msgs = [m for m in items if isinstance(m, up.RobotMessage)]
            for m in msgs:
                self.wire.received(f"{self.name}:{self.port}", f"message {m.kind}: "
                                   f"{m.describe()}")
            with self._cond:
                for m in items:
                    if isinstance(m, up.KinematicsInfo):
                        self.kinematics = m
                    elif isinstance(m, up.RobotModeData):
                        self.robot_mode = m
                self.heard += [Heard(now, m) for m in msgs]
                del self.heard[:-100]
                self._cond.notify_all()
        with self._cond:
            if not self._closing:
                self.failure = why
                self.wire.note(f"{self.name}:{self.port}", f"lost: {why}")
            self._cond.notify_all()
        with contextlib.suppress(OSError):
            sock.close()

    def close(self) -> None:
        self._closing = True
        if self._sock is not None:
            with contextlib.suppress(OSError):
                self._sock.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                self._sock.close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._sock, self._thread = None, None


def dashboard(host: str, port: int, command: str, timeout_s: float,
              wire: WireLog = NULL) -> str:
    """One dashboard command on its own connection; returns the reply line."""
    try:
        with socket.create_connection((host, port), timeout_s) as s:
            s.settimeout(timeout_s)
            buf = b""
            lines: list[str] = []
            sent = False
            while len(lines) < 2:
                chunk = s.recv(4096)
                if not chunk:
                    raise LinkLost(f"the UR dashboard server closed the connection during "
                                   f"{command!r}")
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    lines.append(line.decode("utf-8", errors="replace").strip())
                if lines and not sent:
                    if not lines[0].startswith("Connected: Universal Robots Dashboard Server"):
                        raise ProtocolError(f"not a UR dashboard server: {lines[0][:120]!r}",
                                            raw=lines[0])
                    wire.sent(f"dashboard:{port}", command)
                    s.sendall(command.encode() + b"\n")
                    sent = True
            wire.received(f"dashboard:{port}", lines[1])
            return lines[1]
    except TimeoutError:
        raise LinkLost(f"the UR dashboard server did not answer {command!r} within "
                       f"{timeout_s:.2f} s") from None
    except OSError as exc:
        raise LinkLost(f"UR dashboard server {host}:{port}: {exc}") from None
