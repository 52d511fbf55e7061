"""Runs one compiled URScript program on the UR emulator's arm, on its own thread.

Joint moves go straight in joint space at the leading joint's speed ``v`` (a fraction of the
model's joint speed limits); Cartesian moves (``movel``, ``movec`` mode 0) are cut into 2 mm
poses, each solved by a local damped Newton step from the previous joints (the controller
tracks the TCP the same way: no jumps between IK branches), timed so the TCP keeps ``v``
where the joint limits allow. Blend radii run as exact stops; a time ``t`` > 0 is refused.
A failure is a `ScriptError`, sent to the clients as a runtime exception; the arm stops.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from assistant.emulators.cartesian import arc_poses, line_poses
from assistant.emulators.ur_script_interp import (
    Pose,
    Program,
    ScriptError,
    Statement,
    evaluate,
)
from assistant.links.timing import time_parametrize
from assistant.links.ur_primary import runtime_exception
from assistant.links.ur_script import from_controller_pose
from assistant.robots.model import Robot

if TYPE_CHECKING:
    from assistant.emulators.ur_emulator import UREmulator

Array = np.ndarray
MAX_JOINT_STEP = 0.35  # rad between 2 mm poses: more is a flip through a singularity


def track_pose(robot: Robot, T: Array, q0: Array, iters: int = 30) -> Array | None:
    """Joints near q0 putting the TCP at T (damped Newton, numerical Jacobian), or None."""
    q = np.asarray(q0, dtype=float).copy()
    for _ in range(iters):
        F = robot.fk(q)
        err = np.concatenate([T[:3, 3] - F[:3, 3],
                              Rotation.from_matrix(T[:3, :3] @ F[:3, :3].T).as_rotvec()])
        if np.linalg.norm(err[:3]) < 1e-9 and np.linalg.norm(err[3:]) < 1e-8:
            return q
        J = np.empty((6, len(q)))
        h = 1e-7
        for j in range(len(q)):
            dq = q.copy()
            dq[j] += h
            Fj = robot.fk(dq)
            J[:3, j] = (Fj[:3, 3] - F[:3, 3]) / h
            J[3:, j] = Rotation.from_matrix(Fj[:3, :3] @ F[:3, :3].T).as_rotvec() / h
        lam = 1e-4
        q = q + J.T @ np.linalg.solve(J @ J.T + lam * lam * np.eye(6), err)
    return None


class ScriptRunner:
    """One program at a time; `run` replaces the running one, `abort` ends it."""

    def __init__(self, emu: UREmulator):
        self.emu = emu
        self._thread: threading.Thread | None = None
        self._abort = threading.Event()
        self.current = ""
        self._tools: dict[bytes, Robot] = {}

    @property
    def running(self) -> bool:
        th = self._thread
        return th is not None and th.is_alive()

    def abort(self) -> None:
        self._abort.set()
        self.emu.arm.stop_all("stopped")
        th = self._thread
        if th is not None and th is not threading.current_thread():
            th.join(timeout=5.0)

    def run(self, prog: Program) -> None:
        self.abort()
        self._abort = threading.Event()
        self.current = prog.name
        self.emu.programs_run.append(prog.name)
        self._thread = threading.Thread(target=self._main, args=(prog, self._abort),
                                        name=f"ur-program-{prog.name}", daemon=True)
        self._thread.start()

    def _main(self, prog: Program, abort: threading.Event) -> None:
        env: dict = {}
        try:
            for st in prog.body:
                if abort.is_set():
                    return
                self._exec(st, env, abort)
        except ScriptError as exc:
            self.emu.arm.stop_all("stopped")
            self.emu.broadcast(runtime_exception(str(exc), exc.line, exc.column), str(exc))
        finally:
            self.emu.set_tcp(None)

    # ------------------------------------------------------------------ statements
    def _value(self, st: Statement, name: str, env: dict, default: object = None) -> object:
        if name not in st.args:
            return default
        return evaluate(st.args[name], env, self._pose_trans)

    @staticmethod
    def _pose_trans(a: object, b: object) -> Pose:
        Ta, Tb = _pose_T(a), _pose_T(b)
        T = Ta @ Tb
        return Pose(list(T[:3, 3]) + list(Rotation.from_matrix(T[:3, :3]).as_rotvec()))

    def _exec(self, st: Statement, env: dict, abort: threading.Event) -> None:
        emu, n = self.emu, st.line
        if st.call == "=":
            env[st.target] = self._value(st, "value", env)
            return
        v = {name: self._value(st, name, env, d) for name, d in _params(st.call)}
        if st.call == "write_output_integer_register":
            addr = int(v["address"])
            if not 0 <= addr < 48:
                raise ScriptError(f"write_output_integer_register: address {addr} not in "
                                  "0-47", n)
            with emu._lock:
                emu.int_registers[addr] = int(v["value"])
        elif st.call == "set_tcp":
            emu.set_tcp(_pose_T(v["pose"], n))
        elif st.call in ("set_tool_digital_out", "set_standard_digital_out", "set_digital_out"):
            emu.digital_outputs[f"{st.call}[{int(v['n'])}]"] = bool(v["b"])
        elif st.call == "sleep":
            abort.wait(max(0.0, float(v["t"])) / emu.time_scale)
        elif st.call == "textmsg":
            emu.messages.append(f"{v['s1']}{v['s2']}")
        elif st.call in ("stopj", "stopl"):
            emu.arm.stop_all("stopped")
        elif st.call == "sync":
            abort.wait(0.002)
        elif st.call == "movej":
            self._movej(v, n, abort)
        else:
            self._cartesian(st.call, v, n, abort)

    def _movej(self, v: dict, n: int, abort: threading.Event) -> None:
        emu, robot = self.emu, self.emu.robot
        if float(v["t"]) > 0.0:
            raise ScriptError("movej: a time t > 0 is not emulated", n)
        target = v["q"]
        q0 = emu.arm.q
        if isinstance(target, Pose):
            res = robot.ik(from_controller_pose(robot, target), q0)
            if not res.ok:
                raise ScriptError(f"movej: inverse kinematics failed ({res.message})", n)
            q = res.best(q0)
        else:
            q = np.asarray(target, dtype=float)
        if q.shape != (robot.dof,):
            raise ScriptError(f"movej: {robot.dof} joint values needed, got {q.size}", n)
        if not robot.limits.contains(q):
            raise ScriptError("movej: target outside the joint limits ("
                              + ", ".join(robot.limits.violations(q, robot.joint_names)) + ")",
                              n)
        frac = float(v["v"]) / float(np.min(robot.limits.velocity))
        self._move(np.array([q]), frac, abort)

    def _cartesian(self, call: str, v: dict, n: int, abort: threading.Event) -> None:
        emu, robot = self.emu, self.emu.robot
        q0 = emu.arm.q
        T0 = robot.fk(q0)
        if call == "movel":
            poses = line_poses(T0, self._target(v["pose"], n))
        else:
            if int(v["mode"]) != 0:
                raise ScriptError("movec: only mode=0 (unconstrained orientation) is emulated",
                                  n)
            try:
                poses = arc_poses(T0, self._target(v["pose_via"], n),
                                  self._target(v["pose_to"], n))
            except ValueError as exc:
                raise ScriptError(f"movec: {exc}", n) from None
        qs, q = [], q0
        for T in poses:
            qn = track_pose(robot, T, q)
            if qn is None or np.max(np.abs(qn - q)) > MAX_JOINT_STEP:
                raise ScriptError(f"{call}: inverse kinematics failed on the way (pose "
                                  f"{np.round(T[:3, 3], 4).tolist()} m)", n)
            if not robot.limits.contains(qn):
                raise ScriptError(f"{call}: the path leaves the joint limits", n)
            qs.append(qn)
            q = qn
        path = np.vstack([q0[None], qs])
        full = time_parametrize(path, robot.limits.velocity).duration
        length = sum(float(np.linalg.norm(b[:3, 3] - a[:3, 3]))
                     for a, b in zip([T0] + poses[:-1], poses, strict=True))
        wanted = length / max(float(v["v"]), 1e-6)
        self._move(np.array(qs), full / wanted if wanted > 0 else 1.0, abort)

    def _target(self, value: object, n: int) -> Array:
        if isinstance(value, Pose):
            return from_controller_pose(self.emu.base_robot, value)
        q = np.asarray(value, dtype=float)
        if q.shape != (self.emu.robot.dof,):
            raise ScriptError("a pose p[...] or a joint vector is needed", n)
        return self.emu.robot.fk(q)

    def _move(self, waypoints: Array, frac: float, abort: threading.Event) -> None:
        m = self.emu.arm.enqueue(waypoints, float(np.clip(frac, 1e-3, 1.0)), "ur")
        while not abort.is_set():
            outcome = self.emu.arm.wait(m, timeout=0.05, abort=abort)
            if outcome:
                if outcome != "reached":
                    abort.set()  # protective stop / drop / stopj: the program ends
                return


def _params(call: str):  # noqa: ANN202
    from assistant.emulators.ur_script_interp import SIGNATURES

    return SIGNATURES[call]


def _pose_T(value: object, n: int = 0) -> Array:
    if not isinstance(value, Pose) or len(value) != 6:
        raise ScriptError("a pose p[x, y, z, rx, ry, rz] is needed", n)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.asarray(value[3:], dtype=float)).as_matrix()
    T[:3, 3] = value[:3]
    return T
