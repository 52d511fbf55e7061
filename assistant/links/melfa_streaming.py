"""Joint streaming for `MelfaLink`: the data-link program, the paced target stream and its
acknowledgements, the DSTATE poll that runs beside it, and how a stream ends.

The PC runs the thesis' CONTROLLINK loop (003 Listing 4) on the controller, opens the data
link (``COM2:``) and sends one ``seq,(j1,...,j6)`` target per controller cycle, at most
`stream_window` of them unacknowledged; each acknowledgement carries the current joints.
`StatusPoller` polls DSTATE on the command port in its own thread, so a slow reply never delays
a target. This lives apart from the command-port session in `assistant.links.melfa`, which
mixes `MelfaStreaming` into `MelfaLink`.
"""

from __future__ import annotations

import contextlib
import math
import select
import socket
import threading
import time
from typing import TYPE_CHECKING

import numpy as np

from assistant.links import melfa_protocol as mp
from assistant.links.errors import ProtocolError
from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost
from assistant.links.timing import time_parametrize, validate_path
from assistant.robots.model import Robot

if TYPE_CHECKING:
    from assistant.links.melfa import MelfaLink

Array = np.ndarray


class StatusPoller:
    """Polls DSTATE on the command port while the stream runs, in its own thread, so a slow
    command channel never delays a streamed target. The stream loop reads `error_code` and
    `failure` (a LinkError the poll ran into)."""

    def __init__(self, link: MelfaLink, period_s: float):
        self._link = link
        self._period = period_s
        self._done = threading.Event()
        self.error_code = 0
        self.failure: LinkError | None = None
        self._thread = threading.Thread(target=self._run, name="melfa-status", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._done.wait(self._period):
            try:
                code = self._link.read_state().error_code
            except LinkError as exc:
                self.failure = exc
                return
            if code:
                self.error_code = code
                return

    def close(self) -> None:
        self._done.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=self._link.timeout_s + 1.0)


