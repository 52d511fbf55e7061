"""From fitted primitives to a verified `Trajectory` (and the whole smoothing pipeline).

Each line/arc becomes a LINEAR/CIRCULAR motion whose waypoints carry the TCP pose and the
joints. A waypoint's orientation is taken from FK of the net particle that ends the
primitive (position replaced by the primitive's end); along the move the orientation is
slerped between its two waypoints, as controllers do, and the dense joint path is solved pose
by pose at <= `step` TCP spacing, each seeded from the previous solution. If that cannot be
done continuously (no IK, a branch flip, a singularity) the piece becomes a JOINT motion to
the same end, and the report says so.

Nothing is offered unverified: the dense joint path of the whole trajectory goes through the
exact continuous FCL check (`CollisionChecker.check_path`) and the joint limits. On failure
`AssemblyResult.trajectory` is None and the report names the motion, where along it, and
what touched what.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from assistant.collision.reports import MotionCheck
from assistant.collision.validity import ValidityChecker
from assistant.mission.motion import Motion, MotionKind, Trajectory, Waypoint
from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.trajectory.cartesian_follow import follow_poses
from assistant.trajectory.elastic_net import (
    AllowedFn,
    ElasticNetParams,
    ElasticNetResult,
    run_elastic_net,
)
from assistant.trajectory.fit_growth import fit_primitives
from assistant.trajectory.joint_steps import joint_steps
from assistant.trajectory.particles import Particles
from assistant.trajectory.primitives import (
    FitParams,
    Primitive,
    PrimitiveFit,
    PrimitiveKind,
    primitive_poses,
)

Array = np.ndarray


class PathVerifier(Protocol):
    """What verification needs; `collision.CollisionChecker` provides it."""

    def check_path(self, path: Sequence[Array], max_step: float | None = None,
                   trusted: Array | None = None) -> tuple[int, MotionCheck] | None: ...

    def min_clearance_along(self, path: Sequence[Array], max_step: float = 0.01) -> float: ...


@dataclass(frozen=True)
class AssemblyParams:
    #: Largest TCP distance between dense joint-path samples (m).
    step: float = 0.005
    #: Largest joint change between two dense samples before it counts as a jump (rad).
    max_joint_step: float = 0.1
    #: Cartesian speed of LINEAR/CIRCULAR motions (m/s).
    speed: float = 0.1
    #: JOINT fallbacks: fraction of the maximum joint speed.
    joint_speed: float = 0.3
    #: Blend radius at line/line corners (the controller rounds them, thesis Fig. 108).
    corner_blend: float = 0.01
    #: Arm travel between clearance samples (m).
    clearance_step: float = 0.01
    label: str = ""


@dataclass(frozen=True)
class VerificationFailure:
    """Where a trajectory fails: motion index and kind, fraction along it, and what happened."""

    motion_index: int
    motion_kind: str
    fraction: float
    q: Array = field(repr=False)
    tcp_position: Array
    description: str

    def describe(self) -> str:
        p = self.tcp_position * 1000.0
        return (f"motion {self.motion_index + 1} ({self.motion_kind}) at "
                f"{self.fraction * 100:.0f}%, TCP ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm: "
                f"{self.description}")


@dataclass(frozen=True)
class TrajectoryReport:
    ok: bool
    reason: str
    failure: VerificationFailure | None
    #: Smallest arm-obstacle distance along the dense path (m; None without a verifier or
    #: without obstacles) or the measurement that gives it: read it as `min_clearance`.
    clearance: float | None | Callable[[], float | None] = field(compare=False)
    #: Length of the executed (dense) TCP path (m) or the measurement that gives it: read
    #: it as `tcp_length`.
    tcp_measure: float | Callable[[], float] = field(compare=False)
    joint_length: float  # rad, sum of joint-space step norms
    primitive_counts: dict[str, int]
    max_deviation: float  # m, nodes to primitives (0 if not from a fit)
    fallbacks: tuple[str, ...] = ()
    dense_configurations: int = 0

    @property
    def min_clearance(self) -> float | None:
        """The clearance, measured when first read.

        Why on demand: it is a figure for the operator, not part of the decision (the
        path is verified before this report exists), and a distance query along the whole
        dense path is ~5 % of a transfer's planning. Most transfers are never shown alone: a
        mission measures its joined trajectory again, and a re-plan during execution is
        driven at once. The planning benchmark measures OMPL's path the same way, after
        its timed query."""
        value = self.clearance
        if callable(value):
            value = value()
            object.__setattr__(self, "clearance", value)  # once: the path does not change
        return value

    @property
    def tcp_length(self) -> float:
        """The TCP path length, measured when first read.

        Why on demand, like the clearance: FK of every dense sample (~600 a transfer) is
        ~1.5 % of a transfer's planning, and no decision reads it - the operator's report
        and the session file do; a mission reports its joined trajectory's length."""
        value = self.tcp_measure
        if callable(value):
            value = float(value())
            object.__setattr__(self, "tcp_measure", value)  # once: the path does not change
        return value

    def describe(self) -> str:
        counts = ", ".join(f"{v} {k}" for k, v in self.primitive_counts.items() if v)
        clear = ("" if self.min_clearance is None
                 else f", min clearance {self.min_clearance * 1000:.1f} mm")
        head = "verified" if self.ok else f"REJECTED: {self.reason}"
        return (f"{head}; {counts}; TCP {self.tcp_length * 1000:.0f} mm, joints "
                f"{self.joint_length:.2f} rad{clear}; max deviation "
                f"{self.max_deviation * 1000:.2f} mm"
                + (f"; fallbacks: {'; '.join(self.fallbacks)}" if self.fallbacks else ""))


