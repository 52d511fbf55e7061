"""Which of the inverse-kinematics branches a configuration is on, as controllers encode it.

A Cartesian target alone is ambiguous (arm in front of / behind J1, elbow up / down, joints
turned by +-360 deg). MELFA sends a structure flag FL1 (Right/Left, Above/Below, Non-flip/
Flip) and FL2 (multi-turn), KUKA sends Status S and Turn T. The links compute them from the
planned joints so the controller lands on the *planned* configuration - the 002 bridge left
S and T to the user and reported axis-limit stops as its most frequent failure.

The geometric features are computed from the model's link frames, so the link and our
emulators (which use the same model) agree bit for bit. A real controller defines the bits
for its own arm; for a real KUKA arm the same rules apply per its manual (S bit 0: wrist
behind A1, bit 1: elbow, bit 2: A5 sign; T bit i: axis i negative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.robots.model import Robot

Array = np.ndarray

#: Angles closer to zero than this cannot decide a turn/flip bit after wire rounding.
AMBIGUOUS_RAD = 1e-3


@dataclass(frozen=True)
class ArmConfig:
    front: bool  # wrist centre in front of the J1 axis (MELFA "R", KUKA S bit 0 clear)
    elbow_up: bool  # elbow above the shoulder-wrist line (MELFA "A", KUKA S bit 1 clear)
    wrist_flip: bool  # wrist pitch joint negative (MELFA "F", KUKA S bit 2 set)
    #: Margins: how clearly each feature is decided (near 0: numerically ambiguous).
    margins: tuple[float, float, float] = (1.0, 1.0, 1.0)


def arm_config(robot: Robot, q: Array) -> ArmConfig:
    """Branch features of `q`: front/behind J1, elbow up/down, wrist flipped."""
    q = np.asarray(q, dtype=float)
    F = robot.link_poses(q)
    n = len(F)
    turret = F[min(1, n - 1)]
    shoulder = F[min(2, n - 1)][:3, 3]
    elbow = F[min(3, n - 1)][:3, 3]
    wrist = F[min(4, n - 1)][:3, 3]
    forward = turret[:3, 0].copy()
    forward[2] = 0.0
    side = float(wrist[:2] @ forward[:2])
    axis2 = F[min(2, n - 1)][:3, 2]
    up = float(np.cross(wrist - shoulder, elbow - shoulder) @ axis2)
    pitch = float(q[robot.dof - 2]) if robot.dof >= 2 else 0.0
    return ArmConfig(side >= 0.0, up >= 0.0, pitch < 0.0, (abs(side), abs(up), abs(pitch)))


def turn_bits(q: Array) -> int:
    """KUKA Turn: bit i set when axis i is negative."""
    return int(sum(1 << i for i, v in enumerate(np.asarray(q, dtype=float)) if v < 0.0))


def status_bits(cfg: ArmConfig) -> int:
    """KUKA Status from the branch features."""
    return (0 if cfg.front else 1) | (0 if cfg.elbow_up else 2) | (4 if cfg.wrist_flip else 0)


def melfa_fl1(cfg: ArmConfig) -> int:
    """MELFA FL1: bit 2 Right(1)/Left(0), bit 1 Above(1)/Below(0), bit 0 Non-flip(1)/Flip(0)."""
    return (4 if cfg.front else 0) | (2 if cfg.elbow_up else 0) | (0 if cfg.wrist_flip else 1)


def melfa_fl2(q: Array) -> int:
    """MELFA FL2 as used here: the number of full turns of the last joint (0 within +-180)."""
    return int(np.floor((float(np.asarray(q)[-1]) + np.pi) / (2.0 * np.pi)))


def matches_status_turn(robot: Robot, q: Array, s: int | None, t: int | None) -> bool:
    """True when q agrees with S/T on every bit that q decides unambiguously."""
    q = np.asarray(q, dtype=float)
    if s is not None:
        cfg = arm_config(robot, q)
        mine = status_bits(cfg)
        for bit, margin in zip((1, 2, 4), cfg.margins, strict=True):
            if margin > 1e-6 and (mine & bit) != (s & bit):
                if bit == 4 and cfg.margins[2] < AMBIGUOUS_RAD:
                    continue
                return False
    if t is not None:
        for i, v in enumerate(q):
            if abs(v) > AMBIGUOUS_RAD and bool(t & (1 << i)) != (v < 0.0):
                return False
    return True


def matches_melfa_flags(robot: Robot, q: Array, fl1: int | None, fl2: int | None) -> bool:
    """True when q agrees with FL1/FL2 on every feature it decides unambiguously."""
    q = np.asarray(q, dtype=float)
    if fl1 is not None:
        cfg = arm_config(robot, q)
        mine = melfa_fl1(cfg)
        for bit, margin in zip((4, 2, 1), cfg.margins, strict=True):
            if (mine & bit) != (fl1 & bit):
                if bit == 1 and margin < AMBIGUOUS_RAD:
                    continue
                if margin > 1e-6:
                    return False
    if fl2 is not None:
        v = float(q[-1])
        # Near +-180 deg the turn count is ambiguous after rounding.
        if abs(abs(v) - np.pi) > AMBIGUOUS_RAD and melfa_fl2(q) != fl2:
            return False
    return True
