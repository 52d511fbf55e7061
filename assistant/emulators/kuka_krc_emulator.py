"""A KUKA KR C4 running the bridge's own KRL program, with the shipped bridge server in front:
the whole controller side of the KUKA link, on localhost, on a KR 6 R900 sixx model.

The REST server is `kuka_bridge.bridge_server` itself; it writes commands into a channel
folder. The emulated controller runs `kuka_bridge/cellbridge.src` (+ .dat) in `krl_interp`
against the arm: the program reads those files with ``CWRITE($FCT_CALL, ...)``, moves with
PTP/LIN/CIRC and writes its answers - so the test drives the very KRL a user copies to the
controller. The robot's own kinematics are the URDF's KUKA ``$FLANGE`` (the ``flange``
link) with ``$TOOL`` on it; ``INVERSE`` solves with the S/T bits and ignores the software
limit switches (the program checks ``$SOFTN_END``/``$SOFTP_END`` itself, as on a KR C4);
a motion that hits a hidden obstacle or a limit halts the program with a message, as the
controller does (the bridge then answers statuscode -5 after its timeout), and
`acknowledge()` restarts it like an operator would.

    python -m assistant.emulators.kuka_krc_emulator --port 8000
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from assistant.collision.reports import ObstacleView
from assistant.emulators.arm import EmulatedArm, solve_wire_pose
from assistant.emulators.cartesian import arc_poses, line_poses
from assistant.emulators.krl_interp import Interpreter, KrlError, KrlHalt, T_frame, frame_T
from assistant.links.arm_config import arm_config, matches_status_turn, status_bits, turn_bits
from assistant.links.kuka_bridge import bridge_server
from assistant.links.kuka_bridge import files as bridge_files
from assistant.robots.model import Robot
from assistant.transforms import inv_T

Array = np.ndarray
ARM = "kuka_kr6_r900_sixx"


def kuka_arm(tool_link: str = "tool0") -> Robot:
    """The catalogue's KR 6 R900 sixx with the given flange link."""
    from assistant.robots.catalog import CATALOG, catalog_path
    from assistant.robots.urdf_robot import URDFRobot

    return URDFRobot.from_file(catalog_path(ARM), base_link=CATALOG[ARM].base_link,
                               tool_link=tool_link, load_visual=False)