@dataclass(frozen=True)
class AssemblyResult:
    #: None when verification failed: such a trajectory is never offered.
    trajectory: Trajectory | None
    report: TrajectoryReport
    #: The assembled trajectory even when rejected (for display of the failure only).
    candidate: Trajectory | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.report.ok


def assemble_trajectory(
    robot: Robot,
    fit: PrimitiveFit,
    particles: Particles,
    verifier: PathVerifier | None,
    params: AssemblyParams | None = None,
) -> AssemblyResult:
    """Motions for the fitted primitives, with dense joint paths, then verification."""
    params = params or AssemblyParams()
    q0 = np.asarray(particles.joints[0], dtype=float)
    start = Waypoint(robot.fk(q0), q0, "start")
    motions: list[Motion] = []
    checked: list[bool] = []  # per motion: the verifier already passed its dense path
    fallbacks: list[str] = []
    current = start
    prims = fit.primitives
    for k, prim in enumerate(prims):
        nxt = prims[k + 1] if k + 1 < len(prims) else None
        blend = (params.corner_blend if nxt is not None and prim.kind == PrimitiveKind.LINE
                 and nxt.kind == PrimitiveKind.LINE else 0.0)
        q_ref = np.asarray(particles.joints[prim.last_node], dtype=float)
        R_end = robot.fk(q_ref)[:3, :3]
        vias = np.asarray(particles.joints[prim.first_node + 1 : prim.last_node], dtype=float)
        made, passed, note = _cartesian_motion(robot, prim, current, R_end, q_ref, params,
                                               blend, k, vias, verifier)
        if note:
            fallbacks.append(note)
        if not made:
            report = _report(robot, None, fit, fallbacks, False,
                             f"primitive {k + 1} ({prim.kind.value}) cannot be reached", None,
                             None)
            return AssemblyResult(None, report)
        motions += made
        checked += passed
        current = made[-1].target
    traj = Trajectory(start, motions)
    return verify(robot, traj, verifier, max_deviation=fit.max_deviation,
                  fallbacks=tuple(fallbacks), clearance_step=params.clearance_step,
                  checked=tuple(checked))


