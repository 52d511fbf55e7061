"""The `Machine` side of the MELFA emulator: what the MELFA BASIC interpreter drives.

Joints and pose, servo, hands, override, sleeping in robot time, the data-link channels, and
the moves themselves (MOV, MVS, MVR): targets are resolved to joints with the controller's
reply codes for out-of-range or unreachable positions, then queued on the emulated arm.
`MelfaMachine` is mixed into `MelfaEmulator`, which holds the command port.
"""

from __future__ import annotations

import threading

import numpy as np

from assistant.emulators.arm import EmulatedArm, solve_wire_pose
from assistant.emulators.cartesian import arc_poses, line_poses
from assistant.emulators.melfa_program import ProgramError
from assistant.emulators.melfa_sockets import DataLinkPort
from assistant.links import melfa_protocol as mp
from assistant.links.arm_config import matches_melfa_flags
from assistant.links.melfa_protocol import MelfaPose
from assistant.robots.model import Robot

Array = np.ndarray


class MelfaMachine:
    """Mixin of `MelfaEmulator` implementing the interpreter's `Machine` protocol.

    The host supplies the attributes below.
    """

    robot: Robot
    joint_names: list[str]
    arm: EmulatedArm
    time_scale: float
    servo_on: bool
    error_code: int
    panel_ovrd: float
    hands: dict[int, bool]
    datalinks: dict[int, DataLinkPort]

    def current_q(self) -> Array:
        return self.arm.q

    def current_pose(self) -> MelfaPose:
        q = self.arm.q
        fl1, fl2 = mp.pose_flags(self.robot, q)
        return MelfaPose(self.robot.fk(q), fl1, fl2)

    def panel_override(self) -> float:
        return self.panel_ovrd

    def set_servo(self, on: bool) -> None:
        self.servo_on = on
        if not on:
            self.arm.stop_all("stopped")

    def set_hand(self, n: int, closed: bool) -> None:
        self.hands[n] = closed

    def sleep(self, robot_seconds: float, abort: threading.Event) -> None:
        abort.wait(max(0.0, robot_seconds) / self.time_scale)

    def datalink_open(self, com: int, abort: threading.Event) -> None:
        if com not in self.datalinks:
            raise ProgramError(mp.ERR_ILLEGAL_DATA, f"COM{com}: is not a data-link port")
        self.datalinks[com].wait_connection(abort)

    def datalink_readline(self, com: int, abort: threading.Event) -> str:
        return self.datalinks[com].readline(abort)

    def datalink_write(self, com: int, text: str, abort: threading.Event) -> None:
        self.datalinks[com].write(text, abort)

    def _joints_for(self, value: object, seed: Array) -> Array:
        if isinstance(value, MelfaPose):
            q, why = solve_wire_pose(
                self.robot, value.T_base_tool, seed,
                lambda s: matches_melfa_flags(self.robot, s, value.fl1, value.fl2))
            if q is None:
                raise ProgramError(mp.ERR_UNREACHABLE, why)
            return q
        if isinstance(value, float):
            raise ProgramError(mp.ERR_ILLEGAL_DATA, "a move needs a position")
        q = np.asarray(value, dtype=float)
        if not self.robot.limits.contains(q):
            raise ProgramError(mp.ERR_JOINT_RANGE, ", ".join(
                self.robot.limits.violations(q, self.joint_names)))
        return q

    def _pose_of(self, value: object, seed: Array) -> Array:
        if isinstance(value, MelfaPose):
            return value.T_base_tool
        return self.robot.fk(self._joints_for(value, seed))

    def _cartesian(self, poses: list[Array], seed: Array) -> list[Array]:
        out, q = [], seed
        for T in poses:
            q_new, why = solve_wire_pose(self.robot, T, q, lambda s: True,
                                       project_tol_rad=np.pi)
            if q_new is None or np.max(np.abs(q_new - q)) > 0.35:
                raise ProgramError(mp.ERR_UNREACHABLE, why or "configuration flip on the path")
            out.append(q_new)
            q = q_new
        return out

    def move(self, targets: list[object], kind: str, speed: float, blend: bool,
             abort: threading.Event) -> None:
        if not self.servo_on:
            raise ProgramError(mp.ERR_SERVO_OFF, "servo is off")
        if self.error_code:
            raise ProgramError(self.error_code, "controller in error")
        start = self.arm.planned_end()
        if kind == "MOV":
            waypoints = [self._joints_for(targets[0], start)]
        elif kind == "MVS":
            T0 = self.robot.fk(start)
            T1 = self._pose_of(targets[0], start)
            waypoints = self._cartesian(line_poses(T0, T1), start)
        else:
            Ta, Tb, Tc = (self._pose_of(t, start) for t in targets)
            poses = [] if np.linalg.norm(self.robot.fk(start)[:3, 3] - Ta[:3, 3]) < 1e-4 \
                else line_poses(self.robot.fk(start), Ta)
            try:
                arc = arc_poses(Ta, Tb, Tc)
            except ValueError as exc:
                raise ProgramError(mp.ERR_ILLEGAL_DATA, str(exc)) from None
            waypoints = self._cartesian(poses + arc, start)
        motion = self.arm.enqueue(np.array(waypoints), speed, kind)
        if blend:
            # CNT: the program runs on while this move executes (one move of look-ahead).
            self.arm.wait_queue_at_most(2, abort)
            if motion.outcome == "collision":
                raise ProgramError(mp.ERR_COLLISION, "collision")
            return
        outcome = self.arm.wait(motion, abort=abort)
        if outcome == "collision":
            raise ProgramError(mp.ERR_COLLISION, "collision")
        if outcome in ("dropped", "stopped") and not abort.is_set():
            raise ProgramError(mp.ERR_ILLEGAL_DATA, f"move {outcome}")
