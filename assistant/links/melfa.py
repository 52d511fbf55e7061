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

This module holds the command-port session (connect, requests, status, single moves, how a
move ends); `melfa_streaming` holds the joint stream and `melfa_programs` the program upload
and run, both mixed into `MelfaLink`.
"""

from __future__ import annotations

import contextlib
import math
import socket
import threading
import time

import numpy as np

from assistant.links import melfa_protocol as mp
from assistant.links.errors import ControllerRefused
from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.links.melfa_programs import MelfaPrograms
from assistant.links.melfa_protocol import DState, MelfaPose, Reply
from assistant.links.melfa_streaming import MelfaStreaming
from assistant.links.operator_button import OperatorButton
from assistant.links.timing import time_parametrize, validate_path
from assistant.links.wirelog import NULL, WireLog
from assistant.robots.model import Robot

Array = np.ndarray


class MelfaLink(MelfaStreaming, MelfaPrograms, OperatorButton, RobotLink):
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
        wire: WireLog = NULL,
    ):
        super().__init__()
        self.wire = wire
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
                self.wire.sent(f"command:{self.port}", mp.format_request(
                    self.robot_number, self.slot, command))
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
            self.wire.received(f"command:{self.port}", raw)
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

    # ------------------------------------------------------------------ how a move ends
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


__all__ = ["ControllerRefused", "MelfaLink"]