def _cartesian_motion(robot: Robot, prim: Primitive, current: Waypoint, R_end: Array,
                      q_ref: Array, params: AssemblyParams, blend: float, k: int,
                      vias: Array, verifier: PathVerifier | None,
                      ) -> tuple[list[Motion], list[bool], str]:
    """The primitive as one LINEAR/CIRCULAR motion, or else as joint moves to its end;
    with each motion whether the verifier already passed its dense path.

    The joint moves keep the particles' arm branch; a straight joint move that the verifier
    refuses is split at the middle one of the net particles it covers (`vias`), recursively,
    so the fallback follows the net (where the arm was checked) with as few moves as the
    obstacles allow. Verification of the whole trajectory still follows.
    """
    u, poses = primitive_poses(prim, params.step, current.T_base_tool[:3, :3], R_end)
    follow = follow_poses(robot, poses, current.q, max_joint_step=params.max_joint_step)
    if follow.ok:
        Q = follow.joints
        Q[0] = current.q  # the move starts where the arm is
        target = Waypoint(robot.fk(Q[-1]), Q[-1])
        kind = MotionKind.LINEAR if prim.kind == PrimitiveKind.LINE else MotionKind.CIRCULAR
        via = None
        if kind == MotionKind.CIRCULAR:
            m = len(u) // 2
            via = Waypoint(robot.fk(Q[m]), Q[m])
        return [Motion(kind, target, via=via, joint_path=Q, label=params.label,
                       speed=params.speed, blend_radius=blend)], [False], ""
    # Fallback: a joint move to the primitive's end, keeping the particle's arm branch.
    T_end = np.eye(4)
    T_end[:3, :3], T_end[:3, 3] = R_end, prim.end
    q_end, why = _end_joints(robot, T_end, q_ref)
    if q_end is None:
        return [], [], f"primitive {k + 1}: end unreachable ({why})"
    chain = np.vstack([np.asarray(current.q, dtype=float)[None], vias, q_end[None]])
    keep, passed = _joint_splits(robot, chain, 0, len(chain) - 1, verifier, params.step)
    motions = []
    for a, b in zip(keep[:-1], keep[1:], strict=True):
        Q = joint_interpolation(robot, chain[a], chain[b], params.step)
        motions.append(Motion(MotionKind.JOINT, Waypoint(robot.fk(chain[b]), chain[b]),
                              joint_path=Q, label=params.label, speed=params.joint_speed,
                              blend_radius=0.0))
    what = "a joint move" if len(motions) == 1 else f"{len(motions)} joint moves"
    note = (f"primitive {k + 1} ({prim.kind.value}) became {what}: {follow.message} "
            f"at {100.0 * (follow.fail_index or 0) / max(1, len(u) - 1):.0f}%")
    return motions, passed, note


def _end_joints(robot: Robot, T_end: Array, q_ref: Array) -> tuple[Array | None, str]:
    """Joints for a fallback's end pose nearest q_ref: the pose as asked, else turned into
    the arm plane, else the position alone; or None and `ik`'s reason.

    Robots with a batched closed form answer the first two from their candidates (one
    compiled call, what `follow_poses` trusts too) instead of asking `ik` for the pose and
    again for its turned orientation (~0.2 ms a fallback, one transfer in two has one).
    Where they stand in for `ik` and have no solution, `ik` would fail on both too (two
    calls, ~0.28 ms, to hear it): the position alone is asked straight away."""
    batch = getattr(robot, "ik_candidates_batch", None)
    cands = batch(T_end[None]) if batch is not None else None
    if cands is not None and cands.answers(0):
        return np.asarray(cands.nearest(0, q_ref), dtype=float), ""
    if cands is not None and cands.exact[0]:
        res = robot.ik(T_end, q_ref, position_only=True)
    else:
        res = robot.ik(T_end, q_ref)
        if not res.ok and res.nearest_T_base_tool is not None:
            res = robot.ik(res.nearest_T_base_tool, q_ref)
        if not res.ok:
            res = robot.ik(T_end, q_ref, position_only=True)
    if not res.ok:
        return None, res.message
    return np.asarray(res.best(q_ref), dtype=float), ""


def _joint_splits(robot: Robot, chain: Array, a: int, b: int, verifier: PathVerifier | None,
                  step: float) -> tuple[list[int], list[bool]]:
    """Indices a..b of `chain` to move through in straight joint moves: a -> b if the verifier
    accepts it, else split at the middle index and recurse (no split below one step); with
    each move whether the verifier was asked (and passed it)."""
    if b - a < 2 or verifier is None:
        return [a, b], [False]
    if verifier.check_path(joint_interpolation(robot, chain[a], chain[b], step)) is None:
        return [a, b], [True]
    m = (a + b) // 2
    left, left_passed = _joint_splits(robot, chain, a, m, verifier, step)
    right, right_passed = _joint_splits(robot, chain, m, b, verifier, step)
    return left + right[1:], left_passed + right_passed