class KrcMachine:
    """What the KRL program sees of the controller: system variables, motions, files."""

    def __init__(self, arm: EmulatedArm, flange_robot: Robot, channel: Path,
                 time_scale: float, stop: threading.Event):
        self.arm, self.robot, self.channel = arm, flange_robot, channel
        self.time_scale = time_scale
        self._stop = stop
        lo, hi = flange_robot.limits.lower, flange_robot.limits.upper
        self._wide = flange_robot.with_limits(np.column_stack([lo - 2 * np.pi, hi + 2 * np.pi]))
        self.vars: dict[str, Any] = {"$TOOL": _null(), "$BASE": _null(), "$OV_PRO": 100.0}
        self._files: dict[int, Any] = {}
        self._handles = iter(range(1, 1 << 30))

    # ------------------------------------------------------------------ variables
    def sysvar(self, name: str) -> Any:
        if name == "$POS_ACT":
            q = self.arm.q
            T = self.robot.fk(q) @ frame_T(self.vars["$TOOL"])
            return {**T_frame(T), "S": float(status_bits(arm_config(self.robot, q))),
                    "T": float(turn_bits(q))}
        if name == "$AXIS_ACT":
            return {f"A{i + 1}": float(np.degrees(v)) for i, v in enumerate(self.arm.q)}
        if name == "$SOFTN_END":
            return [float(v) for v in np.degrees(self.robot.limits.lower)]
        if name == "$SOFTP_END":
            return [float(v) for v in np.degrees(self.robot.limits.upper)]
        if name == "$NULLFRAME":
            return _null()
        if name == "$FCT_CALL":
            return "$FCT_CALL"
        if name in self.vars:
            return self.vars[name]
        raise KrlError(f"system variable {name} is not emulated")

    def set_sysvar(self, name: str, value: Any) -> None:
        if name not in ("$TOOL", "$BASE", "$OV_PRO"):
            raise KrlError(f"{name} cannot be written here")
        self.vars[name] = value

    def compose(self, a: dict, b: dict) -> dict:
        return T_frame(frame_T(a) @ frame_T(b))

    # ------------------------------------------------------------------ kinematics
    def _flange_T(self, pos: dict) -> Array:
        return frame_T(pos) @ inv_T(frame_T(self.vars["$TOOL"]))

    def inverse(self, pos: dict, start: dict) -> tuple[dict, int]:
        s = int(pos["S"]) if "S" in pos else None
        t = int(pos["T"]) if "T" in pos else None
        seed = np.radians([float(start.get(f"A{i + 1}", 0.0)) for i in range(self.robot.dof)])
        q, _ = solve_wire_pose(self._wide, self._flange_T(pos), seed,
                               lambda c: matches_status_turn(self._wide, c, s, t))
        if q is None:
            return {f"A{i + 1}": 0.0 for i in range(6)}, 1
        return {f"A{i + 1}": float(np.degrees(v)) for i, v in enumerate(q)}, 0

    def motion(self, kind: str, targets: list[dict], line: int) -> None:
        start = self.arm.q
        speed = float(np.clip(self.vars["$OV_PRO"] / 100.0, 0.01, 1.0))
        tgt = targets[-1]
        if kind == "PTP":
            if "A1" in tgt:
                q = np.radians([float(tgt.get(f"A{i + 1}", np.degrees(start[i])))
                                for i in range(self.robot.dof)])
            else:
                axes, err = self.inverse(tgt, self.sysvar("$AXIS_ACT"))
                if err:
                    raise KrlHalt(f"line {line}: KSS01422 target not reachable")
                q = np.radians([axes[f"A{i + 1}"] for i in range(self.robot.dof)])
            self._limits(q, line)
            self._run([q], speed, line)
            return
        T0 = self.robot.fk(start)
        poses = line_poses(T0, self._flange_T(tgt)) if kind == "LIN" else \
            arc_poses(T0, self._flange_T(targets[0]), self._flange_T(tgt))
        out, q = [], start
        for T in poses:
            qn, why = solve_wire_pose(self.robot, T, q, lambda c: True, project_tol_rad=np.pi)
            if qn is None or np.max(np.abs(qn - q)) > 0.35:
                raise KrlHalt(f"line {line}: KSS01441 {kind} path not possible ({why or 'flip'})")
            out.append(qn)
            q = qn
        self._run(out, speed, line)

    def _limits(self, q: Array, line: int) -> None:
        if not self.robot.limits.contains(q):
            bad = ", ".join(self.robot.limits.violations(q, self.robot.joint_names))
            raise KrlHalt(f"line {line}: KSS01806 software limit switch ({bad})")

    def _run(self, waypoints: list[Array], speed: float, line: int) -> None:
        m = self.arm.enqueue(np.array(waypoints), speed, f"krl:{line}")
        outcome = self.arm.wait(m)
        if outcome == "collision":
            info = self.arm.last_collision
            raise KrlHalt(f"line {line}: KSS00203 collision detection "
                          f"({info.description if info else 'contact'})")
        if outcome != "reached":
            raise KrlHalt(f"line {line}: motion {outcome}")

    # ------------------------------------------------------------------ files
    def file_call(self, fn: str, args: list, out: Callable[[int, Any], None]) -> str:
        fn = fn.lower()
        if fn == "krl_fopen":
            name, mode = str(args[0]), str(args[1])
            try:
                f = open(self.channel / Path(name).name,  # noqa: SIM115 (KRL holds it)
                         mode[:1] if mode[:1] in "rwa" else "r",
                         encoding="ascii", errors="replace")
            except OSError:
                return "#CMD_ABORT"
            h = next(self._handles)
            self._files[h] = f
            out(2, h)
            return "#CMD_OK"
        f = self._files.get(int(args[0])) if args else None
        if f is None:
            return "#CMD_ABORT"
        if fn == "krl_fgets":
            text = f.readline(int(args[2])).rstrip("\r\n")
            out(1, text)
            out(3, len(text))
            return "#CMD_OK"
        if fn == "krl_fputs":
            f.write(str(args[1]) + "\n")
            return "#CMD_OK"
        if fn == "krl_fclose":
            f.close()
            del self._files[int(args[0])]
            return "#CMD_OK"
        raise KrlError(f"{fn} is not emulated")

    def close_files(self) -> None:
        for f in self._files.values():
            with contextlib.suppress(OSError):
                f.close()
        self._files.clear()

    def wait(self, seconds: float) -> None:
        if self._stop.wait(seconds / self.time_scale):
            raise KrlHalt("stopped")


def _null() -> dict:
    return {k: 0.0 for k in "XYZABC"}


