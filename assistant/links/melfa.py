"""Drive a Mitsubishi MELFA CR-series controller (RV-2AJ on a CR1) over Ethernet.

Two channels, as in the thesis (003 §7.1): the *controller communication* port carries one
request/reply at a time (``1;1;JPOSF`` -> ``QoKJ1;...``) for set-up, status, single moves,
program upload and run; an Ethernet *data link* (``COM2:``) carries the joint stream.

Streaming follows the thesis' CONTROLLINK program (Listing 4) - ``INPUT #1`` / ``MOV`` with
``CNT 1`` blending in a loop - moved from RS-232 to the data-link port: the PC sends one
``seq,(j1,...,j6)`` target per controller cycle (7.1 ms), keeps at most `stream_window`
targets unacknowledged, and the controller answers each accepted target with its current
joints. A status poll (``DSTATE``) on the command port, in its own thread so a slow reply
never delays a target, catches errors (collision, range) while the arm moves; the thesis
needed that second connection too.

Real-world choice: the CR1's *Real-time external control* (MXT, UDP, one packet per 7.1 ms
cycle, 003 Table 4 "RTEC") is the lower-latency path for a production set-up; it needs a
C-level sender to hold the cycle (the thesis found Java too slow). This link uses the
data-link program because it works on every CR controller with no option board and
tolerates a late packet (CNT keeps the arm moving). `benchmarks/link_stream.py` measures the
pacing we achieve.

Everything is refused before it is sent if it is outside the joint limits or unreachable.
Every read has a timeout; a timeout or a dropped socket mid-move ends the move with
LINK_LOST, marks the link disconnected and leaves the robot "stopped at its last known
joints"; `connect()` again and re-plan from `current_joints()`.
"""

from __future__ import annotations

import contextlib
import math
import select
import socket
import threading
import time
from collections.abc import Callable

import numpy as np

from assistant.links import melfa_protocol as mp
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.links.melfa_protocol import DState, MelfaPose, Reply
from assistant.links.operator_button import OperatorButton
from assistant.links.timing import time_parametrize, validate_path
from assistant.robots.model import Robot

Array = np.ndarray


class _StatusPoller:
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