def joint_interpolation(robot: Robot, q0: Array, q1: Array, step: float) -> Array:
    """The straight joint-space move q0 -> q1 sampled so no arm point moves more than `step`."""
    q0 = np.ascontiguousarray(q0, dtype=float)
    q1 = np.ascontiguousarray(q1, dtype=float)
    if not (np.isfinite(q0).all() and np.isfinite(q1).all()):
        return _joint_interpolation_numpy(robot, q0, q1, step)
    return joint_steps(q0, q1, robot.arm_radii(), float(step))  # the numpy form, compiled


def _joint_interpolation_numpy(robot: Robot, q0: Array, q1: Array, step: float) -> Array:
    """`joint_interpolation` as numpy (`joint_steps` gives the same rows to the bit; this
    form also says what a non-finite joint does)."""
    travel = float(np.sum(robot.arm_radii() * np.abs(q1 - q0)))
    n = max(1, int(np.ceil(travel / step)))
    f = np.linspace(0.0, 1.0, n + 1)[:, None]
    return q0 + f * (q1 - q0)


def verify(robot: Robot, traj: Trajectory, verifier: PathVerifier | None, *,
           max_deviation: float = 0.0, fallbacks: tuple[str, ...] = (),
           clearance_step: float = 0.01, checked: tuple[bool, ...] = ()) -> AssemblyResult:
    """Joint limits and the exact continuous collision check of the dense path, then figures.

    `checked` flags motions whose dense path this verifier already passed (the assembly's
    joint-move fallbacks are checked as they are split): their samples are not asked again
    (`PathVerifier.check_path`'s `trusted`), the rest of the path is, and the result is the
    same."""
    paths = [_motion_path(traj, i) for i in range(len(traj.motions))]
    # Joint limits first: a clearer message than a collision report. One test of every
    # row; motion by motion only to name the first offender.
    inside_all = not paths or bool(robot.limits.contains_batch(np.concatenate(paths)).all())
    for i, Q in enumerate(() if inside_all else paths):
        inside = robot.limits.contains_batch(Q)
        if not inside.all():
            j = int(np.argmin(inside))
            viol = ", ".join(robot.limits.violations(Q[j], robot.joint_names))
            fail = _failure(robot, traj, i, j / max(1, len(Q) - 1), Q[j],
                            f"joint limit: {viol}")
            return _rejected(robot, traj, fail, max_deviation, fallbacks)
    dense = traj.dense_joint_path()
    if verifier is not None:
        # One check of the whole dense path (its segments are the motions' segments in
        # order, each motion's first row being the previous one's last): the first invalid
        # segment is the one a check motion by motion would find, at one call's cost.
        trusted = (np.repeat(np.asarray(checked, dtype=bool), [len(Q) - 1 for Q in paths])
                   if any(checked) else None)
        hit = verifier.check_path(dense, trusted=trusted)
        if hit is not None:
            g, mc = hit
            ends = np.cumsum([len(Q) - 1 for Q in paths])  # segments up to each motion's end
            i = int(np.searchsorted(ends, g, side="right"))
            Q = paths[i]
            seg = g - (int(ends[i - 1]) if i else 0)
            frac = (seg + (mc.first_invalid_fraction or 0.0)) / max(1, len(Q) - 1)
            q = Q[seg] + (mc.first_invalid_fraction or 0.0) * (Q[seg + 1] - Q[seg])
            what = mc.report.describe() if mc.report is not None else "invalid"
            return _rejected(robot, traj, _failure(robot, traj, i, frac, q, what),
                             max_deviation, fallbacks)
    clearance = (_clearance_of(verifier, dense, clearance_step)
                 if verifier is not None else None)
    report = _report(robot, traj, None, fallbacks, True, "", None, clearance,
                     max_deviation=max_deviation, dense=dense)
    return AssemblyResult(traj, report, traj)


def _tcp_length_of(robot: Robot, dense: Array) -> Callable[[], float]:
    """The report's TCP length measurement (`TrajectoryReport.tcp_length`)."""
    def measure() -> float:
        tcp = np.asarray(robot.batch_fk(dense).positions)
        return float(np.linalg.norm(np.diff(tcp, axis=0), axis=1).sum())

    return measure


