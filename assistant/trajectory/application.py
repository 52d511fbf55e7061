"""Application paths (where the tool works) into motions the exporter and the robot can use.

Lines and arcs are used as taught (LINEAR; CIRCULAR through the taught via point). Cubic
Bezier chains are sampled by chord error (the export package's `bezier` sampler, so the
program and the plan cut curves identically) into LINEAR moves, or kept as one SPLINE move
through the samples for dialects that have splines. The tool keeps the path's
fixed orientation; a 5-axis robot (RV-2AJ) cannot hold an orientation whose approach vector
leaves its arm plane, so each point's orientation is projected into the plane there, and the
largest correction is reported - the operator sees it, nothing is substituted silently.

Each motion carries a dense joint path (IK every <= `step` metres, seeded from the previous
sample: a branch flip or singularity on the path is an error, because a working path cannot
be replaced by a joint move). Tool actions: `actions_before` are done at the path's start
(after the transfer arrives), `actions_after` on the last motion.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from assistant.mission.model import ApplicationPath, PathSegment, SegmentKind
from assistant.mission.motion import Motion, MotionKind, ToolAction, Trajectory, Waypoint
from assistant.robots.model import Robot
from assistant.trajectory.assemble import PathVerifier, TrajectoryReport, verify
from assistant.trajectory.bezier import de_casteljau, sample_bezier_chain
from assistant.trajectory.cartesian_follow import follow_poses, poses_from
from assistant.trajectory.primitives import ArcPrimitive, sample_primitive
from assistant.transforms import rotation_angle

Array = np.ndarray


class BezierMode(str, Enum):
    LINEAR = "linear"  # chords within tolerance as LINEAR moves (every dialect)
    SPLINE = "spline"  # one SPLINE move through the samples (KRL SPL, ...)


#: Two Bezier segments whose tangents meet within this angle join without a corner ...
SPLINE_CORNER_RAD = np.radians(1.0)
#: ... and the first blends into the second by this much (m) instead of stopping: a KRL
#: program writes them as one SPLINE block, other dialects blend their linear moves.
SPLINE_JOIN_BLEND = 5e-4


@dataclass(frozen=True)
class ApplicationParams:
    #: Largest TCP distance between dense joint-path samples (m).
    step: float = 0.005
    #: Chord error allowed when sampling Bezier curves (m).
    bezier_tolerance: float = 0.0005
    bezier_mode: BezierMode = BezierMode.LINEAR
    #: Largest joint change between two dense samples before it counts as a jump (rad).
    max_joint_step: float = 0.1


@dataclass(frozen=True)
class ApplicationFailure:
    segment_index: int
    fraction: float
    tcp_position: Array
    message: str

    def describe(self) -> str:
        p = self.tcp_position * 1000.0
        return (f"segment {self.segment_index + 1} at {self.fraction * 100:.0f}%, TCP "
                f"({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm: {self.message}")


@dataclass(frozen=True)
class ApplicationMotions:
    """The motions of one application path, or why it cannot be done."""

    name: str
    ok: bool
    start: Waypoint | None
    motions: list[Motion] = field(default_factory=list)
    actions_before: tuple[ToolAction, ...] = ()
    failure: ApplicationFailure | None = None
    #: Largest rotation (rad) applied to the taught orientation to make it reachable.
    max_orientation_correction: float = 0.0
    #: Achieved maximum distance of the executed polyline from the Bezier curves (m).
    max_chord_error: float = 0.0
    #: Verification of the dense path (None if no verifier was given).
    verification: TrajectoryReport | None = None

    def to_trajectory(self) -> Trajectory:
        """The path on its own: start, moves, and the tool actions at its start."""
        if self.start is None:
            raise ValueError(f"application path {self.name!r} has no motions: "
                             + (self.failure.describe() if self.failure else ""))
        return Trajectory(self.start, list(self.motions), self.actions_before)


@dataclass
class _Piece:
    """One motion to build: its kind, dense TCP points from the previous target, via index."""

    kind: MotionKind
    segment: int
    points: Array
    via_index: int | None = None
    through_indices: tuple[int, ...] = ()
    #: Exact unit tangents at the start and end (Bezier pieces: from the control points).
    tangent_in: Array | None = None
    tangent_out: Array | None = None
    #: The last motion of its segment: its target is the segment's end point.
    ends_segment: bool = True


def application_motions(
    robot: Robot,
    path: ApplicationPath,
    *,
    q_seed: Array | None = None,
    T_base_world: Array | None = None,
    verifier: PathVerifier | None = None,
    params: ApplicationParams | None = None,
) -> ApplicationMotions:
    """Motions for one application path.

    Args:
        robot: kinematics (and the 5-axis projection through its IK).
        path: the taught path in the world frame.
        q_seed: configuration to start next to (e.g. where the transfer ends); else the
            robot's preferred solution.
        T_base_world: the world frame in the robot base frame (identity if None).
        verifier: exact collision check of the dense path (optional).
        params: sampling and continuity settings.
    """
    params = params or ApplicationParams()
    approach, depart = path.approach > 0.0, path.depart > 0.0
    path = with_approach(path)
    T_bw = np.eye(4) if T_base_world is None else np.asarray(T_base_world, dtype=float)
    R_base_tool = T_bw[:3, :3] @ np.asarray(path.R_world_tool, dtype=float)
    pieces, chord_err = _pieces(path, T_bw, params)
    start_point = pieces[0].points[0]
    T0 = np.eye(4)
    T0[:3, :3], T0[:3, 3] = R_base_tool, start_point
    res = robot.ik(T0, q_seed)
    correction = 0.0
    if not res.ok and res.nearest_T_base_tool is not None:
        correction = rotation_angle(res.nearest_T_base_tool[:3, :3].T @ R_base_tool)
        res = robot.ik(res.nearest_T_base_tool, q_seed)
    if not res.ok:
        fail = ApplicationFailure(0, 0.0, start_point, f"start not reachable: {res.message}")
        return ApplicationMotions(path.name, False, None, failure=fail,
                                  actions_before=tuple(path.actions_before))
    q = np.asarray(res.best(q_seed), dtype=float)
    # Points taught as named locations keep their names in the program (P7 stays P7).
    start = Waypoint(robot.fk(q), q, path.segments[0].point_name(0))
    motions: list[Motion] = []
    for piece in pieces:
        R = np.repeat(R_base_tool[None], len(piece.points), axis=0)
        follow = follow_poses(robot, poses_from(piece.points, R), q,
                              max_joint_step=params.max_joint_step)
        correction = max(correction, follow.max_orientation_correction)
        if not follow.ok:
            i = follow.fail_index or 0
            fail = ApplicationFailure(piece.segment, i / max(1, len(piece.points) - 1),
                                      piece.points[i], follow.message)
            return ApplicationMotions(path.name, False, start, motions,
                                      tuple(path.actions_before), fail, correction, chord_err)
        Q = follow.joints
        Q[0] = q
        seg = path.segments[piece.segment]
        target = Waypoint(robot.fk(Q[-1]), Q[-1], seg.point_name(-1) if piece.ends_segment
                          else "")
        via = None
        if piece.via_index is not None:
            via = Waypoint(robot.fk(Q[piece.via_index]), Q[piece.via_index], seg.point_name(1))
        through = tuple(Waypoint(robot.fk(Q[k]), Q[k]) for k in piece.through_indices)
        motions.append(Motion(piece.kind, target, via=via, through=through, joint_path=Q,
                              label=path.name, speed=path.speed))
        q = Q[-1]
    for i in range(len(pieces) - 1):
        if _tangent_join(pieces[i], pieces[i + 1]):
            motions[i] = replace(motions[i], blend_radius=SPLINE_JOIN_BLEND)
    before = tuple(path.actions_before)
    if approach:  # the tool works where the approach line arrives, not above it
        motions[0] = replace(motions[0], actions_after=before)
        before = ()
    work_end = -2 if depart else -1
    motions[work_end] = replace(motions[work_end], actions_after=tuple(path.actions_after))
    out = ApplicationMotions(path.name, True, start, motions, before, None,
                             correction, chord_err)
    if verifier is not None:
        checked = verify(robot, out.to_trajectory(), verifier)
        fail = None
        vf = checked.report.failure
        if vf is not None:
            fail = ApplicationFailure(pieces[vf.motion_index].segment, vf.fraction,
                                      vf.tcp_position, vf.description)
        out = replace(out, verification=checked.report, ok=checked.ok, failure=fail)
    return out


def _pieces(path: ApplicationPath, T_bw: Array, params: ApplicationParams,
            ) -> tuple[list[_Piece], float]:
    """Dense TCP points per motion, in the base frame; and the worst Bezier chord error."""
    if not path.segments:
        raise ValueError(f"application path {path.name!r} has no segments")
    pieces: list[_Piece] = []
    worst = 0.0
    for si, seg in enumerate(path.segments):
        P = [(T_bw @ np.append(np.asarray(p, dtype=float), 1.0))[:3] for p in seg.points]
        if seg.kind == SegmentKind.LINE:
            pieces.append(_Piece(MotionKind.LINEAR, si, _line_points(P[0], P[1], params.step)))
        elif seg.kind == SegmentKind.ARC:
            arc = ArcPrimitive.through(P[0], P[1], P[2])
            u, pts = sample_primitive(arc, params.step)
            # CIRCULAR through the taught via point: put it into the samples.
            phi = _arc_param(arc, P[1])
            k = int(np.argmin(np.abs(u - phi)))
            pts[k] = P[1]
            pieces.append(_Piece(MotionKind.CIRCULAR, si, pts, via_index=k))
        else:
            ctrl = np.array(P)
            samp = sample_bezier_chain([ctrl], params.bezier_tolerance)
            worst = max(worst, samp.max_deviation)
            if params.bezier_mode == BezierMode.SPLINE:
                pts, idx = _spline_points(ctrl, samp.t, params.step)
                pieces.append(_Piece(MotionKind.SPLINE, si, pts, through_indices=idx,
                                     tangent_in=_end_tangent(ctrl),
                                     tangent_out=_end_tangent(ctrl[::-1], outgoing=True)))
            else:
                chords = list(zip(samp.points[:-1], samp.points[1:], strict=True))
                for k, (a, b) in enumerate(chords):
                    pieces.append(_Piece(MotionKind.LINEAR, si, _line_points(a, b, params.step),
                                         ends_segment=k == len(chords) - 1))
    return pieces, worst


def _end_tangent(ctrl: Array, *, outgoing: bool = False) -> Array | None:
    """Unit tangent of a Bezier at its first control point (reversed control points and
    `outgoing`: at its end, in the direction of travel); None for a degenerate curve."""
    for p in ctrl[1:]:
        d = p - ctrl[0]
        n = float(np.linalg.norm(d))
        if n > 1e-12:
            return -d / n if outgoing else d / n
    return None


def _tangent_join(a: _Piece, b: _Piece) -> bool:
    """Two Bezier pieces that meet without a corner: the program should not stop there."""
    if a.kind != MotionKind.SPLINE or b.kind != MotionKind.SPLINE or \
            a.tangent_out is None or b.tangent_in is None:
        return False
    return float(a.tangent_out @ b.tangent_in) >= np.cos(SPLINE_CORNER_RAD)


def _line_points(a: Array, b: Array, step: float) -> Array:
    n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
    return a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)


def _arc_param(arc: ArcPrimitive, p: Array) -> float:
    r0 = arc.start - arc.centre
    v = p - arc.centre
    a = np.arctan2(np.cross(r0, v) @ arc.normal, r0 @ v) % (2.0 * np.pi)
    return float(a / arc.sweep)


def _spline_points(ctrl: Array, ts: Array, step: float) -> tuple[Array, tuple[int, ...]]:
    """The curve itself at <= step spacing, with the sample parameters `ts` included."""
    fine = [0.0]
    idx = []
    for k, (a, b) in enumerate(zip(ts[:-1], ts[1:], strict=True)):
        chord = float(np.linalg.norm(de_casteljau(ctrl, b) - de_casteljau(ctrl, a)))
        n = max(1, int(np.ceil(chord / step)))
        fine += list(np.linspace(a, b, n + 1)[1:])
        if k < len(ts) - 2:
            idx.append(len(fine) - 1)
    return de_casteljau(ctrl, np.array(fine)), tuple(idx)


def with_approach(path: ApplicationPath) -> ApplicationPath:
    """The path with its approach and depart lines as segments of its own (along the tool's
    -Z, as a programmer writes them): tool actions move onto the work itself - `before` at
    the end of the approach, `after` at the start of the depart (`application_motions`).
    Approach points are named `<start>_APP`, depart points `<end>_DEP` when the ends are."""
    if path.approach <= 0.0 and path.depart <= 0.0:
        return path
    back = -np.asarray(path.R_world_tool, dtype=float)[:, 2]  # away from the work
    segs = list(path.segments)
    first, last = segs[0], segs[-1]
    if path.approach > 0.0:
        a = first.start + path.approach * back
        name = first.point_name(0)
        segs.insert(0, PathSegment(SegmentKind.LINE, (a, first.start),
                                   (f"{name}_APP" if name else "", name)
                                   if first.names else ()))
    if path.depart > 0.0:
        d = last.end + path.depart * back
        name = last.point_name(-1)
        segs.append(PathSegment(SegmentKind.LINE, (last.end, d),
                                (name, f"{name}_DEP" if name else "") if last.names else ()))
    return replace(path, segments=segs, approach=0.0, depart=0.0)


def reversed_path(path: ApplicationPath) -> ApplicationPath:
    """The same path run backwards (for mission ordering of reversible paths).

    Tool actions keep their meaning (e.g. pen down before, pen up after), and so do the
    approach and depart lines: they swap ends."""
    return replace(path, segments=[seg.reversed() for seg in reversed(path.segments)],
                   approach=path.depart, depart=path.approach)