class MelfaLink(OperatorButton, RobotLink):
    """TCP client for a MELFA CR controller: commands, streaming, programs.

    Args:
        robot: the model of the connected arm (limits, speeds, kinematics).
        host, port: controller command port (controller communication mode, 10000-10009).
        datalink_port: TCP port of the data-link ``COM2:`` the streaming program opens.
        robot_number, slot: the first two fields of every request.
        connect_timeout_s: TCP connect timeout.
        timeout_s: longest wait for any reply (and for a streamed target's acknowledgement).
        stream_cycle_s: interval between streamed joint targets (the controller cycle).
        stream_window: streamed targets allowed in flight without acknowledgement.
        status_period_s: interval of the DSTATE error poll while streaming.
        event_period_s: MOVED events are emitted at most this often.
        reset_alarms_on_connect: clear a pending alarm in `connect()` (the operator asked to
            reconnect); otherwise `connect()` fails while the controller is in error.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        host: str = "127.0.0.1",
        port: int = 10001,
        datalink_port: int = 10002,
        robot_number: int = 1,
        slot: int = 1,
        connect_timeout_s: float = 2.0,
        timeout_s: float = 1.0,
        stream_cycle_s: float = 0.0071,
        stream_window: int = 4,
        status_period_s: float = 0.05,
        event_period_s: float = 0.05,
        client_name: str = "CELLTEACH",
        reset_alarms_on_connect: bool = True,
        reached_tol_rad: float = math.radians(0.05),
        collision_codes: frozenset[int] = mp.COLLISION_CODES,
    ):
        super().__init__()
        if stream_cycle_s <= 0 or stream_window < 1 or timeout_s <= 0:
            raise ValueError("stream_cycle_s, stream_window and timeout_s must be positive")
        self.robot = robot
        self.host, self.port, self.datalink_port = host, int(port), int(datalink_port)
        self.robot_number, self.slot = int(robot_number), int(slot)
        self.connect_timeout_s, self.timeout_s = float(connect_timeout_s), float(timeout_s)
        self.stream_cycle_s, self.stream_window = float(stream_cycle_s), int(stream_window)
        self.status_period_s, self.event_period_s = float(status_period_s), float(event_period_s)
        self.client_name = client_name
        self.reset_alarms_on_connect = reset_alarms_on_connect
        self.reached_tol_rad = float(reached_tol_rad)
        self.collision_codes = frozenset(collision_codes)
        self._names = list(robot.joint_names)
        self._cmd: socket.socket | None = None
        self._cmd_buf = b""
        self._cmd_lock = threading.RLock()
        self._dl: socket.socket | None = None
        self._dl_buf = b""
        self._connected = False
        self._stream_ready = False
        self._ovrd: int | None = None
        self._stop = threading.Event()
        self._moving = threading.Lock()
        self._direct_busy = threading.Event()
        self._last_q = np.zeros(robot.dof)
        self._progress_index = 0
        self.controller_info = ""
        #: Send / acknowledgement times (monotonic) of the last stream's targets (benchmarks).
        self.last_stream_send_times: list[float] = []
        self.last_stream_ack_times: list[float] = []

    # ------------------------------------------------------------------ low level
    def _lost(self, why: str) -> LinkLost:
        self._drop()
        return LinkLost(f"MELFA link to {self.host}:{self.port} lost: {why}")

    def _drop(self) -> None:
        """Forget both sockets; the robot is treated as stopped at its last known joints."""
        self._connected = False
        self._stream_ready = False
        for s in (self._cmd, self._dl):
            if s is not None:
                with contextlib.suppress(OSError):
                    s.close()
        self._cmd, self._dl = None, None
        self._cmd_buf, self._dl_buf = b"", b""

    def request(self, command: str, *, timeout_s: float | None = None) -> Reply:
        """Send one command, return the parsed reply (refusals included, not raised)."""
        with self._cmd_lock:
            if self._cmd is None:
                raise LinkError("MELFA link is not connected; call connect() first")
            sock = self._cmd
            try:
                sock.settimeout(self.timeout_s if timeout_s is None else timeout_s)
                sock.sendall(mp.format_request(self.robot_number, self.slot, command))
                while b"\r" not in self._cmd_buf:
                    chunk = sock.recv(4096)
                    if not chunk:
                        raise self._lost(f"controller closed the connection during {command!r}")
                    self._cmd_buf += chunk
            except TimeoutError:
                raise self._lost(f"no reply to {command!r} within "
                                 f"{self.timeout_s if timeout_s is None else timeout_s:.2f} s"
                                 ) from None
            except OSError as exc:
                raise self._lost(f"{exc} during {command!r}") from None
            raw, _, self._cmd_buf = self._cmd_buf.partition(b"\r")
            return mp.parse_reply(raw.decode("ascii", errors="replace") + "\r", command)

    def command(self, command: str, *, timeout_s: float | None = None) -> Reply:
        """Like `request`, but a refusal raises `ControllerRefused` with the controller's text."""
        reply = self.request(command, timeout_s=timeout_s)
        if not reply.accepted:
            raise mp.refusal(reply, command, self._error_message(reply.error_code))
        return reply

    def _error_message(self, code: int | None) -> str:
        if not code:
            return ""
        try:
            r = self.request(f"ERRORMES{code}")
        except LinkError:
            return ""
        return r.body if r.accepted else ""

    # ------------------------------------------------------------------ RobotLink
    def connect(self) -> None:
        self._drop()
        try:
            sock = socket.create_connection((self.host, self.port), self.connect_timeout_s)
        except OSError as exc:
            raise LinkLost(f"cannot reach the MELFA controller at {self.host}:{self.port}: "
                           f"{exc}") from None
        with self._cmd_lock:
            self._cmd, self._cmd_buf = sock, b""
        try:
            self.controller_info = self.command(f"OPEN={self.client_name}").body
            self.command("CNTLON")
            st = self.read_state()
            if st.error_code:
                if not self.reset_alarms_on_connect:
                    msg = self._error_message(st.error_code)
                    raise LinkError(f"controller is in error {st.error_code:04d} ({msg}); "
                                    "reset it on the teach pendant or allow alarm reset")
                self.command("RSTALRM")
            self.command("SRVON")
            self._ovrd = None
            self._last_q = self._read_joints()
            self._connected = True
        except Exception:
            self._drop()
            raise

    def close(self) -> None:
        if self._cmd is None:
            self._drop()
            return
        try:
            if self._stream_ready and self._dl is not None:
                with contextlib.suppress(OSError):
                    self._dl.sendall(mp.format_stream_line(-1, np.zeros(self.robot.dof),
                                                           self._names))
            for c in ("SRVOFF", "CNTLOFF", "CLOSE"):
                with contextlib.suppress(LinkError):
                    self.request(c)
        finally:
            self._drop()

    @property
    def connected(self) -> bool:
        return self._connected

    def current_joints(self) -> Array:
        """Joints read from the controller; the last known ones while disconnected."""
        if self._connected:
            self._last_q = self._read_joints()
        return self._last_q.copy()

    def stop(self) -> None:
        self._stop.set()
        if self._direct_busy.is_set():
            self._stop_via_second_connection()

    def _stop_via_second_connection(self) -> None:
        """A direct move blocks the command socket until done: STOP goes over another one."""
        try:
            with socket.create_connection((self.host, self.port), self.connect_timeout_s) as s:
                s.settimeout(self.timeout_s)
                s.sendall(mp.format_request(self.robot_number, self.slot, "STOP"))
                s.recv(256)
        except OSError:
            pass

    # ------------------------------------------------------------------ status
    def _read_joints(self) -> Array:
        return mp.parse_jposf(self.command("JPOSF"), self._names)

    def read_state(self) -> DState:
        return mp.parse_dstate(self.command("DSTATE"))

    def read_error(self) -> tuple[int, str]:
        """(error number, message); (0, '') when the controller is fine."""
        code = self.read_state().error_code
        return code, self._error_message(code)

    def reset_alarm(self) -> None:
        self.command("RSTALRM")

    def current_pose(self) -> MelfaPose:
        return mp.parse_pposf(self.command("PPOSF"))

    def servo(self, on: bool) -> None:
        self.command("SRVON" if on else "SRVOFF")

    def set_override(self, percent: int) -> None:
        percent = int(np.clip(percent, 1, 100))
        if percent != self._ovrd:
            self.command(f"OVRD={percent}")
            self._ovrd = percent

    # ------------------------------------------------------------------ single moves
    def move_joints_direct(self, q: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        """One joint move by direct execution (EXEC), the reply coming when it is done.

        This is the send-wait-reply way the thesis calls too slow for continuous motion;
        kept for single moves and as the benchmark's baseline.
        """
        q = validate_path(self.robot, q)[0]
        lit = mp.format_joint_literal(q, self._names, decimals=3)
        return self._direct_move(f"JCTEACH={lit}", "MOV JCTEACH", q, speed_scale)

    def move_to_pose(self, T_base_tool: Array, *, speed_scale: float = 1.0,
                     seed: Array | None = None) -> LinkEvent:
        """Joint-interpolated move to a Cartesian target; the controller solves the IK.

        Refused before sending if our model finds no solution within the limits. The structure
        flags FL1/FL2 of our chosen solution are sent so the controller takes the same one.
        """
        seed = self._last_q if seed is None else np.asarray(seed, dtype=float)
        res = self.robot.ik(np.asarray(T_base_tool, dtype=float), seed)
        if not res.ok:
            raise LinkError(f"target pose refused before sending: {res.message}")
        q = res.best(seed)
        fl1, fl2 = mp.pose_flags(self.robot, q)
        lit = mp.format_pose_literal(MelfaPose(self.robot.fk(q), fl1, fl2))
        return self._direct_move(f"PCTEACH={lit}", "MOV PCTEACH", q, speed_scale)

    def _direct_move(self, assign: str, move: str, q: Array, speed_scale: float) -> LinkEvent:
        if not self._connected:
            raise LinkError("MELFA link is not connected; call connect() first")
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        self._stop.clear()
        self._pressed = None
        try:
            self._stop_stream()
            self.set_override(math.ceil(speed_scale * 100))
            timed = time_parametrize(np.vstack([self._last_q[None], q[None]]),
                                     self.robot.limits.velocity, max(speed_scale, 0.01))
            self.command(f"EXEC{assign}")
            self._direct_busy.set()
            try:
                reply = self.request(f"EXEC{move}",
                                     timeout_s=timed.duration * 1.5 + self.timeout_s)
            finally:
                self._direct_busy.clear()
            if reply.accepted:
                self._last_q = self._read_joints()
                ev = LinkEvent(LinkEventKind.REACHED, self._last_q.copy(), time.monotonic(),
                               "reached", 0)
                self._emit(ev)
                return ev
            return self._controller_stopped(reply.error_code or 0, reply.raw, 0,
                                            stopped=self._stop.is_set())
        except LinkLost as exc:
            return self._lost_event(str(exc), 0)
        finally:
            self._moving.release()

    # ------------------------------------------------------------------ streaming
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
        poller = _StatusPoller(self, self.status_period_s)
        try:
            return self._stream_loop(dl, targets, index, path, poller, t0)
        finally:
            poller.close()

    def _stream_loop(self, dl: socket.socket, targets: Array, index: Array, path: Array,
                     poller: _StatusPoller, t0: float) -> LinkEvent:
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
                raise self._lost(f"data link failed: {exc}") from None
            if not ready:
                continue
            try:
                chunk = dl.recv(4096)
            except TimeoutError:
                continue
            except OSError as exc:
                raise self._lost(f"data link failed: {exc}") from None
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

    def _controller_stopped(self, code: int, raw: str, path_index: int, *, stopped: bool = False,
                            message: str | None = None, emit: bool = True) -> LinkEvent:
        """The controller ended a move itself: collision, refusal or STOP."""
        with contextlib.suppress(LinkError):
            self._stop_stream()
        if message is None:
            message = self._error_message(code)
        with contextlib.suppress(LinkError):
            self._last_q = self._read_joints()
        details = {"error_code": f"{code:04d}", "controller_message": message, "raw": raw}
        if code in self.collision_codes:
            kind = LinkEventKind.COLLISION_INDICATED
            details["source"] = "controller"
            text = f"collision indicated by the controller: error {code:04d} {message}"
            # Recorded and reported: clear the alarm so the re-planned motion can run.
            with contextlib.suppress(LinkError):
                self.command("RSTALRM")
        elif stopped:
            kind, text, details = self._stopped_as(details)
        else:
            kind = LinkEventKind.ERROR
            text = f"controller refused the motion: error {code:04d} {message}; raw {raw!r}"
        ev = LinkEvent(kind, self._last_q.copy(), time.monotonic(), text, path_index, details)
        if emit:
            self._emit(ev)
        return ev

    def _lost_event(self, message: str, path_index: int) -> LinkEvent:
        self._drop()
        ev = LinkEvent(LinkEventKind.LINK_LOST, self._last_q.copy(), time.monotonic(), message,
                       path_index)
        self._emit(ev)
        return ev

    # ------------------------------------------------------------------ programs
    def program_names(self) -> list[str]:
        """Programs stored on the controller (PDIR pages until an empty one)."""
        names: list[str] = []
        for page in range(256):
            body = self.command("PDIR" if page == 0 else f"PDIR{page:02X}").body
            if not body.strip():
                break
            names.append(body.split(";", 1)[0].split(".", 1)[0].upper())
        return names

    def _store_program(self, name: str, lines: list[str]) -> None:
        chunks = mp.emdat_chunks(lines)
        if not chunks:
            raise LinkError("program is empty")
        self.command("NEW")
        self.command(f"LOAD={name}")
        self.request_edit("ECLR")
        for chunk in chunks:
            self.request_edit(f"EMDAT{chunk}")
        self.command("SAVE")

    def request_edit(self, command: str) -> Reply:
        """A command for the edit slot (TASKMAX + 1), as program editing requires."""
        slot, self.slot = self.slot, mp.EDIT_SLOT
        try:
            return self.command(command)
        finally:
            self.slot = slot

    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Store a program under a name not yet on the controller; returns that name.

        The name is `name` made MELFA-safe (A-Z, 0-9, at most 6 characters) plus a two-digit
        number chosen against the controller's directory, so a second upload never replaces
        (or is confused with) the first - the flaw of the 002 bridge.
        """
        if not self._connected:
            raise LinkError("MELFA link is not connected; call connect() first")
        try:
            lines = mp.program_lines(files)
        except UnicodeDecodeError as exc:
            raise LinkError(f"program files must be ASCII: {exc}") from None
        taken = set(self.program_names())
        base = mp.sanitize_program_name(name, max_len=6)
        unique = next((f"{base}{n:02d}" for n in range(1, 100) if f"{base}{n:02d}" not in taken),
                      None)
        if unique is None:
            raise LinkError(f"controller already holds 99 programs named {base}NN")
        self._stop_stream()
        self._store_program(unique, lines)
        if unique not in self.program_names():
            raise LinkError(f"controller did not list {unique} after SAVE")
        return unique

    def run_program(self, name: str, *, wait: bool = True,
                    on_poll: Callable[[], None] | None = None,
                    timeout_s: float = 600.0) -> LinkEvent:
        """Run a stored program in slot 1 (cycle mode); optionally wait until it ends."""
        if not self._connected:
            raise LinkError("MELFA link is not connected; call connect() first")
        self._stop_stream()
        self._stop.clear()
        self._pressed = None
        self.command("SLOTINIT")
        self.command(f"RUN{mp.sanitize_program_name(name, max_len=12)};1")
        if not wait:
            return LinkEvent(LinkEventKind.MOVED, self._last_q.copy(), time.monotonic(),
                             f"{name} started")
        deadline = time.monotonic() + timeout_s
        while True:
            st = self.read_state()
            if on_poll:
                on_poll()
            if st.error_code:
                return self._controller_stopped(st.error_code, f"DSTATE error "
                                                f"{st.error_code:04d}", st.step)
            if self._stop.is_set():
                self.command("STOP")
                return self._controller_stopped(0, "STOP", st.step, stopped=True, message="")
            if not st.running:
                self._last_q = self._read_joints()
                ev = LinkEvent(LinkEventKind.REACHED, self._last_q.copy(), time.monotonic(),
                               f"{name} finished")
                self._emit(ev)
                return ev
            if time.monotonic() > deadline:
                raise LinkError(f"{name} still running after {timeout_s:.0f} s")
            time.sleep(max(self.status_period_s, 0.01))


__all__ = ["ControllerRefused", "MelfaLink"]