def _clearance_of(verifier: PathVerifier, dense: Array, step: float,
                  ) -> Callable[[], float | None]:
    """The report's clearance measurement (`TrajectoryReport.min_clearance`)."""
    def measure() -> float | None:
        c = verifier.min_clearance_along(dense, max_step=step)
        return float(c) if np.isfinite(c) else None  # infinite: no obstacles known

    return measure


def _motion_path(traj: Trajectory, i: int) -> Array:
    m = traj.motions[i]
    prev = traj.start if i == 0 else traj.motions[i - 1].target
    if m.joint_path is not None and len(m.joint_path):
        return np.asarray(m.joint_path, dtype=float)
    return np.stack([np.asarray(prev.q, dtype=float), np.asarray(m.target.q, dtype=float)])


def _failure(robot: Robot, traj: Trajectory, i: int, frac: float, q: Array, what: str,
             ) -> VerificationFailure:
    return VerificationFailure(i, traj.motions[i].kind.value, float(frac), np.asarray(q),
                               robot.fk(q)[:3, 3].copy(), what)


def _rejected(robot: Robot, traj: Trajectory, fail: VerificationFailure, max_deviation: float,
              fallbacks: tuple[str, ...]) -> AssemblyResult:
    report = _report(robot, traj, None, fallbacks, False, fail.describe(), fail, None,
                     max_deviation=max_deviation)
    return AssemblyResult(None, report, traj)


def _report(robot: Robot, traj: Trajectory | None, fit: PrimitiveFit | None,
            fallbacks: Sequence[str], ok: bool, reason: str,
            failure: VerificationFailure | None,
            clearance: float | None | Callable[[], float | None], *,
            max_deviation: float | None = None, dense: Array | None = None,
            ) -> TrajectoryReport:
    """The report of `traj` (`dense`: its dense joint path, if the caller has it)."""
    tcp_len: float | Callable[[], float]
    if traj is not None:
        dense = traj.dense_joint_path() if dense is None else dense
        tcp_len = _tcp_length_of(robot, dense)
        joint_len = float(np.linalg.norm(np.diff(dense, axis=0), axis=1).sum())
        counts = traj.primitive_counts()
        n_dense = len(dense)
    else:
        tcp_len = joint_len = 0.0
        counts = {}
        n_dense = 0
    if max_deviation is None:
        max_deviation = fit.max_deviation if fit is not None else 0.0
    return TrajectoryReport(ok, reason, failure, clearance, tcp_len, joint_len, counts,
                            float(max_deviation), tuple(fallbacks), n_dense)


# ---------------------------------------------------------------------- the whole pipeline


@dataclass(frozen=True)
class SmoothedTrajectory:
    """Net, fit and assembly of one searched path, for display and figures."""

    net: ElasticNetResult
    fit: PrimitiveFit
    assembly: AssemblyResult

    @property
    def trajectory(self) -> Trajectory | None:
        return self.assembly.trajectory

    @property
    def report(self) -> TrajectoryReport:
        return self.assembly.report


def trajectory_from_joint_path(
    robot: Robot,
    joint_path: Sequence[Array] | Array,
    *,
    allowed: AllowedFn | None = None,
    validity: ValidityChecker | None = None,
    verifier: PathVerifier | None = None,
    net_params: ElasticNetParams | None = None,
    fit_params: FitParams | None = None,
    assembly_params: AssemblyParams | None = None,
    progress: Progress | None = None,
) -> SmoothedTrajectory:
    """Searched joint path -> elastic net -> lines/arcs -> verified trajectory.

    `validity` guards the net's particles (FCL or the octree), `verifier` checks the final
    dense path exactly; a `CollisionChecker` serves as both.
    """
    net = run_elastic_net(robot, joint_path, allowed=allowed, validity=validity,
                          params=net_params,
                          progress=progress.sub(0.0, 0.8) if progress else None)
    fit = fit_primitives(net.particles.points, fit_params)
    if progress is not None:
        progress.update(0.85, "primitives fitted")
    asm = assemble_trajectory(robot, fit, net.particles, verifier, assembly_params)
    if progress is not None:
        progress.update(1.0, "trajectory verified" if asm.ok else "trajectory rejected")
    return SmoothedTrajectory(net, fit, asm)
