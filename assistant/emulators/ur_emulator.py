"""A Universal Robots controller on localhost, driven by our kinematic model (a UR5 from
example-robot-data in the tests).

Ports, as on a real controller (each 0 = any free port here): RTDE (30004,
`ur_rtde_server`), the primary client interface (30001: URScript in; robot state at 10 Hz -
robot mode, the calibrated kinematics - and robot messages out, `ur_primary`), the secondary
interface (30002: URScript in, robot state out, no messages), and the dashboard server
(29999: ``is in remote control``, ``unlock protective stop``, ``power on``, ``brake
release``, ``robotmode``, ``safetystatus``, ``get serial number``, ...). The state stream
carries a sub-package and, now and then, a package of types no client knows, as newer
controllers do.

Factory state (an e-Series, software 5.11, as it ships): *Local control* - the primary and
secondary interfaces close every connection and the dashboard refuses ``power on``,
``brake release``, ``unlock protective stop`` and program commands with UR's sentence -
until `set_remote_control(True)` (the pendant's toggle; ``--remote`` on the command line).
A CB3 (software 3.x) has no such mode and streams RTDE at 125 Hz at most. The arm is
calibrated: `calibration` (default `ur_kinematics.factory_calibration`, a few mm from
nominal) is published on the primary interface and is what the controller computes its TCP
and solves ``movel`` with; collisions are checked on the nominal model. A received program
is compiled first (`ur_script_interp`; anything outside the subset is a compile error
reported as a runtime-exception message, and nothing moves), then run on a thread; a new
program replaces the running one, as on a UR. Motions run on `EmulatedArm` at infinite
acceleration: ``movej`` is the straight joint segment at the leading joint's speed ``v``,
``movel``/``movec`` follow the TCP line/arc (2 mm steps, a local IK tracking each pose).

Safety: touching a hidden obstacle is a protective stop (what a UR's force limit does), as
is `trigger_protective_stop`; `unlock protective stop` is refused until `unlock_delay_s`
after it (5 s on a UR). `press_emergency_stop` powers the arm off until released, powered
on and its brakes released. Faults (`faults.Faults`): drop (every socket closed mid-move),
reply delay (the RTDE stream and dashboard stall), garbage (a package's bytes replaced).

    python -m assistant.emulators.ur_emulator --rtde-port 30004 --script-port 30002
"""

from __future__ import annotations

import argparse
import contextlib
import re
import socket
import threading
import time
from collections.abc import Iterable

import numpy as np

from assistant.collision.reports import ObstacleView
from assistant.emulators.arm import CollisionInfo, EmulatedArm
from assistant.emulators.faults import Faults, Received
from assistant.emulators.ur_rtde_server import RtdeServer
from assistant.emulators.ur_runner import ScriptRunner
from assistant.emulators.ur_script_interp import ScriptError, compile_script
from assistant.links import ur_kinematics as uk
from assistant.links import ur_primary as up
from assistant.links import ur_rtde_wire as w
from assistant.links.ur_script import to_controller_pose
from assistant.robots.model import Robot

Array = np.ndarray
UNLOCK_REFUSED = ("Cannot unlock protective stop until 5s after occurrence. Always inspect "
                  "cause of protective stop before unlocking")
#: The dashboard's answer to a command an e-Series in Local control does not take.
NOT_REMOTE = ("Command is not allowed due to safety reasons, please switch robot to Remote "
              "Control mode and reconnect to port 29999")
#: Dashboard commands an e-Series takes in Local control too (reading, not acting).
LOCAL_ALLOWED = ("robotmode", "safetystatus", "safetymode", "is in remote control",
                 "polyscopeversion", "get serial number", "get robot model", "programstate",
                 "running", "get loaded program", "is program saved", "get operational mode",
                 "quit")
STATE_PERIOD_S = 0.1  # robot state packages on 30001/30002: 10 Hz


