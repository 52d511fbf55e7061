"""The TCP path a controller would drive for a neutral program, through the robot's kinematics.

Joint moves interpolate joints linearly; linear moves interpolate the TCP position on a line
and the orientation by slerp; circular moves follow the circle through start, via and end;
spline moves follow a centripetal Catmull-Rom curve through their points (the vendors' spline
interpolators are proprietary; this is the usual stand-in). Cartesian samples are solved by IK
seeded with the previous sample, so a path that leaves the workspace, breaks a joint limit or
jumps branch (a singularity) is found here and reported with its step.

A 7-axis arm's controller holds its redundant joint (`redundant_axis`: RAPID eax_a, KRL E1)
at the value the target carries and interpolates it linearly along a Cartesian path; so do
targets and path samples here (`redundant_axis.solve_pinned`), which makes the posture at
each target the planned one instead of wherever a seeded IK drifts in the null space.

Blending (CNT, C_DIS, zones) is not simulated: the path runs through every target, which is
what the planner's primitives describe; blending only cuts corners within the blend radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from assistant.export.configuration import ArmConfig
from assistant.export.errors import ExportError
from assistant.export.program import Move, MoveKind, NeutralProgram, Position
from assistant.export.redundant_axis import REDUNDANT_JOINT, solve_pinned
from assistant.robots.model import IKFailure, Robot
from assistant.transforms import rotation_angle

Array = np.ndarray

#: A 5-axis arm cannot hold an orientation that rounding pushed off its arm plane; the
#: projection back may turn the tool by at most this much (rad) before we call it an error.
ORIENTATION_SNAP = np.radians(0.05)


@dataclass(frozen=True)
class SimulatedMove:
    index: int
    step: str
    kind: MoveKind
    tcp: Array  # (N, 3) metres, base frame
    q: Array  # (N, dof)


@dataclass(frozen=True)
class Simulation:
    moves: list[SimulatedMove]
    #: Targets whose configuration flags matched no IK solution (the nearest was used).
    config_mismatches: tuple[str, ...] = ()

    def tcp_points(self) -> Array:
        return np.concatenate([m.tcp for m in self.moves]) if self.moves else np.zeros((0, 3))

    def sample_counts(self) -> list[int]:
        return [len(m.tcp) for m in self.moves]


def simulate(program: NeutralProgram, robot: Robot, q_start: Array | None = None, *,
             max_step: float = 0.002, samples: list[int] | None = None) -> Simulation:
    """Dense TCP path of every move.

    Args:
        program: the program (targets in the base frame).
        robot: kinematics used for FK/IK.
        q_start: where the robot stands before the first move (default `program.q_start`,
            else the first target's solution).
        max_step: largest TCP step between samples (m).
        samples: per move sample counts to use instead (to compare two simulations point by
            point).
    Raises:
        ExportError naming the step when a target or a path sample has no IK solution.
    """
    moves = program.moves()
    if samples is not None and len(samples) != len(moves):
        raise ExportError(f"cannot compare: {len(samples)} moves planned, {len(moves)} read")
    q = q_start if q_start is not None else program.q_start
    mismatches: list[str] = []
    if q is None:
        if not moves:
            return Simulation([])
        q = _solve_target(robot, moves[0].target, None, moves[0].step, mismatches)
    q = np.asarray(q, dtype=float)
    out: list[SimulatedMove] = []
    for k, m in enumerate(moves):
        n = None if samples is None else samples[k]
        qs = _simulate_move(robot, m, q, max_step, n, mismatches)
        out.append(SimulatedMove(k, m.step, m.kind, tcp_points(robot, qs), qs))
        q = qs[-1]
    return Simulation(out, tuple(mismatches))


def max_deviation(a: Simulation, b: Simulation) -> float:
    """Largest pointwise TCP distance (m) between two simulations with equal sample counts."""
    if a.sample_counts() != b.sample_counts():
        raise ValueError("simulations differ in structure; compare with samples=")
    if not a.moves:
        return 0.0
    return float(np.max(np.linalg.norm(a.tcp_points() - b.tcp_points(), axis=1)))


# ---------------------------------------------------------------------------- targets
def target_pose(robot: Robot, p: Position) -> Array:
    if p.T_base_tool is not None:
        return np.asarray(p.T_base_tool, dtype=float)
    if p.q is None:
        raise ExportError(f"position {p.name!r} has neither a pose nor joints")
    return robot.fk(p.q)


def _solve_target(robot: Robot, p: Position, seed: Array | None, step: str,
                  mismatches: list[str]) -> Array:
    if p.q is not None:
        return np.asarray(p.q, dtype=float)
    T = target_pose(robot, p)
    cfg: ArmConfig | None = p.config
    if cfg is not None and cfg.redundant is not None:
        sols = _pinned_target(robot, T, cfg.redundant, seed, step, p.name)
    else:
        sols = _ik_all(robot, T, seed, step, p.name)
    if cfg is not None:
        ok = [s for s in sols if cfg.matches(robot, s, tol=1e-4)]
        if ok:
            sols = ok
        else:
            mismatches.append(p.name)
    if seed is None:
        return sols[0]
    return min(sols, key=lambda s: float(np.linalg.norm(s - seed)))


def _ik_all(robot: Robot, T: Array, seed: Array | None, step: str, what: str, *,
            on_path: bool = False) -> list[Array]:
    """IK solutions; a 5-axis arm's orientation is projected into its reach.

    Targets may be turned by rounding only (`ORIENTATION_SNAP`). Between targets a 5-axis
    arm cannot follow a slerp that leaves its arm plane; like its controller it keeps the
    TCP on the path and turns the tool as little as needed (`on_path`).
    """
    res = robot.ik(T, seed)
    if not res.ok and res.failure == IKFailure.ORIENTATION and res.nearest_T_base_tool is not None:
        near = res.nearest_T_base_tool
        turn = _angle(near[:3, :3], T[:3, :3])
        limit = np.pi if on_path and robot.dof < 6 else ORIENTATION_SNAP
        if np.linalg.norm(near[:3, 3] - T[:3, 3]) < 1e-7 and turn <= limit:
            res = robot.ik(near, seed)
    if not res.ok:
        raise ExportError(f"{what}: {res.message}", step=step)
    return res.solutions


def _pinned_target(robot: Robot, T: Array, pin: tuple[int, float], seed: Array | None,
                   step: str, what: str) -> list[Array]:
    """Solutions with the redundant joint held, from the seed and from each IK branch."""
    joint, value = pin
    res = robot.ik(T, seed)
    seeds = ([] if seed is None else [seed]) + list(res.solutions)
    sols = solve_pinned(robot, T, joint, value, seeds)
    if not sols:
        raise ExportError(f"{what}: no joint solution with joint {joint + 1} at "
                          f"{np.degrees(value):.3f} deg reaches this pose", step=step)
    return sols


def _pinned_value(robot: Robot, m: Move) -> float | None:
    """The redundant joint's value at a Cartesian move's target (None: not a 7-axis arm, or
    a target that does not say)."""
    if robot.dof != 7:
        return None
    if m.target.q is not None:
        return float(m.target.q[REDUNDANT_JOINT])
    cfg = m.target.config
    return None if cfg is None or cfg.redundant is None else cfg.redundant[1]


def _angle(Ra: Array, Rb: Array) -> float:
    return rotation_angle(Ra.T @ Rb)


# ---------------------------------------------------------------------------- moves
def _simulate_move(robot: Robot, m: Move, q0: Array, max_step: float, n: int | None,
                   mismatches: list[str]) -> Array:
    if m.kind == MoveKind.JOINT:
        q1 = _solve_target(robot, m.target, q0, m.step, mismatches)
        if n is None:
            radii = robot.arm_radii()
            n = int(np.ceil(float(np.abs(q1 - q0) @ radii) / max_step)) + 1
        s = np.linspace(0.0, 1.0, max(n, 2))[:, None]
        return q0 + s * (q1 - q0)
    T0 = robot.fk(q0)
    poses = _cartesian_poses(robot, m, T0, max_step, n)
    qs = [q0]
    radii = robot.arm_radii()
    held = _pinned_value(robot, m)
    for i, T in enumerate(poses[1:], start=1):
        where = f"{m.kind.value} path at {100.0 * i / (len(poses) - 1):.0f}%"
        if held is not None:
            s = i / (len(poses) - 1)
            value = (1.0 - s) * q0[REDUNDANT_JOINT] + s * held
            sols = solve_pinned(robot, T, REDUNDANT_JOINT, value, [qs[-1]])
            if not sols:
                raise ExportError(f"{where}: no joint solution with joint "
                                  f"{REDUNDANT_JOINT + 1} at {np.degrees(value):.3f} deg",
                                  step=m.step)
        else:
            sols = _ik_all(robot, T, qs[-1], m.step, where, on_path=i < len(poses) - 1)
        q = min(sols, key=lambda s: float(np.linalg.norm(s - qs[-1])))
        chord = float(np.linalg.norm(T[:3, 3] - poses[i - 1][:3, 3]))
        sweep = float(np.abs(q - qs[-1]) @ radii)
        if sweep > 20.0 * max(chord, max_step) + 0.02:
            raise ExportError(f"the {m.kind.value} path to {m.target.name!r} passes a "
                              f"singularity or changes arm configuration near "
                              f"{100.0 * i / (len(poses) - 1):.0f}% (joints jump)", step=m.step)
        qs.append(q)
    q_end = qs[-1]
    # The planned solution for the target must be the one the path arrives in.
    if (m.target.q is not None and m.target.config is None
            and float(np.abs(q_end - m.target.q) @ radii) > 1e-3):
            raise ExportError(f"the {m.kind.value} path arrives at {m.target.name!r} in another "
                              "arm configuration than planned", step=m.step)
    return np.array(qs)


def _cartesian_poses(robot: Robot, m: Move, T0: Array, max_step: float,
                     n: int | None) -> list[Array]:
    T1 = target_pose(robot, m.target)
    if m.kind == MoveKind.LINEAR:
        pts_fn = _line(T0[:3, 3], T1[:3, 3])
        keys = [T0, T1]
    elif m.kind == MoveKind.CIRCULAR:
        if m.via is None:
            raise ExportError("a circular move needs a via point", step=m.step)
        Tv = target_pose(robot, m.via)
        pts_fn = circle_through(T0[:3, 3], Tv[:3, 3], T1[:3, 3], step=m.step)
        keys = [T0, T1]
    elif m.kind == MoveKind.SPLINE:
        Ts = [T0] + [target_pose(robot, p) for p in m.through] + [T1]
        pts_fn = _catmull_rom([T[:3, 3] for T in Ts])
        keys = Ts
    else:  # pragma: no cover - joint handled by the caller
        raise AssertionError(m.kind)
    length = pts_fn.length
    if n is None:
        n = int(np.ceil(length / max_step)) + 1
    s = np.linspace(0.0, 1.0, max(n, 2))
    pts = pts_fn(s)
    rots = _orientation_track(keys, pts_fn.key_params)(s)
    out = []
    for p, R in zip(pts, rots, strict=True):
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = p
        out.append(T)
    return out


class _Curve:
    """A path parametrised by s in [0, 1] with its length and the parameters of its keys."""

    def __init__(self, fn, length: float, key_params: list[float]):
        self.fn = fn
        self.length = length
        self.key_params = key_params

    def __call__(self, s: Array) -> Array:
        return self.fn(np.asarray(s, dtype=float))


def _line(a: Array, b: Array) -> _Curve:
    return _Curve(lambda s: a + s[:, None] * (b - a), float(np.linalg.norm(b - a)), [0.0, 1.0])


def circle_through(p0: Array, pv: Array, p1: Array, *, step: str = "") -> _Curve:
    """The arc from p0 through pv to p1 (parametrised by angle)."""
    a, b = pv - p0, p1 - p0
    n = np.cross(a, b)
    nn = float(np.linalg.norm(n))
    scale = max(float(np.linalg.norm(a)), float(np.linalg.norm(b)), 1e-12)
    if nn < 1e-9 * scale * scale or np.linalg.norm(a) < 1e-9 or np.linalg.norm(b - a) < 1e-9:
        raise ExportError("the arc's start, via and end points are (nearly) on one line or "
                          "coincide", step=step)
    # Circumcentre of the triangle.
    c = p0 + (np.cross(n, a) * (b @ b) + np.cross(b, n) * (a @ a)) / (2.0 * nn * nn)
    r = float(np.linalg.norm(p0 - c))
    u = (p0 - c) / r
    nz = n / nn
    v = np.cross(nz, u)

    def ang(p):
        d = p - c
        return float(np.arctan2(d @ v, d @ u)) % (2.0 * np.pi)

    total = ang(p1)
    via = ang(pv)
    if via > total:  # cannot happen with n = a x b, kept for numerical safety
        total += 2.0 * np.pi

    def fn(s: Array) -> Array:
        t = s * total
        return c + r * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)

    return _Curve(fn, r * total, [0.0, 1.0])


def _catmull_rom(points: list[Array]) -> _Curve:
    """Centripetal Catmull-Rom through the points (end tangents by reflection)."""
    P = np.asarray(points, dtype=float)
    if len(P) == 2:
        return _line(P[0], P[1])
    ext = np.vstack([2 * P[0] - P[1], P, 2 * P[-1] - P[-2]])
    d = np.linalg.norm(np.diff(ext, axis=0), axis=1)
    knots = np.r_[0.0, np.cumsum(np.sqrt(np.maximum(d, 1e-12)))]
    seg_len = np.linalg.norm(np.diff(P, axis=0), axis=1)
    cum = np.r_[0.0, np.cumsum(seg_len)]
    total = float(cum[-1])

    def fn(s: Array) -> Array:
        out = np.empty((len(s), 3))
        dist = s * total
        for i, x in enumerate(dist):
            j = int(np.clip(np.searchsorted(cum, x, side="right") - 1, 0, len(P) - 2))
            u = (x - cum[j]) / max(seg_len[j], 1e-15)
            k = j + 1  # index into ext / knots of P[j]
            t0, t1, t2, t3 = knots[k - 1:k + 3]
            t = t1 + u * (t2 - t1)
            p0, p1, p2, p3 = ext[k - 1:k + 3]
            a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1
            a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2
            a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3
            b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2
            b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3
            out[i] = (t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2
        return out

    return _Curve(fn, total, list(cum / max(total, 1e-15)))


def _orientation_track(keys: list[Array], params: list[float]):
    """Slerp between the key orientations at their path parameters."""
    R = Rotation.from_matrix(np.array([T[:3, :3] for T in keys]))
    ps = np.array(params, dtype=float)
    keep = np.r_[True, np.diff(ps) > 1e-12]
    slerp = Slerp(ps[keep], R[np.flatnonzero(keep)])

    def track(s: Array) -> Array:
        return slerp(np.clip(s, ps[0], ps[-1])).as_matrix()

    return track


def tcp_points(robot: Robot, qs: Array) -> Array:
    """TCP positions (N, 3) of joint samples, base frame."""
    return np.asarray(robot.batch_fk(np.asarray(qs, dtype=float)).positions, dtype=float)
