"""Sample trajectories the tests, the benchmark and the sample cells export.

`thesis_trajectory`: the thesis' experimental scenario (003 §10.8, SPEC §7) rebuilt for the
RV-2AJ: start P1, a joint move to P2, arc P2-P3-P4 around obstacle O1, line to P5, arc
P5-P6-P7 around O2, open the gripper at P7, the application path P7 -> P8, arc P8-P9-P10 to
the target. Six primitives, as the thesis' generated program (MOV, MVR, MVS, MVR, MVS, MVR).
The thesis gives no coordinates; these are chosen inside the RV-2AJ's reach with the tool
pointing down (J5 within +-90 deg), the arm in front of the base with the elbow up.

`drawing_trajectory`: a Bezier drawing (source 000) on a calibrated paper plane: joint move
above the first point, pen down, the drawing, pen up. With `arcs` every segment that is a
line or a circular arc within the tolerance becomes a linear or circular move; the other
segments, cut at corners (joints that are not G1), become splines through their adaptively
sampled points (or linear moves through them), so no spline rounds a corner.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from assistant.mission.motion import (
    Motion,
    MotionKind,
    ToolAction,
    ToolActionKind,
    Trajectory,
    Waypoint,
)
from assistant.robots.model import Robot, UnreachableError
from assistant.trajectory.bezier import BezierChain, fit_primitives, sample_bezier_chain
from assistant.transforms import make_T, rot_x

Array = np.ndarray

#: Tool pointing straight down, tool x along base x: reachable at any J1 for the 5-axis arm.
R_DOWN = rot_x(np.pi)

#: Thesis scenario positions (mm) in the RV-2AJ base frame, tool pointing down.
THESIS_POINTS_MM = {
    "P1": (150.0, -250.0, 280.0),
    "P2": (220.0, -220.0, 230.0),
    "P3": (290.0, -170.0, 210.0),
    "P4": (320.0, -90.0, 190.0),
    "P5": (320.0, -20.0, 170.0),
    "P6": (300.0, 40.0, 160.0),
    "P7": (250.0, 80.0, 150.0),
    "P8": (250.0, 160.0, 150.0),
    "P9": (300.0, 210.0, 190.0),
    "P10": (230.0, 260.0, 230.0),
}

#: The arm branch the thesis' robot worked in: in front of the base, elbow up.
ELBOW_UP_SEED = np.radians([0.0, 20.0, 90.0, 70.0, 0.0])


def waypoint(robot: Robot, name: str, xyz_m: Array, R: Array = R_DOWN,
             seed: Array | None = None) -> Waypoint:
    """A named waypoint with the IK solution nearest to `seed` (elbow up by default)."""
    T = make_T(R, np.asarray(xyz_m, dtype=float))
    if seed is None:
        seed = ELBOW_UP_SEED.copy()
        if robot.dof == len(seed):
            seed[0] = np.arctan2(T[1, 3], T[0, 3])
        else:
            seed = None
    res = robot.ik(T, seed)
    if not res.ok:
        raise UnreachableError(f"{name}: {res.message}", res)
    return Waypoint(T, res.best(seed), name)


def thesis_trajectory(robot: Robot, *, linear_speed: float = 0.1, joint_speed: float = 0.5,
                      jitter: float = 0.0, seed: int = 0) -> Trajectory:
    """The thesis scenario P1..P10 with its six primitives and the gripper opening at P7.

    `jitter` (m) moves every point randomly by up to that much, so the coordinates are not
    round millimetres (as a planner's are not): then the number format shows in round trips.
    """
    rng = np.random.default_rng(seed)
    w: dict[str, Waypoint] = {}
    prev_q = None
    for name, xyz in THESIS_POINTS_MM.items():
        p = np.array(xyz) / 1000.0 + rng.uniform(-jitter, jitter, 3)
        w[name] = waypoint(robot, name, p, seed=None if prev_q is None else prev_q)
        prev_q = w[name].q
    lin = dict(speed=linear_speed)
    motions = [
        Motion(MotionKind.JOINT, w["P2"], label="P1->P2", speed=joint_speed),
        Motion(MotionKind.CIRCULAR, w["P4"], via=w["P3"], label="around O1", **lin),
        Motion(MotionKind.LINEAR, w["P5"], label="P4->P5", **lin),
        Motion(MotionKind.CIRCULAR, w["P7"], via=w["P6"], label="around O2", **lin,
               actions_after=(ToolAction(ToolActionKind.GRIPPER_OPEN, 1),)),
        Motion(MotionKind.LINEAR, w["P8"], label="P7->P8", speed=0.05),
        Motion(MotionKind.CIRCULAR, w["P10"], via=w["P9"], label="P8->P10", **lin),
    ]
    return Trajectory(w["P1"], motions)


def paper_frame(origin_mm: tuple[float, float, float] = (290.0, 0.0, 100.0)) -> Array:
    """T_base_paper: the calibrated drawing base (paper x along base x, z up)."""
    return make_T(np.eye(3), np.asarray(origin_mm, dtype=float) / 1000.0)


def drawing_trajectory(robot: Robot, chain: BezierChain, *, T_base_paper: Array | None = None,
                       tolerance: float = 1e-4, spline: bool = True, arcs: bool = True,
                       lift: float = 0.03, draw_speed: float = 0.05, blend: float = 5e-4,
                       name: str = "drawing") -> Trajectory:
    """Pen down, the chain (within `tolerance`), pen up; positions D1, D2, ... on paper.

    Moves inside a corner-free run blend into each other by `blend` (m): the transitions are
    tangent, so the pen does not stop and the cut is negligible (0.5 mm into a 10 mm arc
    passes about 3 um from it).
    """
    T = paper_frame() if T_base_paper is None else T_base_paper
    chain3 = chain.transformed(T)
    up = T[:3, 2] * lift
    R = T[:3, :3] @ R_DOWN
    first = chain3.segments[0].start
    start = waypoint(robot, "HOME", first + up + T[:3, 2] * 0.05, R)
    above = waypoint(robot, "ABOVE", first + up, R, seed=start.q)
    down = waypoint(robot, "D1", first, R, seed=above.q)
    label = f"draw {name}"
    motions = [Motion(MotionKind.JOINT, above, label="approach", speed=0.5),
               Motion(MotionKind.LINEAR, down, label="pen down", speed=0.02)]
    namer = _DrawingPoints(robot, R, down.q)
    for run in corner_runs(chain3):
        first_of_run = len(motions)
        motions += _run_motions(run, namer, tolerance, spline=spline, arcs=arcs, label=label,
                                speed=draw_speed)
        for i in range(first_of_run, len(motions) - 1):
            motions[i] = replace(motions[i], blend_radius=blend)
    lift_wp = waypoint(robot, "LIFT", chain3.segments[-1].end + up, R, seed=namer.q)
    motions.append(Motion(MotionKind.LINEAR, lift_wp, label="pen up", speed=0.05))
    return Trajectory(start, motions)


class _DrawingPoints:
    """Waypoints D2, D3, ... with IK seeded by the previous one (the arm does not jump)."""

    def __init__(self, robot: Robot, R: Array, q: Array):
        self.robot, self.R, self.q, self.k = robot, R, q, 1

    def __call__(self, points: Array) -> list[Waypoint]:
        out = []
        for p in points:
            self.k += 1
            wp = waypoint(self.robot, f"D{self.k}", p, self.R, seed=self.q)
            self.q = wp.q
            out.append(wp)
        return out


def _run_motions(run: list, points: _DrawingPoints, tol: float, *, spline: bool, arcs: bool,
                 label: str, speed: float) -> list[Motion]:
    out: list[Motion] = []

    def curve(wps: list[Waypoint]) -> None:
        if len(wps) == 1 or not spline:
            out.extend(Motion(MotionKind.LINEAR, w, label=label, speed=speed) for w in wps)
        else:
            out.append(Motion(MotionKind.SPLINE, wps[-1], through=tuple(wps[:-1]), label=label,
                              speed=speed))

    if not arcs:
        curve(points(sample_bezier_chain(run, tol).points[1:]))
        return out
    pending: list[Waypoint] = []
    for piece in fit_primitives(run, tol):
        if piece.kind == "curve":
            pending += points(piece.points[1:])
            continue
        if pending:
            curve(pending)
            pending = []
        if piece.kind == "line":
            out.append(Motion(MotionKind.LINEAR, points(piece.points[1:])[0], label=label,
                              speed=speed))
        else:
            via, end = points(piece.points[1:])
            out.append(Motion(MotionKind.CIRCULAR, end, via=via, label=label, speed=speed))
    if pending:
        curve(pending)
    return out


def corner_runs(chain: BezierChain, angle: float = np.radians(1.0)) -> list[list]:
    """The chain's segments grouped into runs without corners (tangent turn <= angle)."""
    corners = set(chain.c1_defects(angle, geometric=True))
    runs: list[list] = [[chain.segments[0]]]
    for j in range(1, len(chain.segments)):
        if j in corners:
            runs.append([])
        runs[-1].append(chain.segments[j])
    return runs
