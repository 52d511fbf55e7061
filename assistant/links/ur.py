"""Drive a Universal Robots arm: state over RTDE, motion and programs as URScript.

State - joints, TCP, robot mode, safety mode, the running program's progress registers -
comes over RTDE (30004) at the controller's rate (500 Hz on an e-Series, 125 Hz on a CB3:
read from its version) from our own small client (`ur_rtde_client` says why not ur-rtde's).
Motion goes as URScript programs over the secondary interface (30002, `ur_script`); what
the controller says back - runtime exceptions, safety messages, error popups - and its
calibrated kinematics come on the primary interface (30001, `ur_primary`), which the link
reads all along. ur-rtde's control interface would need its own control script running on
the controller and RTDE input registers, i.e. a full controller; plain programs work on every
UR and are what the exporter writes anyway. A joint path is decimated (`decimate.py`) and sent
as one program of exact-stop ``movej`` - one round trip per path, not per target.

Connecting checks what a controller as it ships would refuse: an e-Series starts in Local
control, drops the client interfaces and refuses ``power on``; the link asks the dashboard
``is in remote control`` first and says what to switch on the pendant. The TCP the controller
reports is checked against its own calibrated kinematics (`ur_kinematics`), and how far the
calibration moves the TCP from the nominal model is reported (`calibration`).

How moves end, mapped onto the session's states as the MELFA and KUKA links do:
- the finish register reaches the program's number: REACHED;
- a protective stop (the UR's reaction to a contact): COLLISION_INDICATED, source
  "controller"; before the next move the link unlocks it through the dashboard (a UR refuses
  for 5 s; the link retries for `unlock_wait_s`);
- an emergency stop: LINK_LOST - the robot is powered off and stays still; `connect()` is
  refused until the e-stop is released, then powers the arm on and releases the brakes;
- a safeguard stop, our `stop()` or a program ended by someone else: STOPPED (the operator's
  Collision! button: COLLISION_INDICATED, source "operator");
- a runtime exception from the controller (a refused target, a script it cannot run): ERROR
  quoting the controller's message;
- a silent or dropped stream, or an arm standing still past the move's time + `timeout_s`
  without the program's end: LINK_LOST (a moving arm is never timed out - the speed slider
  may stretch a move far beyond its planned time);
  a garbled stream: ERROR quoting the bytes (RTDE is re-opened on the next call).
"""

from __future__ import annotations

import contextlib
import itertools
import re
import threading
import time

import numpy as np

from assistant.links import ur_kinematics as uk
from assistant.links import ur_rtde_wire as w
from assistant.links import ur_script as us
from assistant.links.decimate import exact_stop_targets
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.links.operator_button import OperatorButton
from assistant.links.timing import time_parametrize, validate_path
from assistant.links.ur_channels import ScriptChannel, dashboard
from assistant.links.ur_rtde_client import RtdeClient, RtdeState
from assistant.links.wirelog import NULL, WireLog
from assistant.robots.model import Robot

Array = np.ndarray
#: Program numbers (in the progress registers): time-based, so registers a previous session
#: left on the controller never match a new program's number.
_program_seq = itertools.count(int(time.time()) % 100000 * 100)
TCP_CHECK_M = 0.002  # the robot's TCP must agree with our model within this
#: A joint change between two state packages above this is motion (rad); RTDE doubles carry
#: the encoder value, whose noise on a standing UR is ~1e-6 rad.
MOVING_RAD = 1e-5
#: What an e-Series in Local control needs from the operator (PolyScope 5 user manual,
#: "Remote Control"; the toggle is at the top right of the pendant's header).
LOCAL_MODE = ("the UR is in Local control: on the teach pendant tap the Local icon at the top "
              "right and choose Remote Control (if it is not offered: Settings > System > "
              "Remote Control > Enable, with the admin password), then Connect again")


