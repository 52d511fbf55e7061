"""The cheap screen of one candidate (milliseconds): every target solved by IK within the joint
limits less the margin, collision-free there (FCL), then the straight joint move of each
transfer checked. A candidate that fails names the first failing target or transfer and why
("P7 out of reach by 42 mm"); one that passes carries its postures, the transfers whose
straight move is blocked (they need the roadmap) and an estimated TCP length to rank by.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.mission.model import ResolvedMission
from assistant.planning.locations import branch_seed
from assistant.robots.model import IKFailure, Robot
from assistant.study.problem import Leg, Target, targets_and_legs
from assistant.transforms import inv_T

Array = np.ndarray


@dataclass
class ScreenResult:
    """What the screen found for one candidate."""

    ok: bool
    reason: str = ""
    #: Per target, the chosen joint solution (empty when the screen failed).
    q: list[Array] = field(default_factory=list)
    #: Smallest distance of any chosen solution to a joint limit (rad).
    margin: float = 0.0
    #: Transfers whose straight joint move collides ("P1 -> SEAM").
    blocked: list[str] = field(default_factory=list)
    #: Estimated TCP length (m): straight joint moves + the application paths.
    estimate: float = math.inf
    seconds: float = 0.0


def screen(robot: Robot, checker: CollisionChecker, T_world_base: Array, mission: ResolvedMission,
           names: dict[str, Array], margin: float, q_seed: Array) -> ScreenResult:
    """Screen the mission with the robot at `T_world_base`; `checker` holds the candidate's
    obstacles in its base frame."""
    t0 = time.perf_counter()
    targets, legs = targets_and_legs(mission, names)
    T_bw = inv_T(np.asarray(T_world_base, dtype=float))
    lo = robot.limits.lower + margin
    hi = robot.limits.upper - margin
    prev = np.asarray(q_seed, dtype=float)
    chosen: list[Array] = []
    for tgt in targets:
        T_bt = T_bw @ tgt.T_world_tool
        q, why = _solve(robot, checker, tgt, T_bt, lo, hi, margin, prev)
        if q is None:
            return ScreenResult(False, why, seconds=time.perf_counter() - t0)
        chosen.append(q)
        prev = q
    Q = np.array(chosen)
    dist = np.minimum(Q - robot.limits.lower, robot.limits.upper - Q)
    blocked = [leg.label for leg in legs
               if checker.check_motion(chosen[leg.a], chosen[leg.b]).first_invalid_fraction
               is not None]
    est = _estimate(robot, chosen, targets, legs, T_world_base)
    return ScreenResult(True, "", chosen, float(dist.min()), blocked, est,
                        time.perf_counter() - t0)


def _solve(robot: Robot, checker: CollisionChecker, tgt: Target, T_bt: Array, lo: Array,
           hi: Array, margin: float, prev: Array) -> tuple[Array | None, str]:
    seed = branch_seed(prev, T_bt[:3, 3])
    res = robot.ik(T_bt, seed)
    if not res.ok:
        if res.failure in (IKFailure.REACH, IKFailure.NO_CONVERGENCE, None):
            short = reach_shortfall(robot, T_bt)
            if short is not None:
                return None, f"{tgt.name} out of reach by {short * 1000:.0f} mm"
            return None, f"{tgt.name} out of reach ({res.message})"
        if res.failure == IKFailure.ORIENTATION:
            return None, f"{tgt.name}: orientation not reachable ({res.message})"
        return None, f"{tgt.name}: every solution outside the joint limits ({res.message})"
    sols = np.array([np.asarray(q, dtype=float) for q in res.solutions])
    inside = np.all((sols >= lo) & (sols <= hi), axis=1)
    if not inside.any():
        worst = np.minimum(sols - (lo - margin), (hi + margin) - sols)
        best = int(np.argmax(worst.min(axis=1)))
        j = int(np.argmin(worst[best]))
        return None, (f"{tgt.name} within {math.degrees(margin):.0f} deg of a joint limit "
                      f"({robot.joint_names[j]} {math.degrees(worst[best, j]):.1f} deg from it)")
    sols = sols[inside]
    ok = checker.is_valid_batch(sols)
    if not ok.any():
        return None, f"{tgt.name} in collision: {checker.check(sols[0]).describe()}"
    sols = sols[ok]
    d = np.linalg.norm(sols - seed, axis=1)
    return sols[int(np.argmin(d))], ""


def reach_shortfall(robot: Robot, T_base_tool: Array, steps: int = 12) -> float | None:
    """How far (m) the target must move toward the robot's shoulder to be reachable (the
    same orientation), to ~1 mm; None if no point on that line is."""
    frames = robot.link_poses(np.zeros(robot.dof))
    shoulder = frames[min(2, len(frames) - 1)][:3, 3]
    p = T_base_tool[:3, 3]
    d = shoulder - p
    length = float(np.linalg.norm(d))
    if length < 1e-6:
        return None

    def reachable(t: float) -> bool:
        T = T_base_tool.copy()
        T[:3, 3] = p + d * (t / length)
        return robot.ik(T).ok

    a, b = 0.0, None
    for t in np.linspace(0.0, length, 9)[1:]:  # a reachable point on the line, nearest first
        if reachable(float(t)):
            b = float(t)
            break
        a = float(t)
    if b is None:
        return None
    for _ in range(steps):
        m = 0.5 * (a + b)
        if reachable(m):
            b = m
        else:
            a = m
    return b


def _estimate(robot: Robot, chosen: list[Array], targets: list[Target], legs: list[Leg],
              T_world_base: Array) -> float:
    """TCP length of the straight joint transfers plus the application paths' chords."""
    total = 0.0
    for leg in legs:
        f = np.linspace(0.0, 1.0, 17)[:, None]
        Q = chosen[leg.a][None] + f * (chosen[leg.b] - chosen[leg.a])[None]
        P = robot.batch_fk(Q).positions
        total += float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
    in_leg = {(leg.a, leg.b) for leg in legs}
    for i in range(len(targets) - 1):
        if (i, i + 1) not in in_leg and not any(leg.b == i + 1 for leg in legs):
            a, b = targets[i].T_world_tool[:3, 3], targets[i + 1].T_world_tool[:3, 3]
            total += float(np.linalg.norm(b - a))
    return total