class UREmulator:
    """RTDE + secondary interface + dashboard over one model arm."""

    def __init__(self, robot: Robot, *, hidden_obstacles: Iterable[ObstacleView] = (),
                 host: str = "127.0.0.1", rtde_port: int = 0, script_port: int = 0,
                 dashboard_port: int = 0, primary_port: int = 0, time_scale: float = 1.0,
                 tick_s: float = 0.004, start_q: Array | None = None,
                 faults: Faults | None = None, unlock_delay_s: float = 5.0,
                 version: tuple[int, int, int, int] = (5, 11, 1, 108318),
                 local_mode: bool | None = None, realtime_port: int = 0,
                 calibration: up.KinematicsInfo | None | bool = True,
                 serial: str = "20235500001"):
        self.model_name, _, _ = uk.identify(robot)
        if calibration is True:
            calibration = uk.factory_calibration(self.model_name) if self.model_name else None
        self.calibration: up.KinematicsInfo | None = calibration or None
        #: The controller's own arm: base = its base frame, flange = tool0, calibrated.
        self.base_robot = robot if self.calibration is None else \
            uk.calibrated_robot(self.calibration, robot)
        self.robot = self.base_robot.with_tool(robot.T_flange_tool)  # the installation TCP
        self.host, self.version = host, version
        self.serial = serial
        e_series = version[0] >= 5
        self.remote_control = not e_series if local_mode is None else \
            (not local_mode or not e_series)
        self.faults = faults or Faults()
        self.time_scale = float(time_scale)
        self.unlock_delay_s = float(unlock_delay_s)
        self.arm = EmulatedArm(robot, hidden_obstacles=hidden_obstacles, time_scale=time_scale,
                               tick_s=tick_s, start_q=start_q, faults=self.faults,
                               on_collision=self._on_collision, on_drop=self.drop_connections)
        self._lock = threading.RLock()
        self.safety_mode = w.SafetyMode.NORMAL
        self.robot_mode = w.RobotMode.RUNNING
        self.int_registers = [0] * 48
        self.digital_outputs: dict[str, bool] = {}
        self.messages: list[str] = []  # runtime exceptions / text sent to clients
        self.received: list[Received] = []
        self.programs_run: list[str] = []
        self._pstop_at = 0.0
        self._tcp_key: tuple = ()
        self._tcp: list[float] = []
        self._t0 = time.monotonic()
        self.runner = ScriptRunner(self)
        self.rtde = RtdeServer(self.snapshot, self.faults, host=host, port=rtde_port,
                               version=version)
        self._primary_srv = socket.create_server((host, primary_port))
        self._script_srv = socket.create_server((host, script_port))
        self._realtime_srv = socket.create_server((host, realtime_port))
        self._dash_srv = socket.create_server((host, dashboard_port))
        self._conns: set[socket.socket] = set()
        self._script_conns: set[socket.socket] = set()  # 30002: robot state only
        self._primary_conns: set[socket.socket] = set()  # 30001: state and messages
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> UREmulator:
        self.arm.start()
        self.rtde.start()
        for srv, fn in ((self._primary_srv, self._serve_primary),
                        (self._script_srv, self._serve_script),
                        (self._realtime_srv, self._serve_realtime),
                        (self._dash_srv, self._serve_dashboard)):
            srv.settimeout(0.05)
            th = threading.Thread(target=self._accept, args=(srv, fn), daemon=True,
                                  name="ur-emulator-accept")
            th.start()
            self._threads.append(th)
        th = threading.Thread(target=self._state_loop, daemon=True, name="ur-emulator-state")
        th.start()
        self._threads.append(th)
        return self

    def close(self) -> None:
        self._stop.set()
        self.runner.abort()
        self.arm.close()
        self.rtde.close()
        self.drop_connections()
        for th in self._threads:
            th.join(timeout=2.0)
        for srv in (self._primary_srv, self._script_srv, self._realtime_srv, self._dash_srv):
            srv.close()

    def __enter__(self) -> UREmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def rtde_port(self) -> int:
        return self.rtde.port

    @property
    def script_port(self) -> int:
        return self._script_srv.getsockname()[1]

    @property
    def primary_port(self) -> int:
        return self._primary_srv.getsockname()[1]

    @property
    def realtime_port(self) -> int:
        return self._realtime_srv.getsockname()[1]

    def set_remote_control(self, on: bool) -> None:
        """The pendant's Local / Remote toggle; leaving Remote drops 30001-30003 clients."""
        with self._lock:
            self.remote_control = bool(on) or self.version[0] < 5
            conns = [] if self.remote_control else \
                list(self._primary_conns | self._script_conns)
        for c in conns:
            with contextlib.suppress(OSError):
                c.shutdown(socket.SHUT_RDWR)

    @property
    def dashboard_port(self) -> int:
        return self._dash_srv.getsockname()[1]

    def drop_connections(self) -> None:
        """The cable is pulled: every client socket closes, then the program and the arm stop
        (in that order, so no client reads the stopped program before the wire goes)."""
        self.rtde.drop_clients()
        with self._lock:
            conns, self._conns = list(self._conns), set()
            self._script_conns, self._primary_conns = set(), set()
        for c in conns:
            with contextlib.suppress(OSError):
                c.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                c.close()
        self.runner.abort()

    # ------------------------------------------------------------------ state
    def snapshot(self) -> dict:
        """The RTDE output values now."""
        q = self.arm.q
        running = self.runner.running  # before the registers: a finished program's last
        # After `running` too: the arm halts at a contact (releasing the program, which may
        # end) a moment before `_on_collision` records the protective stop; a UR shows both
        # at once, so a contact already made is a protective stop here.
        collided = self.arm.faulted_now
        with self._lock:  # register write is then always seen together with its end
            mode, smode = self.robot_mode, self.safety_mode
            regs = list(self.int_registers)
            robot = self.robot
        if collided and smode == w.SafetyMode.NORMAL:
            smode = w.SafetyMode.PROTECTIVE_STOP
        powered = mode in (w.RobotMode.POWER_ON, w.RobotMode.IDLE, w.RobotMode.RUNNING)
        key = (q.tobytes(), id(robot))
        if key != self._tcp_key:  # a still arm: no kinematics at 500 Hz
            self._tcp_key, self._tcp = key, to_controller_pose(self.base_robot, robot.fk(q))
        tcp = self._tcp
        snap = {
            "timestamp": time.monotonic() - self._t0, "actual_q": list(q), "target_q": list(q),
            "actual_TCP_pose": tcp, "target_TCP_pose": tcp, "robot_mode": int(mode),
            "safety_mode": int(smode), "safety_status": int(smode),
            "safety_status_bits": w.safety_status_bits(smode),
            "runtime_state": int(w.RuntimeState.PLAYING if running else w.RuntimeState.STOPPED),
            "robot_status_bits": (1 if powered else 0) | (2 if running else 0),
            "joint_mode": [253] * 6, "speed_scaling": 1.0, "target_speed_fraction": 1.0,
            "speed_scaling_combined": 1.0, "joint_temperatures": [30.0] * 6,
            "actual_main_voltage": 48.0, "actual_robot_voltage": 48.0,
            "actual_joint_voltage": [48.0] * 6, "actual_execution_time": 0.5,
        }
        for i, v in enumerate(regs):
            snap[f"output_int_register_{i}"] = int(v)
        return snap

    def mode_data(self) -> up.RobotModeData:
        with self._lock:
            mode, smode = self.robot_mode, self.safety_mode
        return up.RobotModeData(
            power_on=mode in (w.RobotMode.POWER_ON, w.RobotMode.IDLE, w.RobotMode.RUNNING),
            emergency_stopped=smode in w.EMERGENCY_STOPS,
            protective_stopped=smode == w.SafetyMode.PROTECTIVE_STOP,
            program_running=self.runner.running, robot_mode=int(mode))

    def _state_loop(self) -> None:
        """Robot state packages at 10 Hz to 30001 and 30002 clients; every tenth also a
        package type no client knows (clients must skip it by its length)."""
        k = 0
        while not self._stop.wait(STATE_PERIOD_S):
            subs = [up.robot_mode_sub(self.mode_data())]
            if self.calibration is not None:
                subs.append(up.kinematics_sub(self.calibration))
            subs.append(up.unknown_package(99, b"\x00" * 12))  # a sub-package of the future
            pkg = up.robot_state(*subs)
            if k % 10 == 0:
                pkg = up.unknown_package(24, b"\x01" * 40) + pkg  # e.g. safety compliance
            k += 1
            with self._lock:
                conns = list(self._primary_conns | self._script_conns)
            for c in conns:
                with contextlib.suppress(OSError):
                    c.sendall(pkg)

    def set_tcp(self, T_flange_tool: Array | None) -> None:
        with self._lock:
            self.robot = self.base_robot if T_flange_tool is None \
                else self.base_robot.with_tool(T_flange_tool)

    def _on_collision(self, info: CollisionInfo) -> None:
        self.trigger_protective_stop(f"C153A1 protective stop: collision ({info.description})")

    def trigger_protective_stop(self, why: str = "C153A1 protective stop") -> None:
        with self._lock:
            self.safety_mode = w.SafetyMode.PROTECTIVE_STOP
            self._pstop_at = time.monotonic()
        self.runner.abort()
        self.arm.stop_all("stopped")
        self.broadcast(up.safety_mode_message(153, 1, int(w.SafetyMode.PROTECTIVE_STOP), why),
                       why)

    def press_emergency_stop(self) -> None:
        with self._lock:
            self.safety_mode = w.SafetyMode.ROBOT_EMERGENCY_STOP
            self.robot_mode = w.RobotMode.POWER_OFF
        self.runner.abort()
        self.arm.stop_all("stopped")

    def release_emergency_stop(self) -> None:
        with self._lock:
            if self.safety_mode in w.EMERGENCY_STOPS:
                self.safety_mode = w.SafetyMode.NORMAL

    def broadcast(self, package: bytes, text: str) -> None:
        """Send a robot message to every primary-interface client (the secondary interface
        carries no messages)."""
        with self._lock:
            self.messages.append(text)
            conns = list(self._primary_conns)
        for c in conns:
            with contextlib.suppress(OSError):
                c.sendall(package)

    # ------------------------------------------------------------------ sockets
    def _accept(self, srv: socket.socket, serve) -> None:  # noqa: ANN001
        while not self._stop.is_set():
            try:
                sock, _ = srv.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.settimeout(0.1)
            with self._lock:
                self._conns.add(sock)
            threading.Thread(target=self._guard, args=(serve, sock), daemon=True,
                             name="ur-emulator-client").start()

    def _guard(self, serve, sock: socket.socket) -> None:  # noqa: ANN001
        try:
            serve(sock)
        except OSError:
            pass
        finally:
            with self._lock:
                self._conns.discard(sock)
                self._script_conns.discard(sock)
                self._primary_conns.discard(sock)
            with contextlib.suppress(OSError):
                sock.close()

    def _lines(self, sock: socket.socket):  # noqa: ANN202
        """Yield text chunks as they arrive (None after 0.1 s idle) until EOF or close."""
        while not self._stop.is_set():
            try:
                data = sock.recv(65536)
            except TimeoutError:
                yield None
                continue
            if not data:
                return
            yield data.decode("utf-8", errors="replace")

    def _serve_primary(self, sock: socket.socket) -> None:
        self._serve_script(sock, primary=True)

    def _serve_realtime(self, sock: socket.socket) -> None:
        """30003 takes URScript too (its 500 Hz state stream is not emulated)."""
        self._serve_script(sock, realtime=True)

    def _serve_script(self, sock: socket.socket, primary: bool = False,
                      realtime: bool = False) -> None:
        with self._lock:
            if not self.remote_control:
                return  # Local control: the connection is dropped at once
        major, minor, bugfix, build = self.version
        if primary:
            sock.sendall(up.version_message("URControl", major, minor, bugfix, build))
        with self._lock:
            if not realtime:
                (self._primary_conns if primary else self._script_conns).add(sock)
        buf = ""
        for chunk in self._lines(sock):
            if chunk is None:
                # A program is complete once its text has arrived and the sender paused.
                if buf.strip() and self._complete(buf):
                    self._run_text(buf)
                    buf = ""
                continue
            buf += chunk
            if self._complete(buf):
                self._run_text(buf)
                buf = ""

    @staticmethod
    def _complete(text: str) -> bool:
        """A whole program has arrived: every block opened (def, while, if, ...) is closed."""
        lines = [ln.split("#", 1)[0].strip() for ln in text.splitlines()]
        lines = [ln for ln in lines if ln]
        if not text.endswith("\n") or not lines:
            return False
        if not lines[0].startswith("def "):
            return True
        opened = sum(1 for ln in lines
                     if re.match(r"(def|while|if|for|thread)\b", ln) and ln.endswith(":"))
        return sum(1 for ln in lines if ln == "end") >= opened

    def _run_text(self, text: str) -> None:
        with self._lock:
            self.received.append(Received("script", time.monotonic(), text))
        try:
            prog = compile_script(text)
        except ScriptError as exc:
            self.broadcast(up.runtime_exception(str(exc), exc.line, exc.column), str(exc))
            return
        if all(st.call in ("stopj", "stopl") for st in prog.body):
            self.runner.abort()  # stopping a stopped arm is harmless in any safety state
            return
        with self._lock:
            blocked = self.safety_mode != w.SafetyMode.NORMAL or \
                self.robot_mode != w.RobotMode.RUNNING
            why = f"robot is in {self.safety_mode.name} / {self.robot_mode.name}"
        if blocked:
            self.broadcast(up.runtime_exception(f"cannot start {prog.name}: {why}"), why)
            return
        self.runner.run(prog)

    def _serve_dashboard(self, sock: socket.socket) -> None:
        sock.sendall(b"Connected: Universal Robots Dashboard Server\n")
        buf = ""
        for chunk in self._lines(sock):
            if chunk is None:
                continue
            buf += chunk
            while "\n" in buf:
                line, buf = buf.split("\n", 1)
                with self._lock:
                    self.received.append(Received("dashboard", time.monotonic(), line))
                reply, delay = self.faults.take_reply(self._dashboard(line.strip()))
                if delay > 0:
                    time.sleep(delay)
                sock.sendall((reply + "\n").encode())
                if reply == "Disconnected":
                    return

    def _dashboard(self, cmd: str) -> str:
        c = " ".join(cmd.lower().split())
        with self._lock:
            if not self.remote_control and not c.startswith(LOCAL_ALLOWED):
                return NOT_REMOTE
            if c == "is in remote control":
                if self.version[0] < 5:
                    return f"could not understand: '{cmd}'"
                return "true" if self.remote_control else "false"
            if c == "get serial number":
                return self.serial
            if c == "get robot model":
                return (self.model_name or "UR5").rstrip("e")
            if c == "get operational mode":
                return "NONE"  # no operational-mode password set: as shipped
            if c == "running":
                return f"Program running: {str(self.runner.running).lower()}"
            if c == "get loaded program":
                return "No program loaded"
            if c == "is program saved":
                return "true <unnamed>"
            if c == "quit":
                return "Disconnected"
            if c.startswith("popup "):
                return "showing popup"
            if c == "close popup":
                return "closing popup"
            if c.startswith("addtolog "):
                return "Added log message"
            if c == "robotmode":
                return f"Robotmode: {self.robot_mode.name}"
            if c in ("safetystatus", "safetymode"):
                return f"Safetystatus: {self.safety_mode.name}"
            if c == "unlock protective stop":
                if self.safety_mode != w.SafetyMode.PROTECTIVE_STOP:
                    return "Protective stop releasing"  # what a UR answers when not stopped
                if time.monotonic() - self._pstop_at < self.unlock_delay_s:
                    return UNLOCK_REFUSED
                self.safety_mode = w.SafetyMode.NORMAL
                self.arm.clear_fault()
                return "Protective stop releasing"
            if c == "close safety popup":
                return "closing safety popup"
            if c == "power on":
                if self.safety_mode in w.EMERGENCY_STOPS:
                    return "Failed to execute: power on"
                if self.robot_mode == w.RobotMode.POWER_OFF:
                    self.robot_mode = w.RobotMode.IDLE
                return "Powering on"
            if c == "brake release":
                if self.robot_mode == w.RobotMode.IDLE:
                    self.robot_mode = w.RobotMode.RUNNING
                return "Brake releasing"
            if c == "stop":
                self.runner.abort()
                return "Stopped"
            if c == "programstate":
                name = self.runner.current or "<unnamed>"
                return f"{'PLAYING' if self.runner.running else 'STOPPED'} {name}"
            if c == "polyscopeversion":
                return "URSoftware {}.{}.{}.{} (emulated)".format(*self.version)
            if c == "power off":
                self.runner.abort()
                self.robot_mode = w.RobotMode.POWER_OFF
                return "Powering off"
        return f"could not understand: '{cmd}'"


