"""A Universal Robots controller on localhost, driven by our kinematic model (a UR5 from
example-robot-data in the tests).

Ports, as on a real controller (each 0 = any free port here): RTDE (30004,
`ur_rtde_server`), the secondary client interface (30002: URScript in, robot messages out,
`ur_primary`), and the dashboard server (29999: text commands such as ``unlock protective
stop``, ``power on``, ``brake release``, ``robotmode``, ``safetystatus``). A received program
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

    python -m assistant.links.emulators.ur_emulator --rtde-port 30004 --script-port 30002
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
from assistant.links import ur_primary as up
from assistant.links import ur_rtde_wire as w
from assistant.links.emulators.arm import CollisionInfo, EmulatedArm
from assistant.links.emulators.faults import Faults, Received
from assistant.links.emulators.ur_rtde_server import RtdeServer
from assistant.links.emulators.ur_runner import ScriptRunner
from assistant.links.emulators.ur_script_interp import ScriptError, compile_script
from assistant.links.ur_script import to_controller_pose
from assistant.robots.model import Robot

Array = np.ndarray
UNLOCK_REFUSED = ("Cannot unlock protective stop until 5s after occurrence. Always inspect "
                  "cause of protective stop before unlocking")


class UREmulator:
    """RTDE + secondary interface + dashboard over one model arm."""

    def __init__(self, robot: Robot, *, hidden_obstacles: Iterable[ObstacleView] = (),
                 host: str = "127.0.0.1", rtde_port: int = 0, script_port: int = 0,
                 dashboard_port: int = 0, time_scale: float = 1.0, tick_s: float = 0.004,
                 start_q: Array | None = None, faults: Faults | None = None,
                 unlock_delay_s: float = 5.0,
                 version: tuple[int, int, int, int] = (5, 11, 1, 108318)):
        self.base_robot = robot
        self.robot = robot  # with the TCP of the running program
        self.host, self.version = host, version
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
        self._script_srv = socket.create_server((host, script_port))
        self._dash_srv = socket.create_server((host, dashboard_port))
        self._conns: set[socket.socket] = set()
        self._script_conns: set[socket.socket] = set()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> UREmulator:
        self.arm.start()
        self.rtde.start()
        for srv, fn in ((self._script_srv, self._serve_script),
                        (self._dash_srv, self._serve_dashboard)):
            srv.settimeout(0.05)
            th = threading.Thread(target=self._accept, args=(srv, fn), daemon=True,
                                  name="ur-emulator-accept")
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
        for srv in (self._script_srv, self._dash_srv):
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
    def dashboard_port(self) -> int:
        return self._dash_srv.getsockname()[1]

    def drop_connections(self) -> None:
        """The cable is pulled: every client socket closes, then the program and the arm stop
        (in that order, so no client reads the stopped program before the wire goes)."""
        self.rtde.drop_clients()
        with self._lock:
            conns, self._conns, self._script_conns = list(self._conns), set(), set()
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
        self.broadcast(up.pack_robot_message(up.MSG_SAFETY_MODE, why.encode()), why)

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
        """Send a robot message to every secondary-interface client."""
        with self._lock:
            self.messages.append(text)
            conns = list(self._script_conns)
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

    def _serve_script(self, sock: socket.socket) -> None:
        major, minor, bugfix, build = self.version
        sock.sendall(up.version_message("URControl", major, minor, bugfix, build))
        with self._lock:
            self._script_conns.add(sock)
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

    def _dashboard(self, cmd: str) -> str:
        c = cmd.lower()
        with self._lock:
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
        return f"could not understand: '{cmd}'"


def main(argv: list[str] | None = None) -> None:
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.urdf_robot import URDFRobot

    ap = argparse.ArgumentParser(description="Universal Robots controller emulator (UR5 model)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--rtde-port", type=int, default=30004)
    ap.add_argument("--script-port", type=int, default=30002)
    ap.add_argument("--dashboard-port", type=int, default=29999)
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--reply-delay-ms", type=float, default=0.0)
    args = ap.parse_args(argv)
    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    robot = URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False)
    faults = Faults(reply_delay_s=args.reply_delay_ms / 1000.0)
    q0 = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
    emu = UREmulator(robot, host=args.host, rtde_port=args.rtde_port,
                     script_port=args.script_port, dashboard_port=args.dashboard_port,
                     time_scale=args.time_scale, start_q=q0, faults=faults)
    from assistant.links.emulators.until_stopped import wait_until_stopped

    with emu:
        print(f"UR emulator on {args.host}: rtde :{emu.rtde_port} script :{emu.script_port} "
              f"dashboard :{emu.dashboard_port}; Ctrl-C to stop", flush=True)
        wait_until_stopped()


if __name__ == "__main__":
    main()