class KukaKrcEmulator:
    """The bridge server plus a KR C4 running cellbridge on a KR 6 R900 sixx model.

    Args:
        robot: the arm with its tool link ``tool0`` (collisions; default: the catalogue's).
        hidden_obstacles: obstacles only the emulator knows; touching one halts the program.
        port: the bridge's HTTP port (0 = any free port).
        bridge_timeout_s: how long the bridge waits for the robot program's answer.
    """

    def __init__(self, robot: Robot | None = None, *,
                 hidden_obstacles: Iterable[ObstacleView] = (), host: str = "127.0.0.1",
                 port: int = 0, time_scale: float = 1.0, tick_s: float = 0.012,
                 start_q: Array | None = None, bridge_timeout_s: float = 120.0,
                 channel_dir: Path | None = None, src: str | None = None,
                 dat: str | None = None):
        self.robot = robot or kuka_arm("tool0")
        self.flange_robot = kuka_arm("flange")
        self.host = host
        q0 = np.radians([0.0, -90.0, 90.0, 0.0, 45.0, 0.0]) if start_q is None else start_q
        self.arm = EmulatedArm(self.robot, hidden_obstacles=hidden_obstacles,
                               time_scale=time_scale, tick_s=tick_s, start_q=q0)
        self._tmp = None
        if channel_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="krc-")
            channel_dir = Path(self._tmp.name)
        self.channel = Path(channel_dir)
        paths = bridge_files()
        self.src = src if src is not None else paths["cellbridge.src"].read_text()
        self.dat = dat if dat is not None else paths["cellbridge.dat"].read_text()
        self.bridge = bridge_server.Bridge(str(self.channel), bridge_timeout_s, poll_s=0.005)
        self._server = bridge_server.make_server(host, port, self.bridge)
        self._stop = threading.Event()
        self.time_scale = time_scale
        self.messages: list[str] = []
        self.machine: KrcMachine | None = None
        self._interp: Interpreter | None = None
        self._threads: list[threading.Thread] = []
        self.program_running = threading.Event()

    @property
    def port(self) -> int:
        return self._server.server_address[1]

    def start(self) -> KukaKrcEmulator:
        self.arm.start()
        th = threading.Thread(target=self._server.serve_forever,
                              kwargs={"poll_interval": 0.05}, daemon=True, name="kuka-bridge")
        th.start()
        self._threads.append(th)
        self.acknowledge()
        return self

    def acknowledge(self) -> None:
        """The operator acknowledges the message and starts cellbridge again."""
        if self.program_running.is_set():
            return
        self.arm.clear_fault()
        self.machine = KrcMachine(self.arm, self.flange_robot, self.channel, self.time_scale,
                                  self._stop)
        self._interp = Interpreter(self.src, self.dat, self.machine)  # refuses bad KRL
        self.program_running.set()
        th = threading.Thread(target=self._run, args=(self._interp, self.machine), daemon=True,
                              name="krc-cellbridge")
        th.start()
        self._threads.append(th)

    def _run(self, interp: Interpreter, machine: KrcMachine) -> None:
        try:
            interp.run()
        except KrlHalt as exc:
            if not self._stop.is_set():
                self.messages.append(str(exc))
        except (KrlError, KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
            self.messages.append(f"line {interp.line}: {type(exc).__name__}: {exc}")
        finally:
            machine.close_files()
            self.program_running.clear()

    def wait_halted(self, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while self.program_running.is_set() and time.monotonic() < deadline:
            time.sleep(0.01)
        return not self.program_running.is_set()

    def close(self) -> None:
        self._stop.set()
        if self._interp is not None:
            self._interp.stop()
        self.arm.close()
        self._server.shutdown()
        self._server.server_close()
        for th in self._threads:
            th.join(timeout=3.0)
        if self._tmp is not None:
            self._tmp.cleanup()

    def __enter__(self) -> KukaKrcEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()


def main(argv: list[str] | None = None) -> None:
    from assistant.emulators.until_stopped import install_stop_handlers, wait_until_stopped

    ap = argparse.ArgumentParser(description="KUKA KR C4 with the cellteach bridge "
                                 "(KR 6 R900 sixx model)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8000)
    ap.add_argument("--time-scale", type=float, default=1.0)
    args = ap.parse_args(argv)
    with KukaKrcEmulator(host=args.host, port=args.port, time_scale=args.time_scale) as emu:
        install_stop_handlers()
        print(f"KUKA bridge + KR C4 emulator on http://{args.host}:{emu.port}/krl/; "
              "Ctrl-C to stop", flush=True)
        wait_until_stopped()


if __name__ == "__main__":
    main()
