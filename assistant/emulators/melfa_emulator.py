"""A Mitsubishi CR-series controller on localhost, driven by our kinematic model (RV-2AJ).

It speaks the controller-communication text protocol on one TCP port (``1;1;JPOSF`` ->
``QoKJ1;...``, see `melfa_protocol`) and serves Ethernet data-link ports (``COM2:``) that
programs open with ``OPEN "COM2:" AS #1``. Uploaded programs run in a small MELFA BASIC
interpreter; the arm moves in time at the model's joint speeds, refuses out-of-range targets
with the real reply shape (``QeR2600``), stops before hidden obstacles (error 1010, replies
then start with ``Qok``), and can be told to drop connections, answer late or garble.

This module holds the command port and the program runs; `melfa_machine` holds what the
interpreter drives (moves, servo, data-link channels) and `melfa_sockets` the connections and
data-link ports.

Run as a script for demos::

    python -m assistant.emulators.melfa_emulator --port 10001 --datalink-port 10002
"""

from __future__ import annotations

import argparse
import socket
import socketserver
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from assistant.collision.reports import ObstacleView
from assistant.emulators.arm import CollisionInfo, EmulatedArm
from assistant.emulators.faults import Faults, Received
from assistant.emulators.melfa_machine import MelfaMachine
from assistant.emulators.melfa_program import (
    Interpreter,
    MelfaProgram,
    ProgramError,
    ProgramSyntaxError,
)
from assistant.emulators.melfa_sockets import POLL_S, DataLinkPort, LineConnection
from assistant.emulators.until_stopped import install_stop_handlers, wait_until_stopped
from assistant.links import melfa_protocol as mp
from assistant.links.melfa_protocol import DState
from assistant.robots.model import Robot

Array = np.ndarray


@dataclass
class _RunningProgram:
    name: str
    interp: Interpreter
    abort: threading.Event = field(default_factory=threading.Event)
    thread: threading.Thread | None = None


