"""The KUKA REST bridge of source 002 on localhost, with a model arm behind it.

Same endpoints, query parameters and JSON replies as the 002 bridge (``POST /krl/ptp?x=..``
-> ``{"statuscode": 1, "position": [...]}``), one command at a time (a mutex, as in 002
Listing 4.1). There is no KUKA model in the project, so the arm behind it is the RV-2AJ
model (5 axes; documented wherever it shows). It moves in time at the model's speeds,
answers a target outside the axis ranges with statuscode -1 (software limit switch), stops
before hidden obstacles (statuscode 2), supports ``/krl/stop``, and runs uploaded modules
(their PTP/LIN/CIRC motions). `first_upload_bug=True` reproduces the 002 flaw of always
running the first uploaded file, so the link's guard against it can be tested.

Run as a script for demos::

    python -m assistant.emulators.kuka_bridge_emulator --port 8000
"""

from __future__ import annotations

import argparse
import contextlib
import socket
import threading
import time
from collections.abc import Iterable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlsplit

import numpy as np

from assistant.collision.reports import ObstacleView
from assistant.emulators.arm import EmulatedArm, solve_wire_pose
from assistant.emulators.cartesian import arc_poses, line_poses
from assistant.emulators.faults import Faults, Received
from assistant.emulators.krl_program import KrlError, KrlMotion, parse_dat, parse_motions
from assistant.emulators.until_stopped import install_stop_handlers, wait_until_stopped
from assistant.links import kuka_protocol as kp
from assistant.links.arm_config import matches_status_turn
from assistant.robots.model import Robot

Array = np.ndarray


