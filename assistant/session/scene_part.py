"""What the web page draws: objects, robot visuals, taught paths, the plan.

A part of the `Session`, composed rather than mixed in (`Session.scene`, as viser's
`server.scene`): read-only queries over the session's state, reached only through the parts'
contract (`PartContract`); the session's scene verbs hand over to it."""

from __future__ import annotations

from typing import Any

import numpy as np

from assistant.cell.model import CellObject
from assistant.mission.model import (
    SegmentKind,
)
from assistant.session.contract import PartContract
from assistant.session.types import (
    _arc_points,
)

Array = np.ndarray


class ScenePart:
    """What the web page draws: objects, robot visuals, taught paths, the plan."""

    def __init__(self, core: PartContract) -> None:
        self._core = core

    # ================================================================== scene for the UI
    def scene_objects(self) -> list[CellObject]:
        """Placed objects (display mesh in object frame, `T_world_object`, colour, role)."""
        return list(self._core.cell.objects.values())

    def robot_visuals(self) -> list[tuple[str, Any, tuple[int, int, int]]]:
        """(link name, trimesh in link frame, colour) for every robot link with a visual."""
        return [(lk.name, lk.visual, lk.color) for lk in self._core.robot.links
                if lk.visual is not None]

    def link_poses_world(self, q: Array | None = None) -> Array:
        """T_world_link for every robot link at q (default: where the robot is now)."""
        q = self._core.current_joints() if q is None else np.asarray(q, float)
        return self._core.T_world_base()[None] @ self._core.robot.link_poses(q)

    def path_polylines(self, tol: float = 0.0005) -> list[tuple[str, Array]]:
        """Each application path as points (world frame) for drawing."""
        from assistant.trajectory.bezier import CubicBezier, sample_bezier_chain

        out = []
        for p in self._core.mission.paths:
            pts: list[Array] = []
            for seg in p.segments:
                if seg.kind == SegmentKind.LINE:
                    pts += [seg.start, seg.end]
                elif seg.kind == SegmentKind.ARC:
                    a, v, b = seg.points  # start, a point on the arc, end
                    pts += list(_arc_points(a, v, b))
                else:
                    samp = sample_bezier_chain([CubicBezier(*seg.points)], tol)
                    pts += list(samp.points)
            out.append((p.name, np.array(pts)))
        return out

    def plan_polylines(self) -> list[tuple[str, Array]]:
        """The planned trajectory per motion: (kind, TCP points in the world frame)."""
        traj = self._core.trajectory
        if traj is None:
            return []
        T_wb = self._core.T_world_base()
        out = []
        prev_q = traj.start.q
        for m in traj.motions:
            Q = m.joint_path if m.joint_path is not None and len(m.joint_path) else \
                np.array([prev_q, m.target.q])
            P = self._core.robot.batch_fk(np.asarray(Q, float)).positions
            out.append((m.kind.value, P @ T_wb[:3, :3].T + T_wb[:3, 3]))
            prev_q = m.target.q
        return out