class MelfaEmulator(MelfaMachine):
    """A CR-series controller emulator: command port + data-link ports + a moving model.

    Args:
        robot: the kinematic model the controller drives (the RV-2AJ in the thesis).
        hidden_obstacles: obstacles only the emulator knows; the arm stops before them.
        port: command port (0 = any free port; a real CR1 listens on 10000-10009).
        datalink_ports: COM number -> TCP port for the data link (COM2 = OPT12 = 10002).
        time_scale: robot seconds per wall second (tests run motions faster).
        tick_s: servo cycle in wall seconds (7.1 ms on a CR1).
        start_q: initial joints.
        faults: shared `Faults` object (a new one if omitted).
    """

    def __init__(
        self,
        robot: Robot,
        *,
        hidden_obstacles: Iterable[ObstacleView] = (),
        host: str = "127.0.0.1",
        port: int = 0,
        datalink_ports: dict[int, int] | None = None,
        time_scale: float = 1.0,
        tick_s: float = 0.0071,
        start_q: Array | None = None,
        faults: Faults | None = None,
    ):
        self.robot = robot
        self.joint_names = list(robot.joint_names)
        self.host = host
        self.faults = faults or Faults()
        self.time_scale = float(time_scale)
        self.arm = EmulatedArm(robot, hidden_obstacles=hidden_obstacles, time_scale=time_scale,
                               tick_s=tick_s, start_q=start_q, faults=self.faults,
                               on_collision=self._on_collision, on_drop=self._on_drop)
        self._lock = threading.RLock()
        self.operation_enabled = False
        self.servo_on = False
        self.error_code = 0
        self.panel_ovrd = 100.0
        self.hands: dict[int, bool] = {}
        self.programs: dict[str, MelfaProgram] = {}
        self._edit: MelfaProgram | None = None
        self._running: _RunningProgram | None = None
        self._direct = Interpreter(self)
        self._direct_lock = threading.Lock()
        self.received: list[Received] = []
        self._recv_lock = threading.Lock()
        self._conns: set[LineConnection] = set()
        self._closed = threading.Event()
        self._port_req = port
        self._dl_req = dict(datalink_ports or {mp.STREAM_COM: 0})
        self._server: socketserver.ThreadingTCPServer | None = None
        self._server_thread: threading.Thread | None = None
        self.datalinks: dict[int, DataLinkPort] = {}

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> MelfaEmulator:
        emu = self

        class Handler(socketserver.BaseRequestHandler):
            def handle(self) -> None:
                emu._serve(self.request)

        class Server(socketserver.ThreadingTCPServer):
            allow_reuse_address = True
            daemon_threads = True

        self._server = Server((self.host, self._port_req), Handler)
        self._server_thread = threading.Thread(target=self._server.serve_forever,
                                               kwargs={"poll_interval": POLL_S},
                                               name="melfa-command", daemon=True)
        self._server_thread.start()
        for com, p in self._dl_req.items():
            self.datalinks[com] = DataLinkPort(self, com, self.host, p)
        self.arm.start()
        return self

    def close(self) -> None:
        self._closed.set()
        self._stop_program()
        self.arm.close()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
        for c in list(self._conns):
            c.close()
        for dl in self.datalinks.values():
            dl.close()
        if self._server_thread is not None:
            self._server_thread.join(timeout=2.0)

    def __enter__(self) -> MelfaEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def port(self) -> int:
        assert self._server is not None, "start() first"
        return self._server.server_address[1]

    def datalink_port(self, com: int = mp.STREAM_COM) -> int:
        return self.datalinks[com].port

    # ------------------------------------------------------------------ logs
    def log_received(self, channel: str, text: str) -> None:
        with self._recv_lock:
            self.received.append(Received(channel, time.monotonic(), text))

    def received_texts(self, channel: str | None = None) -> list[str]:
        with self._recv_lock:
            return [r.text for r in self.received if channel is None or r.channel == channel]

    # ------------------------------------------------------------------ command port
    def _serve(self, sock: socket.socket) -> None:
        sock.settimeout(POLL_S)
        conn = LineConnection(sock)
        with self._lock:
            self._conns.add(conn)
        try:
            while not self._closed.is_set():
                line = conn.readline(self._closed)
                if line is None:
                    return
                self.log_received("command", line)
                reply = self.handle(line)
                out, delay = self.faults.take_reply(reply)
                if delay > 0:
                    time.sleep(delay)
                if conn.closed:
                    return
                try:
                    sock.sendall((out + mp.TERMINATOR).encode("ascii", errors="replace"))
                except OSError:
                    return
                if line.split(";", 2)[-1].strip().upper() == "CLOSE":
                    return
        finally:
            with self._lock:
                self._conns.discard(conn)
            conn.close()

    def _ok(self, body: str = "") -> str:
        return ("Qok" if self.error_code else "QoK") + body

    def _refuse(self, code: int, extra: str = "") -> str:
        return ("Qer" if self.error_code else "QeR") + f"{code:04d}" + extra

    def handle(self, line: str) -> str:
        """Answer one request line (public so tests can drive the controller directly)."""
        try:
            robot_no, slot, cmd = mp.parse_request(line)
        except ValueError:
            return self._refuse(mp.ERR_ILLEGAL_DATA)
        if robot_no != 1:
            return self._refuse(mp.ERR_ILLEGAL_DATA)
        up = cmd.upper()
        try:
            return self._dispatch(cmd, up)
        except ProgramSyntaxError as exc:
            return self._refuse(exc.code, f";{exc.line or 0};{exc.pos}")
        except ProgramError as exc:
            return self._refuse(exc.code)
        except (ValueError, IndexError):
            return self._refuse(mp.ERR_ILLEGAL_DATA)

    def _need_rights(self) -> None:
        if not self.operation_enabled:
            raise ProgramError(mp.ERR_NO_OPERATION_RIGHTS, "no operation rights")

    def _dispatch(self, cmd: str, up: str) -> str:
        if up.startswith("OPEN="):
            return self._ok(f"{self.robot.name.split()[-1]};CR1-EMU;MELFA;cellteach emulator")
        if up == "CLOSE":
            return self._ok()
        if up in ("CNTLON", "CNTLOFF"):
            self.operation_enabled = up == "CNTLON"
            return self._ok()
        if up in ("SRVON", "SRVOFF"):
            self._need_rights()
            self.set_servo(up == "SRVON")
            return self._ok()
        if up == "RSTALRM":
            with self._lock:
                self.error_code = 0
            self.arm.clear_fault()
            return self._ok()
        if up == "STOP":
            self._stop_program()
            self.arm.stop_all("stopped")
            return self._ok()
        if up == "SLOTINIT":
            self._need_rights()
            self._stop_program()
            return self._ok()
        if up.startswith("OVRD"):
            if "=" in up:
                self._need_rights()
                self.panel_ovrd = float(np.clip(float(up.split("=", 1)[1]), 1, 100))
            return self._ok(f"{int(self.panel_ovrd)}")
        if up == "JPOSF":
            vals = mp.to_wire_deg(self.arm.q, self.joint_names)
            body = ";".join(f"{n};{v:.2f}" for n, v in zip(mp.WIRE_JOINTS, vals, strict=True))
            return self._ok(f"{body};;****,****;{int(self.panel_ovrd)};0.00;00000000")
        if up == "PPOSF":
            pose = self.current_pose()
            a, b, c = np.degrees(mp.matrix_to_melfa_abc(pose.T_base_tool[:3, :3]))
            x, y, z = pose.T_base_tool[:3, 3] * 1000.0
            body = ";".join(f"{n};{v:.2f}" for n, v in zip("XYZABC", (x, y, z, a, b, c),
                                                           strict=True))
            return self._ok(f"{body};;{pose.fl1},{pose.fl2};{int(self.panel_ovrd)};0.00;"
                            "00000000")
        if up == "DSTATE":
            run = (0x80 if self.operation_enabled else 0) | (0x20 if self.servo_on else 0) | \
                (0x40 if self._running is not None else 0)
            line = self._running.interp.line if self._running is not None else 0
            return self._ok(mp.format_dstate(DState(run, 0, self.error_code, line or 0)))
        if up.startswith("ERRORMES"):
            code = int(up[len("ERRORMES"):] or 0)
            return self._ok(mp.ERROR_MESSAGES.get(code, "Unknown error number"))
        if up.startswith("PDIR"):
            return self._pdir(up[4:])
        if up == "NEW":
            self._need_rights()
            self._edit = None
            return self._ok()
        if up.startswith("LOAD="):
            self._need_rights()
            name = mp.sanitize_program_name(cmd.split("=", 1)[1], max_len=12)
            old = self.programs.get(name)
            self._edit = MelfaProgram(name, dict(old.code), dict(old.positions)) if old \
                else MelfaProgram(name)
            return self._ok()
        if up == "ECLR":
            if self._edit is None:
                raise ProgramError(mp.ERR_NO_PROGRAM, "no program being edited")
            self._edit = MelfaProgram(self._edit.name)
            return self._ok()
        if up.startswith("EMDAT"):
            if self._edit is None:
                raise ProgramError(mp.ERR_NO_PROGRAM, "no program being edited")
            for raw in cmd[5:].split("\v"):
                self._edit.add_line(raw)
            return self._ok()
        if up == "SAVE":
            self._need_rights()
            if self._edit is None:
                raise ProgramError(mp.ERR_NO_PROGRAM, "no program being edited")
            self.programs[self._edit.name] = self._edit
            return self._ok()
        if up.startswith("RUN"):
            self._need_rights()
            name, _, _mode = cmd[3:].partition(";")
            return self._run(mp.sanitize_program_name(name, max_len=12))
        if up.startswith("EXEC"):
            self._need_rights()
            return self._exec(cmd[4:])
        raise ProgramError(mp.ERR_UNKNOWN_COMMAND, cmd)

    def _pdir(self, page: str) -> str:
        names = sorted(self.programs)
        n = int(page, 16) if page.strip() and page.strip() != "TOP" else 0
        if n >= len(names):
            return self._ok()
        p = self.programs[names[n]]
        return self._ok(f"{p.name}.MB4;0;{time.strftime('%y-%m-%d%H:%M:%S')};0;0;"
                        f"{p.line_count}")

    def _run(self, name: str) -> str:
        if self.error_code:
            return self._refuse(self.error_code)
        if name not in self.programs:
            raise ProgramError(mp.ERR_NO_PROGRAM, name)
        if self._running is not None:
            raise ProgramError(mp.ERR_ILLEGAL_DATA, "a program is running")
        prog = self.programs[name]
        # A new program run opens its ports afresh: nothing left over from an earlier client.
        for dl in self.datalinks.values():
            dl.drop()
        run = _RunningProgram(name, Interpreter(self, prog))

        def body() -> None:
            try:
                run.interp.run(run.abort)
            except ProgramError as exc:
                if not run.abort.is_set():
                    with self._lock:
                        self.error_code = exc.code
            finally:
                with self._lock:
                    if self._running is run:
                        self._running = None

        run.thread = threading.Thread(target=body, name=f"melfa-run-{name}", daemon=True)
        self._running = run
        run.thread.start()
        return self._ok()

    def _stop_program(self) -> None:
        run = self._running
        if run is None:
            return
        run.abort.set()
        if run.thread is not None and run.thread is not threading.current_thread():
            run.thread.join(timeout=2.0)
        with self._lock:
            if self._running is run:
                self._running = None

    def _exec(self, stmt: str) -> str:
        if self.error_code:
            return self._refuse(self.error_code)
        with self._direct_lock:
            abort = threading.Event()
            self._direct.execute(stmt, abort)
        return self._ok()

    # ------------------------------------------------------------------ events from the arm
    def _on_collision(self, info: CollisionInfo) -> None:
        with self._lock:
            self.error_code = mp.ERR_COLLISION
            run = self._running
        if run is not None:
            run.abort.set()

    def _on_drop(self) -> None:
        with self._lock:
            conns = list(self._conns)
        for c in conns:
            c.close()
        for dl in self.datalinks.values():
            dl.drop()