class _Refused(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


class KukaBridgeEmulator:
    """HTTP server speaking the 002 bridge protocol, driving a model arm.

    Args:
        robot: the arm behind the bridge (the RV-2AJ model; its limits are the bridge's).
        hidden_obstacles: obstacles only the emulator knows; the arm stops before them.
        port: HTTP port (0 = any free port).
        time_scale: robot seconds per wall second.
        home_q: the "base" (canon) position.
        first_upload_bug: always run the first uploaded module (the 002 behaviour).
    """

    def __init__(
        self,
        robot: Robot,
        *,
        hidden_obstacles: Iterable[ObstacleView] = (),
        host: str = "127.0.0.1",
        port: int = 0,
        time_scale: float = 1.0,
        tick_s: float = 0.012,
        start_q: Array | None = None,
        home_q: Array | None = None,
        faults: Faults | None = None,
        first_upload_bug: bool = False,
    ):
        self.base_robot = robot
        self.robot = robot
        self.host = host
        self.faults = faults or Faults()
        self.home_q = np.zeros(robot.dof) if home_q is None else np.asarray(home_q, float)
        self.first_upload_bug = first_upload_bug
        self.arm = EmulatedArm(robot, hidden_obstacles=hidden_obstacles, time_scale=time_scale,
                               tick_s=tick_s, start_q=start_q, faults=self.faults,
                               on_drop=self._on_drop)
        self._mutex = threading.Lock()
        self._drop_gen = 0
        self.received: list[Received] = []
        self._recv_lock = threading.Lock()
        self.files: dict[str, bytes] = {}
        self.upload_order: list[str] = []
        self.runs: list[str] = []
        self._port_req = port
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> KukaBridgeEmulator:
        emu = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"
            timeout = 2.0  # an idle keep-alive client must not hold a thread forever

            def log_message(self, *args: object) -> None:  # keep test output clean
                return

            def do_POST(self) -> None:  # noqa: N802 (http.server naming)
                emu._handle(self)

            def do_GET(self) -> None:  # noqa: N802
                self.send_error(405, "the bridge accepts POST only")

        class Server(ThreadingHTTPServer):
            daemon_threads = True
            allow_reuse_address = True

        self._server = Server((self.host, self._port_req), Handler)
        self._server.timeout = 0.05
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        kwargs={"poll_interval": 0.05}, name="kuka-bridge",
                                        daemon=True)
        self._thread.start()
        self.arm.start()
        return self

    def close(self) -> None:
        self.arm.close()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def __enter__(self) -> KukaBridgeEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def port(self) -> int:
        assert self._server is not None, "start() first"
        return self._server.server_address[1]

    def received_endpoints(self) -> list[str]:
        with self._recv_lock:
            return [r.channel for r in self.received]

    def _on_drop(self) -> None:
        self._drop_gen += 1

    # ------------------------------------------------------------------ HTTP
    def _handle(self, h: BaseHTTPRequestHandler) -> None:
        url = urlsplit(h.path)
        length = int(h.headers.get("Content-Length") or 0)
        body = h.rfile.read(length) if length else b""
        parts = url.path.strip("/").split("/")
        endpoint = parts[1] if len(parts) == 2 and parts[0] == "krl" else ""
        with self._recv_lock:
            self.received.append(Received(endpoint or url.path, time.monotonic(), url.query))
        if endpoint not in kp.ENDPOINTS:
            self._send(h, 404, '{"detail":"Not Found"}')
            return
        q = {k: v[-1] for k, v in parse_qs(url.query).items()}
        if endpoint == "stop":  # outside the mutex: it must reach a running motion
            self.arm.stop_all("stopped")
            self._send(h, 200, kp.reply_json(kp.STATUS_OK, self._position()))
            return
        gen = self._drop_gen
        with self._mutex:
            try:
                text = self._execute(endpoint, q, body, h.headers.get("Content-Type", ""))
            except _Refused as exc:
                text = kp.reply_json(exc.code, self._position(), str(exc))
            except (ValueError, KeyError) as exc:
                text = kp.reply_json(kp.STATUS_BAD_REQUEST, self._position(), str(exc))
        if self._drop_gen != gen:
            # The cable was pulled mid-move: no answer, the connection just dies.
            with contextlib.suppress(OSError):
                h.connection.shutdown(socket.SHUT_RDWR)
            h.close_connection = True
            return
        self._send(h, 200, text)

    def _send(self, h: BaseHTTPRequestHandler, status: int, text: str) -> None:
        out, delay = self.faults.take_reply(text)
        if delay > 0:
            time.sleep(delay)
        data = out.encode("utf-8", errors="replace")
        try:
            h.send_response(status)
            h.send_header("Content-Type", "application/json")
            h.send_header("Content-Length", str(len(data)))
            h.end_headers()
            h.wfile.write(data)
        except OSError:
            h.close_connection = True

    # ------------------------------------------------------------------ commands
    def _position(self) -> list[float]:
        return kp.T_to_position(self.robot.fk(self.arm.q))

    def _target_T(self, q: dict[str, str], prefix: str = "") -> Array:
        cur = self._position()
        vals = [float(q.get(f"{prefix}{k}", cur[i])) for i, k in enumerate("xyzabc")]
        return kp.position_to_T(vals)

    def _solve(self, T: Array, s: int | None, t: int | None, seed: Array) -> Array:
        qsol, why = solve_wire_pose(self.robot, T, seed,
                                    lambda c: matches_status_turn(self.robot, c, s, t))
        if qsol is None:
            code = kp.STATUS_LIMIT if ("limit" in why or "configuration" in why) \
                else kp.STATUS_UNREACHABLE
            raise _Refused(code, f"{kp.STATUS_TEXT[code]}: {why}")
        return qsol

    def _speed(self, q: dict[str, str]) -> float:
        return float(np.clip(float(q.get("vel", 100.0)) / 100.0, 0.01, 1.0))

    def _run_motion(self, waypoints: list[Array], speed: float, tag: str) -> str:
        m = self.arm.enqueue(np.array(waypoints), speed, tag)
        outcome = self.arm.wait(m)
        if outcome == "collision":
            info = self.arm.last_collision
            raise _Refused(kp.STATUS_COLLISION, f"{kp.STATUS_TEXT[kp.STATUS_COLLISION]}: "
                           f"{info.description if info else 'contact'}")
        if outcome == "stopped":
            raise _Refused(kp.STATUS_STOPPED, kp.STATUS_TEXT[kp.STATUS_STOPPED])
        return outcome

    def _cartesian(self, poses: list[Array], seed: Array) -> list[Array]:
        out, q = [], seed
        for T in poses:
            qn, why = solve_wire_pose(self.robot, T, q, lambda c: True,
                                     project_tol_rad=np.pi)
            if qn is None or np.max(np.abs(qn - q)) > 0.35:
                raise _Refused(kp.STATUS_UNREACHABLE,
                               f"{kp.STATUS_TEXT[kp.STATUS_UNREACHABLE]}: {why or 'flip'}")
            out.append(qn)
            q = qn
        return out

    def _execute(self, endpoint: str, q: dict[str, str], body: bytes, ctype: str) -> str:
        s = int(q["s"]) if "s" in q else None
        t = int(q["t"]) if "t" in q else None
        if endpoint in ("base", "ptp", "linmov", "circ", "uploadfile"):
            self.arm.clear_fault()  # the last collision was reported; a new command may move
        if endpoint in ("getpos",):
            return kp.reply_json(kp.STATUS_OK, self._position())
        if endpoint == "gettcp":
            return kp.reply_json(kp.STATUS_OK, kp.T_to_position(self.robot.T_flange_tool))
        if endpoint == "tcp":
            T = self._target_T(q) if q else np.eye(4)
            self.robot = self.base_robot if np.allclose(T, self.base_robot.T_flange_tool,
                                                        atol=1e-6) \
                else self.base_robot.with_tool(T)
            return kp.reply_json(kp.STATUS_OK, kp.T_to_position(self.robot.T_flange_tool))
        if endpoint == "base":
            self._run_motion([self.home_q], self._speed(q), "base")
        elif endpoint == "ptp":
            target = self._solve(self._target_T(q), s, t, self.arm.q)
            self._run_motion([target], self._speed(q), "ptp")
        elif endpoint == "linmov":
            start = self.arm.q
            poses = line_poses(self.robot.fk(start), self._target_T(q))
            self._run_motion(self._cartesian(poses, start), self._speed(q), "lin")
        elif endpoint == "circ":
            start = self.arm.q
            try:
                poses = arc_poses(self.robot.fk(start), self._target_T(q, "aux_"),
                                   self._target_T(q))
            except ValueError as exc:
                raise _Refused(kp.STATUS_BAD_REQUEST, str(exc)) from None
            self._run_motion(self._cartesian(poses, start), self._speed(q), "circ")
        elif endpoint == "uploadfile":
            return self._upload(body, ctype)
        return kp.reply_json(kp.STATUS_OK, self._position())

    def _upload(self, body: bytes, ctype: str) -> str:
        parts = kp.parse_multipart(body, ctype)
        if "file" not in parts:
            raise _Refused(kp.STATUS_BAD_REQUEST, "multipart field 'file' missing")
        filename, data = parts["file"]
        stem, _, ext = filename.rpartition(".")
        if not stem or ext.lower() not in ("src", "dat"):
            raise _Refused(kp.STATUS_PROGRAM_ERROR, f"{filename!r} is not a .src/.dat file")
        key = f"{stem.upper()}.{ext.lower()}"
        self.files[key] = data
        if ext.lower() == "dat":
            return kp.reply_json(kp.STATUS_OK, self._position(), program=stem)
        self.upload_order.append(stem)
        run = self.upload_order[0] if self.first_upload_bug else stem
        return self._run_module(run)

    def _run_module(self, stem: str) -> str:
        src = self.files[f"{stem.upper()}.src"].decode("utf-8", errors="replace")
        if (kp.krl_module_name(src) or "").upper() != stem.upper():
            raise _Refused(kp.STATUS_PROGRAM_ERROR,
                           f"module name {kp.krl_module_name(src)!r} differs from file {stem!r}")
        dat = self.files.get(f"{stem.upper()}.dat", b"").decode("utf-8", errors="replace")
        try:
            motions = parse_motions(src, parse_dat(dat))
        except KrlError as exc:
            raise _Refused(kp.STATUS_PROGRAM_ERROR, str(exc)) from None
        self.runs.append(stem)
        for mo in motions:
            self._krl_motion(mo)
        return kp.reply_json(kp.STATUS_OK, self._position(), program=stem)

    def _krl_motion(self, mo: KrlMotion) -> None:
        start = self.arm.q
        if mo.is_axis:
            qd = [mo.target.get(f"A{i + 1}", np.degrees(start[i])) for i in range(len(start))]
            target = np.radians(qd)
            if not self.robot.limits.contains(target):
                raise _Refused(kp.STATUS_LIMIT, f"line {mo.line}: " + ", ".join(
                    self.robot.limits.violations(target, self.robot.joint_names)))
            self._run_motion([target], 1.0, "krl")
            return

        def pose(agg: dict[str, float]) -> Array:
            cur = self._position()
            return kp.position_to_T([agg.get(k, cur[i]) for i, k in enumerate("XYZABC")])

        s = int(mo.target["S"]) if "S" in mo.target else None
        t = int(mo.target["T"]) if "T" in mo.target else None
        if mo.kind == "PTP":
            self._run_motion([self._solve(pose(mo.target), s, t, start)], 1.0, "krl")
        elif mo.kind == "LIN":
            self._run_motion(self._cartesian(line_poses(self.robot.fk(start),
                                                         pose(mo.target)), start), 1.0, "krl")
        else:
            assert mo.aux is not None
            poses = arc_poses(self.robot.fk(start), pose(mo.aux), pose(mo.target))
            self._run_motion(self._cartesian(poses, start), 1.0, "krl")


def main(argv: list[str] | None = None) -> None:
    from assistant.emulators.melfa_emulator import _parse_box
    from assistant.robots.rv2aj import RV2AJ

    ap = argparse.ArgumentParser(description="KUKA REST bridge emulator (RV-2AJ model arm)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8000)
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--hidden-box", type=_parse_box, action="append", default=[],
                    help="hidden obstacle box x,y,z,sx,sy,sz in mm (repeatable)")
    args = ap.parse_args(argv)
    emu = KukaBridgeEmulator(RV2AJ(), hidden_obstacles=args.hidden_box, host=args.host,
                             port=args.port, time_scale=args.time_scale)
    with emu:
        install_stop_handlers()
        print(f"KUKA bridge emulator on http://{args.host}:{emu.port}/krl/; Ctrl-C to stop",
              flush=True)
        wait_until_stopped()


if __name__ == "__main__":
    main()