class URLink(OperatorButton, RobotLink):
    """RTDE + secondary interface + dashboard client for a UR (CB3 or e-Series).

    Args:
        robot: the model of the arm (a UR URDF: kinematics, limits, speeds, tool).
        host: the controller's address; `script_port`, `rtde_port`, `dashboard_port` its
            secondary interface (30002), RTDE (30004) and dashboard server (29999).
        rtde_hz: state rate asked for (500 on e-Series, 125 on CB3).
        timeout_s: longest silence of the state stream, and the slack beyond a move's time.
        decimation_tol_m: how far on the arm the movej path may leave the planned one.
        unlock_wait_s: how long to keep asking to unlock a protective stop.
    """

    def __init__(self, robot: Robot, *, host: str = "127.0.0.1", script_port: int = 30002,
                 rtde_port: int = 30004, dashboard_port: int = 29999, rtde_hz: float = 500.0,
                 connect_timeout_s: float = 2.0, timeout_s: float = 1.0,
                 decimation_tol_m: float = 0.002, unlock_wait_s: float = 6.0,
                 joint_accel_rad_s2: float = 4.0, tool_speed_m_s: float = 0.25,
                 event_period_s: float = 0.05, keep_arrivals: int = 0,
                 primary_port: int = 30001, wire: WireLog = NULL):
        super().__init__()
        if timeout_s <= 0 or decimation_tol_m <= 0 or unlock_wait_s < 0:
            raise ValueError("timeout_s, decimation_tol_m must be > 0, unlock_wait_s >= 0")
        self.robot = robot
        self.host = host
        self.dashboard_port = int(dashboard_port)
        self.timeout_s, self.connect_timeout_s = float(timeout_s), float(connect_timeout_s)
        self.decimation_tol_m, self.unlock_wait_s = float(decimation_tol_m), float(unlock_wait_s)
        self.joint_accel, self.tool_speed = float(joint_accel_rad_s2), float(tool_speed_m_s)
        self.event_period_s = float(event_period_s)
        self.wire = wire
        self.rtde = RtdeClient(host, rtde_port, frequency_hz=rtde_hz, timeout_s=timeout_s,
                               connect_timeout_s=connect_timeout_s, keep_arrivals=keep_arrivals,
                               wire=wire)
        self.primary = ScriptChannel(host, primary_port, connect_timeout_s, wire, "primary")
        self.script = self.primary if int(primary_port) == int(script_port) else \
            ScriptChannel(host, script_port, connect_timeout_s, wire, "secondary")
        #: The controller's calibrated kinematics (None before connect or if not published).
        self.kinematics = None
        self.calibration: uk.CalibrationReport | None = None
        self._kin_robot: Robot | None = None
        self.remote_control: bool | None = None
        self._radii = robot.arm_radii()
        self._flange = robot.with_tool(np.eye(4))
        self._connected = False
        self._stop = threading.Event()
        self._moving = threading.Lock()
        self._last_q = np.zeros(robot.dof)
        self.last_command_count = 0
        self.last_program = ""

    # ------------------------------------------------------------------ connection
    def connect(self) -> None:
        self.close()
        try:
            st = self.rtde.connect()
            self.check_remote_control()
            self.primary.connect()
            if self.script is not self.primary:
                self.script.connect()
            st = self._ready(st, on_connect=True)
            self._read_calibration(st)
            self._check_tcp(st)
        except Exception:
            self.close()
            raise
        self._last_q = st.q
        self._connected = True

    @property
    def e_series(self) -> bool:
        return self.rtde.controller_version[0] >= 5

    def dashboard(self, command: str) -> str:
        return dashboard(self.host, self.dashboard_port, command, self.timeout_s, self.wire)

    def check_remote_control(self) -> None:
        """An e-Series must be in Remote control (CB3s have no such mode)."""
        self.remote_control = None
        if not self.e_series:
            return
        reply = self.dashboard("is in remote control").strip().lower()
        if reply in ("true", "false"):
            self.remote_control = reply == "true"
        if self.remote_control is False:
            raise ControllerRefused(LOCAL_MODE, code="local_control", raw=reply)

    def _read_calibration(self, st: RtdeState) -> None:
        """The calibrated DH table from the primary interface, and how far it is from nominal.
        Without one (software before 3.6) the nominal model is all we have."""
        self.kinematics = self.primary.wait_kinematics(max(self.timeout_s, 0.5))
        if self.kinematics is None:
            self._kin_robot, self.calibration = None, None
            return
        self._kin_robot = uk.calibrated_robot(self.kinematics, self.robot)
        self.calibration = uk.compare(self.kinematics, self.robot, st.q)

    def _ready(self, st: RtdeState, *, on_connect: bool = False) -> RtdeState:
        """Make the arm able to move: unlock a protective stop, power on after an e-stop."""
        smode = st["safety_mode"]
        if smode in w.EMERGENCY_STOPS:
            raise LinkLost("the robot's emergency stop is pressed: release it, then "
                           "Reconnect")
        if smode == w.SafetyMode.PROTECTIVE_STOP:
            self._unlock_protective_stop()
        elif smode != w.SafetyMode.NORMAL and smode != w.SafetyMode.REDUCED:
            raise LinkError(f"the robot is in {w.mode_name(w.SafetyMode, smode)}: clear it on "
                            "the teach pendant")
        if not on_connect and st["robot_mode"] != w.RobotMode.RUNNING:
            raise LinkLost(f"the robot is {w.mode_name(w.RobotMode, st['robot_mode'])}: "
                           "Reconnect to power it on and release the brakes")
        if on_connect and st["robot_mode"] != w.RobotMode.RUNNING:
            for cmd, want in (("power on", "Powering on"), ("brake release", "Brake releasing")):
                reply = self.dashboard(cmd)
                if not reply.startswith(want):
                    raise ControllerRefused(f"the robot refused {cmd!r}: {reply!r}",
                                            code=cmd, raw=reply)
            self.rtde.wait_for(lambda s: s["robot_mode"] == w.RobotMode.RUNNING,
                               self.unlock_wait_s + self.timeout_s)
        return self.rtde.wait_for(lambda s: s["safety_mode"] in (w.SafetyMode.NORMAL,
                                                                 w.SafetyMode.REDUCED)
                                  and s["robot_mode"] == w.RobotMode.RUNNING,
                                  self.timeout_s)

    def _unlock_protective_stop(self) -> None:
        deadline = time.monotonic() + self.unlock_wait_s
        while True:
            reply = self.dashboard("unlock protective stop")
            if reply.startswith("Protective stop releasing"):
                return
            if not reply.startswith("Cannot unlock protective stop"):
                raise ProtocolError(f"unexpected dashboard reply to 'unlock protective stop': "
                                    f"{reply[:200]!r}", raw=reply)
            if time.monotonic() > deadline:
                raise ControllerRefused(f"the protective stop could not be unlocked within "
                                        f"{self.unlock_wait_s:.1f} s: {reply!r}",
                                        code="protective_stop", raw=reply)
            time.sleep(0.1)

    def _check_tcp(self, st: RtdeState) -> None:
        """The robot's reported TCP must be where the controller's calibrated chain puts our
        tool (or the bare flange, before our first program sets the TCP); our model's flange
        must be the controller's tool flange, or every pose would be turned."""
        model, _, angle = uk.identify(self.robot)
        if model is not None and angle > 1e-3:
            raise LinkError(f"our {self.robot.name} model's flange ({self._flange_name()}) is "
                            f"turned {np.degrees(angle):.0f} deg against the UR's tool flange: "
                            "choose the tool link 'tool0' for this robot")
        if self._kin_robot is not None:
            T_rep = us.from_controller_pose(self._kin_robot, st.tcp_pose)
            cands = [self._kin_robot.fk(st.q) @ self.robot.T_flange_tool,
                     self._kin_robot.fk(st.q)]
            what = "the controller's calibrated kinematics put"
        else:
            T_rep = us.from_controller_pose(self.robot, st.tcp_pose)
            cands = [m.fk(st.q) for m in (self.robot, self._flange)]
            what = f"our {self.robot.name} model puts"
        off = min(float(np.linalg.norm(T[:3, 3] - T_rep[:3, 3])) for T in cands)
        if off > TCP_CHECK_M:
            raise LinkError(f"the robot reports its TCP {off * 1000:.1f} mm from where {what} "
                            "our tool: wrong robot model or tool?")

    def _flange_name(self) -> str:
        return str(getattr(self.robot, "tool_link", "flange"))

    def close(self) -> None:
        self._connected = False
        self.rtde.close()
        self.primary.close()
        self.script.close()

    @property
    def connected(self) -> bool:
        return self._connected

    def _state(self) -> RtdeState:
        """The newest state; a stream broken by garbage is re-opened once."""
        try:
            return self.rtde.latest()
        except ProtocolError:
            self._reopen()
            raise
        except LinkLost:
            self._connected = False
            raise

    def _reopen(self) -> None:
        """After garbage: reported once; the stream cannot re-synchronise, so re-open it."""
        with contextlib.suppress(LinkError):
            self.rtde.connect()

    def _halt(self) -> None:
        """The link cannot follow the robot any more: stop it (best effort)."""
        with contextlib.suppress(LinkError):
            self.script.send(us.stop_line(self.joint_accel))

    def current_joints(self) -> Array:
        if self._connected:
            self._last_q = self._state().q
        return self._last_q.copy()

    def current_pose(self) -> Array:
        """The TCP pose the robot reports, in the model base."""
        return us.from_controller_pose(self.robot, self._state().tcp_pose)

    def robot_state(self) -> dict[str, str]:
        st = self._state()
        return {"robot_mode": w.mode_name(w.RobotMode, st["robot_mode"]),
                "safety_mode": w.mode_name(w.SafetyMode, st["safety_mode"]),
                "runtime_state": w.mode_name(w.RuntimeState, st["runtime_state"]),
                "control": {None: "n/a", True: "remote", False: "local"}[self.remote_control]}

    def stop(self) -> None:
        self._stop.set()
        with contextlib.suppress(LinkError):
            self.script.send(us.stop_line(self.joint_accel))

    # ------------------------------------------------------------------ motions
    def plan_targets(self, path: Array) -> tuple[Array, Array]:
        """The movej targets (decimated) for a validated path and their path indices."""
        return exact_stop_targets(path, self._last_q, self._radii, self.decimation_tol_m)

    def move_path(self, joint_path: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        path = validate_path(self.robot, joint_path)
        time_parametrize(path[:1], self.robot.limits.velocity, speed_scale)  # checks the scale
        return self._motion(lambda: self._joint_program(path, speed_scale))

    def _joint_program(self, path: Array, speed_scale: float) -> tuple[str, int, float, Array]:
        targets, index = self.plan_targets(path)
        self.last_command_count = len(targets)
        v = speed_scale * float(np.min(self.robot.limits.velocity))
        timed = time_parametrize(np.vstack([self._last_q[None], targets]),
                                 self.robot.limits.velocity, speed_scale)
        number = next(_program_seq)
        name = f"ct_{number}"
        text = us.joint_program(name, number, self.robot, targets, v, self.joint_accel)
        return text, number, timed.duration, index

    def move_linear(self, T_base_tool: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        """Straight TCP line (``movel``) to a pose our model can reach from here."""
        T = np.asarray(T_base_tool, dtype=float)
        if not self.robot.ik(T, self._last_q).ok:
            raise LinkError("movel target refused before sending: our model cannot reach it")
        d = float(np.linalg.norm(T[:3, 3] - self.robot.fk(self._last_q)[:3, 3]))
        return self._motion(lambda: self._cart_program("movel", [T], d, speed_scale))

    def move_circ(self, T_via: Array, T_to: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        """Circular TCP motion through `T_via` to `T_to` (``movec``, mode 0)."""
        for what, T in (("via", T_via), ("target", T_to)):
            if not self.robot.ik(np.asarray(T, dtype=float), self._last_q).ok:
                raise LinkError(f"movec {what} pose refused before sending: unreachable")
        p0 = self.robot.fk(self._last_q)[:3, 3]
        d = float(np.linalg.norm(T_via[:3, 3] - p0) + np.linalg.norm(T_to[:3, 3] - T_via[:3, 3]))
        return self._motion(lambda: self._cart_program("movec", [T_via, T_to], d * 1.6,
                                                       speed_scale))

    def _cart_program(self, kind: str, Ts: list[Array], length: float, speed_scale: float,
                      ) -> tuple[str, int, float, Array]:
        number = next(_program_seq)
        poses = [us.to_controller_pose(self.robot, T) for T in Ts]
        v = speed_scale * self.tool_speed
        text = us.linear_program(f"ct_{number}", number, self.robot, kind, poses, v, 1.2)
        return text, number, 2.0 * length / v, np.zeros(1, dtype=np.int64)

    def _motion(self, build) -> LinkEvent:  # noqa: ANN001
        if not self._connected:
            raise LinkError("UR link is not connected; call connect() first")
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        self._stop.clear()
        self._pressed = None
        try:
            try:
                st = self._state()
                self._last_q = st.q
                self._ready(st)
            except LinkLost as exc:
                return self._lost(str(exc), 0)
            except ProtocolError as exc:
                return self._event(LinkEventKind.ERROR, str(exc), 0, {"raw": exc.raw})
            text, number, expected_s, index = build()
            return self._run(text, number, expected_s, index)
        finally:
            self._moving.release()

    # ------------------------------------------------------------------ running a program
    def _run(self, text: str, number: int, expected_s: float, index: Array) -> LinkEvent:
        """Send a program and follow it on RTDE until it ends; the end as an event."""
        self.last_program = text
        try:
            t_sent = self.script.send(text)
            started = self.rtde.wait_for(
                lambda s: s["output_int_register_24"] == number or self._refused(t_sent)
                or s["safety_mode"] != w.SafetyMode.NORMAL, self.timeout_s)
        except LinkLost as exc:
            return self._lost(str(exc), 0)
        except ProtocolError as exc:
            self._halt()
            self._reopen()
            return self._event(LinkEventKind.ERROR, f"{exc}; the robot was stopped", 0,
                               {"raw": exc.raw})
        if started["output_int_register_24"] != number:
            return self._ended(started, number, t_sent, index)
        deadline = time.monotonic() + expected_s * 1.5 + self.timeout_s
        last_event, seq = 0.0, started.seq
        while True:
            try:
                st = self.rtde.wait_for(lambda s: True, self.timeout_s, after_seq=seq)
            except LinkLost as exc:
                self._halt()
                return self._lost(str(exc), self._index(None, index))
            except ProtocolError as exc:
                self._halt()
                self._reopen()
                return self._event(LinkEventKind.ERROR, f"{exc}; the robot was stopped",
                                   self._index(None, index), {"raw": exc.raw})
            seq = st.seq
            now = time.monotonic()
            if np.max(np.abs(st.q - self._last_q)) > MOVING_RAD:
                # Still moving (the speed slider or a slowed cell may stretch the move far
                # beyond its planned time): only an arm that stands past its time is lost.
                deadline = max(deadline, now + self.timeout_s)
            self._last_q = st.q
            running = st["runtime_state"] == w.RuntimeState.PLAYING
            if st["output_int_register_25"] == number or not running or \
                    st["safety_mode"] != w.SafetyMode.NORMAL or self._refused(t_sent):
                return self._ended(st, number, t_sent, index)
            if now > deadline:
                self.stop()
                return self._lost(f"the UR stood still {self.timeout_s:.1f} s without finishing "
                                  f"a move planned for {expected_s:.2f} s",
                                  self._index(st, index))
            if now - last_event >= self.event_period_s:
                last_event = now
                self._emit(LinkEvent(LinkEventKind.MOVED, st.q, now, "moving",
                                     self._index(st, index)))

    def _errors(self, since: float) -> list:
        """The controller's error messages since `since` (primary interface)."""
        chans = [self.primary] if self.script is self.primary else [self.primary, self.script]
        return [m for c in chans for m in c.messages_since(since) if m.is_error
                and m.kind != 5]  # safety-mode messages: RTDE's safety mode tells those

    def _refused(self, since: float) -> bool:
        return bool(self._errors(since))

    def _index(self, st: RtdeState | None, index: Array) -> int:
        k = 0 if st is None else int(st["output_int_register_26"])
        return int(index[int(np.clip(k, 0, len(index) - 1))])

    def _ended(self, st: RtdeState, number: int, t_sent: float, index: Array) -> LinkEvent:
        self._last_q = st.q
        # Register 26 is this program's only once it has started (24 = its number).
        at = self._index(st, index) if st["output_int_register_24"] == number else int(index[0])
        smode = st["safety_mode"]
        details = {"safety_mode": w.mode_name(w.SafetyMode, smode),
                   "runtime_state": w.mode_name(w.RuntimeState, st["runtime_state"]),
                   "program": f"ct_{number}"}
        if st["output_int_register_25"] == number:
            return self._event(LinkEventKind.REACHED, "reached", int(index[-1]), details)
        if smode in w.EMERGENCY_STOPS:
            return self._lost("emergency stop pressed on the robot; release it, then "
                              "Reconnect", at)
        if smode == w.SafetyMode.PROTECTIVE_STOP and self._pressed is None:
            details["source"] = "controller"
            return self._event(LinkEventKind.COLLISION_INDICATED,
                               "collision indicated by the robot: protective stop", at, details)
        if not self._stop.is_set():
            # A runtime exception may arrive just after RTDE shows the program stopped.
            end = time.monotonic() + min(0.2, self.timeout_s)
            while time.monotonic() < end and not self._refused(t_sent):
                time.sleep(0.01)
        refusals = self._errors(t_sent)
        if refusals and not self._stop.is_set():
            msg = refusals[0].describe()
            details["controller_message"] = msg
            return self._event(LinkEventKind.ERROR, f"the robot refused the program: {msg}",
                               at, details)
        if self._stop.is_set():
            kind, text, details = self._stopped_as(details)
            return self._event(kind, text, at, details)
        return self._event(LinkEventKind.STOPPED, "the program was stopped on the robot "
                           f"({details['safety_mode']})", at, details)

    def _lost(self, message: str, path_index: int) -> LinkEvent:
        self.close()
        return self._event(LinkEventKind.LINK_LOST, f"UR at {self.host} lost: {message}",
                           path_index)

    def _event(self, kind: LinkEventKind, message: str, path_index: int,
               details: dict | None = None) -> LinkEvent:
        ev = LinkEvent(kind, self._last_q.copy(), time.monotonic(), message, path_index,
                       details or {})
        self._emit(ev)
        return ev

    # ------------------------------------------------------------------ programs
    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Run an exported ``.script`` under a fresh name; returns that name once it ended.

        UR programs sent to the secondary interface run at once (storing one needs the
        controller's file system); the program is renamed and reports its start and end
        through RTDE registers, so the link knows it ran to its end.
        """
        scripts = [f for f in files if f.lower().endswith(".script")]
        if len(scripts) != 1 or len(files) != 1:
            raise LinkError(f"need exactly one .script file, got {sorted(files)}")
        text = files[scripts[0]].decode("utf-8")
        base = re.sub(r"[^A-Za-z0-9_]", "_", name).strip("_")[:20] or "prog"
        number = next(_program_seq)
        unique = f"{base if base[0].isalpha() else 'p' + base}_{number}"
        try:
            program = us.instrument_upload(text, unique, number)
        except ValueError as exc:
            raise LinkError(f"{scripts[0]}: {exc}") from None
        ev = self._motion(lambda: (program, number, 3600.0, np.zeros(1, dtype=np.int64)))
        if ev.kind == LinkEventKind.REACHED:
            return unique
        if ev.kind == LinkEventKind.LINK_LOST:
            raise LinkLost(f"program {unique}: {ev.message}")
        raw = ev.details.get("controller_message", ev.message)
        where = re.search(r"script line (\d+)", raw)
        line = f" (line {int(where.group(1)) - 1} of {scripts[0]})" \
            if where and int(where.group(1)) > 1 else ""  # one line was inserted after def
        raise ControllerRefused(f"program {unique} did not run to its end{line}: {ev.message}",
                                code=ev.kind.value, raw=raw)
