"""Frames measured by three points and drawings placed in them, for the teach step."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from assistant.mission.model import (
    ApplicationPath,
    PathSegment,
    SegmentKind,
)
from assistant.mission.motion import ToolAction
from assistant.session.types import SessionError
from assistant.transforms import angle_between

Array = np.ndarray


# ---------------------------------------------------------------------- frames and drawings
#: Three-point calibration: smallest distance between the points (m) and the angle range
#: (deg) between the x axis and the XY-plane point; outside them the frame is ill-defined.
MIN_CALIBRATION_SPAN = 0.02
CALIBRATION_ANGLES_DEG = (15.0, 165.0)


@dataclass(frozen=True)
class FrameCalibration:
    """A frame from the 3-point method (origin, +x point, XY-plane point), world frame."""

    name: str
    T_world_frame: Array
    points: Array  # (3, 3) the measured points
    #: Angle between the frame's z axis and the world z axis (how far the plane is tilted).
    tilt: float
    #: Distance of the XY-plane point from the x axis (m): the lever that fixes the tilt
    #: about x; the frame's rotation error about x is about (point error / this).
    lever_y: float

    def describe(self) -> str:
        o = self.T_world_frame[:3, 3] * 1000.0
        return (f"frame {self.name} calibrated from 3 points: origin ({o[0]:.1f}, {o[1]:.1f}, "
                f"{o[2]:.1f}) mm, tilted {np.degrees(self.tilt):.2f} deg from the world XY "
                f"plane")


def frame_from_three_points(name: str, origin: Array, x_point: Array,
                            xy_point: Array) -> FrameCalibration:
    """x along origin -> x_point; z normal to the plane of the three points with xy_point on
    the +y side; y = z cross x. Refuses points too close or (nearly) on one line."""
    o, px, pxy = (np.asarray(p, dtype=float).reshape(3) for p in (origin, x_point, xy_point))
    ex, ey = px - o, pxy - o
    for v, what in ((ex, "the x point"), (ey, "the XY-plane point")):
        if np.linalg.norm(v) < MIN_CALIBRATION_SPAN:
            raise SessionError(f"frame {name}: {what} is within "
                               f"{MIN_CALIBRATION_SPAN * 1000:.0f} mm of the origin; measure "
                               "points further apart")
    x = ex / np.linalg.norm(ex)
    ang = np.degrees(angle_between(x, ey))
    lo, hi = CALIBRATION_ANGLES_DEG
    if not lo <= ang <= hi:
        raise SessionError(f"frame {name}: the three points are almost on one line "
                           f"({ang:.1f} deg between the x axis and the XY-plane point; "
                           f"{lo:.0f}-{hi:.0f} deg needed)")
    z = np.cross(x, ey)
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = o
    tilt = angle_between(z, np.array([0.0, 0.0, 1.0]))
    return FrameCalibration(name, T, np.array([o, px, pxy]), tilt, float(ey @ y))


def _drawing_control(drawing: int | Array) -> Array:
    """Control points (1 + 3k, 2-D metres) of drawing 1..9 or of the points given."""
    from assistant.trajectory.bezier_drawings import drawing as numbered

    if isinstance(drawing, (int, np.integer)):
        try:
            chain = numbered(int(drawing))
        except ValueError as exc:
            raise SessionError(str(exc)) from None
        segs = [np.asarray(s.control, dtype=float) for s in chain.segments]
        return np.vstack([segs[0][:1]] + [c[1:] for c in segs])
    P = np.asarray(drawing, dtype=float)
    if P.ndim != 2 or P.shape[1] not in (2, 3) or not np.all(np.isfinite(P)):
        raise SessionError("drawing points must be finite (x, y) pairs in the frame")
    if len(P) < 4 or (len(P) - 1) % 3:
        raise SessionError("a Bezier chain needs 1 + 3k points (start, then control, "
                           "control, end for each segment)")
    return P


def drawing_path(name: str, T_world_frame: Array, control: Array, *,
                 at: tuple[float, float] = (0.0, 0.0), angle: float = 0.0, lift: float = 0.03,
                 before: Sequence[ToolAction] = (), after: Sequence[ToolAction] = (),
                 speed: float = 0.05, reversible: bool = False,
                 tool_angle: float = 0.0) -> ApplicationPath:
    """The application path of a pen drawing on a frame's XY plane (see
    `Session.add_drawing`); `control` holds 1 + 3k points, 2-D (or 3-D) metres."""
    if not lift > 0.0:
        raise SessionError("the pen lift above the paper must be > 0")
    P = np.asarray(control, dtype=float)
    if P.shape[1] == 2:
        P = np.column_stack([P, np.zeros(len(P))])
    c, s = np.cos(angle), np.sin(angle)
    T_frame_drawing = np.eye(4)
    T_frame_drawing[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T_frame_drawing[:2, 3] = at
    T = np.asarray(T_world_frame, dtype=float) @ T_frame_drawing
    W = P @ T[:3, :3].T + T[:3, 3]
    up = np.asarray(T_world_frame, dtype=float)[:3, 2] * lift
    segs = [PathSegment(SegmentKind.LINE, (W[0] + up, W[0].copy()))]
    segs += [PathSegment(SegmentKind.BEZIER, tuple(W[i:i + 4])) for i in range(0, len(W) - 1, 3)]
    segs.append(PathSegment(SegmentKind.LINE, (W[-1].copy(), W[-1] + up)))
    # The pen points into the paper: tool z = -frame z, tool x along the drawing's x turned
    # by tool_angle about the pen.
    ct, st = np.cos(tool_angle), np.sin(tool_angle)
    R_turn = np.array([[ct, -st, 0.0], [st, ct, 0.0], [0.0, 0.0, 1.0]])
    R_world_tool = T[:3, :3] @ R_turn @ np.diag([1.0, -1.0, -1.0])
    return ApplicationPath(name, segs, R_world_tool, list(before), list(after), float(speed),
                           bool(reversible))