class MelfaStreaming:
    """Mixin of `MelfaLink`: `move_path` streams joint targets over the data link.

    The host supplies the command port (`command`, `read_state`, `set_override`, `_lost`,
    `_read_joints`, `_error_message`, `_controller_stopped`, `_lost_event`), the programs
    (`program_names`, `_store_program`), `_emit`, `_stopped_as` and the attributes below.
    """

    robot: Robot
    host: str
    datalink_port: int
    connect_timeout_s: float
    timeout_s: float
    stream_cycle_s: float
    stream_window: int
    status_period_s: float
    event_period_s: float
    reached_tol_rad: float
    _names: list[str]
    _dl: socket.socket | None
    _dl_buf: bytes
    _connected: bool
    _stream_ready: bool
    _stop: threading.Event
    _moving: threading.Lock
    _pressed: str | None
    _last_q: Array
    _progress_index: int
    last_stream_send_times: list[float]
    last_stream_ack_times: list[float]

    def move_path(self, joint_path: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        path = validate_path(self.robot, joint_path)
        if not self._connected:
            raise LinkError("MELFA link is not connected; call connect() first")
        timed_check = time_parametrize(path[:1], self.robot.limits.velocity, speed_scale)
        del timed_check  # validates speed_scale before anything is sent
        self._stop.clear()
        self._pressed = None
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        try:
            return self._stream(path, speed_scale)
        except LinkLost as exc:
            return self._lost_event(str(exc), self._progress_index)
        finally:
            self._moving.release()

    def _ensure_stream(self) -> None:
        if self._stream_ready and self._dl is not None:
            return
        self._stop_stream()
        st = self.read_state()
        if st.error_code:
            self.command("RSTALRM")
        if mp.STREAM_PROGRAM_NAME not in self.program_names():
            self._store_program(mp.STREAM_PROGRAM_NAME, mp.streaming_program().splitlines())
        self.command("SLOTINIT")
        self.command(f"RUN{mp.STREAM_PROGRAM_NAME};1")
        try:
            dl = socket.create_connection((self.host, self.datalink_port),
                                          self.connect_timeout_s)
        except OSError as exc:
            raise self._lost(f"cannot open the data link {self.host}:{self.datalink_port}: "
                             f"{exc}") from None
        dl.settimeout(self.timeout_s)
        self._dl, self._dl_buf = dl, b""
        self._stream_ready = True

    def _stop_stream(self) -> None:
        """Stop the streaming program (if any), then close the data link.

        In this order: a data link closed under a running INPUT is a controller alarm.
        """
        try:
            if self._stream_ready:
                self.command("STOP")
        finally:
            if self._dl is not None:
                with contextlib.suppress(OSError):
                    self._dl.close()
            self._dl, self._dl_buf = None, b""
            self._stream_ready = False

    def _stream(self, path: Array, speed_scale: float) -> LinkEvent:
        self._last_q = self._read_joints()
        lead = 0 if np.allclose(path[0], self._last_q, atol=1e-6) else 1
        full = path if lead == 0 else np.vstack([self._last_q[None], path])
        timed = time_parametrize(full, self.robot.limits.velocity, speed_scale)
        targets, seg = timed.resample(self.stream_cycle_s)
        index = np.maximum(seg - lead, 0)
        if timed.duration <= 0.0:
            ev = LinkEvent(LinkEventKind.REACHED, self._last_q.copy(), time.monotonic(),
                           "already there", len(path) - 1)
            self._emit(ev)
            return ev
        self._ensure_stream()
        self.set_override(math.ceil(speed_scale * 100))
        dl = self._dl
        assert dl is not None
        t0 = time.monotonic()
        self._progress_index = 0
        self.last_stream_send_times = []
        self.last_stream_ack_times = []
        poller = StatusPoller(self, self.status_period_s)
        try:
            return self._stream_loop(dl, targets, index, path, poller, t0)
        finally:
            poller.close()

    def _data_link_failed(self, poller: StatusPoller, exc: Exception) -> LinkLost:
        """The data link failed under the stream: when the status poll lost the link first
        (it closes both sockets, so the stream's next read fails on a closed one), its
        reason is the operator's ("no reply to 'STATE' within 0.30 s"), not the closed
        socket's."""
        poller.close()  # the poll thread ends right after it records its failure
        if isinstance(poller.failure, LinkLost):
            return poller.failure
        return self._lost(f"data link failed: {exc}")

    def _stream_loop(self, dl: socket.socket, targets: Array, index: Array, path: Array,
                     poller: StatusPoller, t0: float) -> LinkEvent:
        n = len(targets)
        sent, acked = 0, -1
        cycle, window = self.stream_cycle_s, self.stream_window
        waiting_since: float | None = None
        last_event = 0.0
        while True:
            now = time.monotonic()
            if self._stop.is_set():
                kind, text, details = self._stopped_as()
                return self._halt(kind, text, targets, index, acked, details)
            while sent < n and sent - acked - 1 < window and now >= t0 + sent * cycle:
                try:
                    dl.sendall(mp.format_stream_line(sent, targets[sent], self._names))
                except OSError as exc:
                    raise self._lost(f"data link send failed: {exc}") from None
                self.last_stream_send_times.append(time.monotonic())
                if waiting_since is None:
                    waiting_since = now
                sent += 1
            if acked == n - 1:
                break
            if poller.failure is not None:
                if isinstance(poller.failure, LinkLost):
                    raise poller.failure
                return self._halt(LinkEventKind.ERROR, str(poller.failure), targets, index,
                                  acked)
            if poller.error_code:
                return self._on_error(poller.error_code, targets, index, acked)
            if waiting_since is not None and now - waiting_since > self.timeout_s:
                raise self._lost(f"no acknowledgement of streamed target {acked + 1} within "
                                 f"{self.timeout_s:.2f} s")
            wake = min(t0 + sent * cycle if sent < n else math.inf,
                       (waiting_since or math.inf) + self.timeout_s)
            wait = float(np.clip(wake - time.monotonic(), 0.0, cycle))
            try:
                ready, _, _ = select.select([dl], [], [], wait)
            except (OSError, ValueError) as exc:
                raise self._data_link_failed(poller, exc) from None
            if not ready:
                continue
            try:
                chunk = dl.recv(4096)
            except TimeoutError:
                continue
            except OSError as exc:
                raise self._data_link_failed(poller, exc) from None
            if not chunk:
                raise self._lost("controller closed the data link")
            self._dl_buf += chunk
            while b"\r" in self._dl_buf:
                raw, _, self._dl_buf = self._dl_buf.partition(b"\r")
                text = raw.decode("ascii", errors="replace")
                if not text.strip():
                    continue
                try:
                    seq, q = mp.parse_feedback_line(text, self._names)
                except ProtocolError as exc:
                    return self._halt(LinkEventKind.ERROR, str(exc), targets, index, acked)
                if seq != acked + 1:
                    return self._halt(LinkEventKind.ERROR,
                                      f"data link acknowledged target {seq}, expected "
                                      f"{acked + 1}: {text!r}", targets, index, acked)
                acked = seq
                self.last_stream_ack_times.append(time.monotonic())
                self._last_q = q
                self._progress_index = int(index[self._nearest(targets, acked, q)])
                now = time.monotonic()
                waiting_since = now if sent > acked + 1 else None
                if now - last_event >= self.event_period_s:
                    last_event = now
                    self._emit(LinkEvent(LinkEventKind.MOVED, q.copy(), now, "",
                                         self._progress_index))
        return self._finish_stream(targets, index, path)

    @staticmethod
    def _nearest(targets: Array, upto: int, q: Array) -> int:
        lo = max(0, upto - 16)
        d = np.linalg.norm(targets[lo:upto + 1] - q[None], axis=1)
        return lo + int(np.argmin(d))

    def _finish_stream(self, targets: Array, index: Array, path: Array) -> LinkEvent:
        """All targets accepted: wait (polling) until the arm is at the last one."""
        goal = targets[-1]
        deadline = time.monotonic() + self.timeout_s + 16 * self.stream_cycle_s
        while True:
            try:
                q = self._read_joints()
                st = self.read_state()
            except ProtocolError as exc:
                return self._halt(LinkEventKind.ERROR, str(exc), targets, index,
                                  len(targets) - 1)
            self._last_q = q
            if st.error_code:
                return self._on_error(st.error_code, targets, index, len(targets) - 1)
            if np.max(np.abs(q - goal)) <= self.reached_tol_rad:
                ev = LinkEvent(LinkEventKind.REACHED, q.copy(), time.monotonic(), "reached",
                               len(path) - 1)
                self._emit(ev)
                return ev
            if time.monotonic() > deadline:
                return self._halt(LinkEventKind.ERROR, "the arm did not reach the last target "
                                  f"(off by {np.degrees(np.max(np.abs(q - goal))):.2f} deg)",
                                  targets, index, len(targets) - 1)
            time.sleep(max(self.stream_cycle_s, 0.005))

    def _halt(self, kind: LinkEventKind, message: str, targets: Array, index: Array,
              acked: int, details: dict | None = None) -> LinkEvent:
        """Stop the program and the arm, read where it is, report `kind`."""
        with contextlib.suppress(LinkError):
            self._stop_stream()
        q = self._last_q
        with contextlib.suppress(LinkError):
            q = self._read_joints()
        self._last_q = q
        i = int(index[self._nearest(targets, max(acked, 0), q)]) if len(targets) else 0
        ev = LinkEvent(kind, q.copy(), time.monotonic(), message, i, details or {})
        self._emit(ev)
        return ev

    def _on_error(self, code: int, targets: Array, index: Array, acked: int) -> LinkEvent:
        msg = self._error_message(code)
        ev = self._controller_stopped(code, f"DSTATE error {code:04d}", 0, message=msg,
                                      emit=False)
        i = int(index[self._nearest(targets, max(acked, 0), ev.q)]) if len(targets) else 0
        ev = LinkEvent(ev.kind, ev.q, ev.time_s, ev.message, i, ev.details)
        self._emit(ev)
        return ev