def _parse_box(text: str):
    from assistant.collision.reports import Obstacle
    from assistant.robots.model import CollisionShape, ShapeKind
    from assistant.transforms import make_T

    v = [float(x) / 1000.0 for x in text.split(",")]
    if len(v) != 6:
        raise argparse.ArgumentTypeError("--hidden-box wants x,y,z,sx,sy,sz in mm")
    return Obstacle(f"hidden_{text}", make_T(p=v[:3]),
                    (CollisionShape(ShapeKind.BOX, tuple(v[3:])),))


def main(argv: list[str] | None = None) -> None:
    from assistant.robots.rv2aj import RV2AJ

    ap = argparse.ArgumentParser(description="MELFA CR-series controller emulator (RV-2AJ)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=10001)
    ap.add_argument("--datalink-port", type=int, default=10002, help="TCP port of COM2:")
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--reply-delay-ms", type=float, default=0.0,
                    help="answer every request this late (a busy controller, a slow network)")
    ap.add_argument("--hidden-box", type=_parse_box, action="append", default=[],
                    help="hidden obstacle box x,y,z,sx,sy,sz in mm (repeatable)")
    args = ap.parse_args(argv)
    emu = MelfaEmulator(RV2AJ(), hidden_obstacles=args.hidden_box, host=args.host,
                        port=args.port, datalink_ports={mp.STREAM_COM: args.datalink_port},
                        time_scale=args.time_scale)
    emu.faults.delay_replies(args.reply_delay_ms / 1000.0)
    with emu:
        install_stop_handlers()
        print(f"MELFA emulator: commands on {args.host}:{emu.port}, COM2: data link on "
              f"{args.host}:{emu.datalink_port()}; Ctrl-C to stop", flush=True)
        wait_until_stopped()


if __name__ == "__main__":
    main()