def main(argv: list[str] | None = None) -> None:
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.urdf_robot import URDFRobot

    ap = argparse.ArgumentParser(description="Universal Robots controller emulator (UR5 model)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--rtde-port", type=int, default=30004)
    ap.add_argument("--script-port", type=int, default=30002)
    ap.add_argument("--dashboard-port", type=int, default=29999)
    ap.add_argument("--primary-port", type=int, default=30001)
    ap.add_argument("--remote", action="store_true",
                    help="start in Remote control (a shipped e-Series starts in Local)")
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--reply-delay-ms", type=float, default=0.0)
    args = ap.parse_args(argv)
    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    robot = URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                                tool_link="tool0")
    faults = Faults(reply_delay_s=args.reply_delay_ms / 1000.0)
    q0 = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
    emu = UREmulator(robot, host=args.host, rtde_port=args.rtde_port,
                     script_port=args.script_port, dashboard_port=args.dashboard_port,
                     primary_port=args.primary_port, time_scale=args.time_scale, start_q=q0,
                     faults=faults, local_mode=not args.remote)
    from assistant.emulators.until_stopped import install_stop_handlers, wait_until_stopped

    with emu:
        install_stop_handlers()
        print(f"UR emulator on {args.host}: rtde :{emu.rtde_port} primary :{emu.primary_port} "
              f"script :{emu.script_port} dashboard :{emu.dashboard_port}; Ctrl-C to stop",
              flush=True)
        wait_until_stopped()


if __name__ == "__main__":
    main()
