"""Application paths on the RV-2AJ: lines, arcs and Bezier chains at the path's orientation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from traj_builders import TABLE, box

from assistant.collision.checker import CollisionChecker
from assistant.mission.model import ApplicationPath, PathSegment, SegmentKind
from assistant.mission.motion import MotionKind, ToolAction, ToolActionKind
from assistant.trajectory.application import (
    ApplicationParams,
    BezierMode,
    application_motions,
    reversed_path,
)
from assistant.trajectory.bezier import de_casteljau
from assistant.trajectory.primitives import ArcPrimitive
from assistant.transforms import make_T, rot_x, rot_z

Z = 0.15
DOWN = np.diag([1.0, -1.0, -1.0])  # tool z (approach) pointing down
A = np.array

BEZ = (A([0.30, -0.04, Z]), A([0.25, 0.0, Z]), A([0.35, 0.05, Z]), A([0.28, 0.10, Z]))


def _drawing(R=DOWN) -> ApplicationPath:
    return ApplicationPath(
        "drawing",
        [PathSegment(SegmentKind.LINE, (A([0.25, -0.10, Z]), A([0.30, -0.10, Z]))),
         PathSegment(SegmentKind.ARC, (A([0.30, -0.10, Z]), A([0.33, -0.07, Z]),
                                       A([0.30, -0.04, Z]))),
         PathSegment(SegmentKind.BEZIER, BEZ)],
        R_world_tool=R,
        actions_before=[ToolAction(ToolActionKind.OUTPUT, 3, True)],
        actions_after=[ToolAction(ToolActionKind.OUTPUT, 3, False)],
        speed=0.04,
    )


def test_path_becomes_motions_at_its_orientation(rv2aj):
    path = _drawing()
    out = application_motions(rv2aj, path, verifier=CollisionChecker(rv2aj, [TABLE]),
                              params=ApplicationParams(bezier_tolerance=0.0005))
    assert out.ok, out.failure
    kinds = [m.kind for m in out.motions]
    assert kinds[:2] == [MotionKind.LINEAR, MotionKind.CIRCULAR]
    assert set(kinds[2:]) == {MotionKind.LINEAR} and len(kinds) > 4
    assert out.max_orientation_correction < 1e-9  # straight down is always in the arm plane
    assert out.max_chord_error <= 0.0005
    assert out.verification is not None and out.verification.ok
    # The taught via point is the CIRCULAR move's via; ends are where they were taught.
    arc = out.motions[1]
    assert np.allclose(arc.via.position, [0.33, -0.07, Z], atol=1e-9)
    assert np.allclose(arc.target.position, [0.30, -0.04, Z], atol=1e-9)
    assert np.allclose(out.motions[-1].target.position, BEZ[3], atol=1e-9)
    # Every dense configuration holds the orientation and stays on the taught geometry.
    full_arc = ArcPrimitive.through(A([0.30, -0.10, Z]), A([0.33, -0.07, Z]), A([0.30, -0.04, Z]))
    for m in out.motions:
        poses = [rv2aj.fk(q) for q in m.joint_path]
        assert all(np.allclose(T[:3, :3], DOWN, atol=1e-9) for T in poses)
        assert np.abs(np.diff(m.joint_path, axis=0)).max() <= 0.1
    tcp = np.array([rv2aj.fk(q)[:3, 3] for q in arc.joint_path])
    assert full_arc.distance(tcp).max() < 1e-9
    # Bezier chord ends lie on the curve.
    curve = de_casteljau(np.array(BEZ), np.linspace(0, 1, 4001))
    for m in out.motions[2:]:
        assert np.linalg.norm(curve - m.target.position, axis=1).min() < 1e-4
    # Tool actions and speed.
    traj = out.to_trajectory()
    assert traj.actions_at_start == tuple(path.actions_before)
    assert out.motions[-1].actions_after == tuple(path.actions_after)
    assert all(m.actions_after == () for m in out.motions[:-1])
    assert all(m.speed == 0.04 for m in out.motions)


def test_spline_mode_keeps_one_move_through_the_samples(rv2aj):
    out = application_motions(rv2aj, _drawing(),
                              params=ApplicationParams(bezier_mode=BezierMode.SPLINE))
    assert out.ok
    spline = out.motions[-1]
    assert [m.kind for m in out.motions] == [MotionKind.LINEAR, MotionKind.CIRCULAR,
                                             MotionKind.SPLINE]
    assert len(spline.through) >= 3
    curve = de_casteljau(np.array(BEZ), np.linspace(0, 1, 4001))
    tcp = np.array([rv2aj.fk(q)[:3, 3] for q in spline.joint_path])
    d = np.min(np.linalg.norm(tcp[:, None] - curve[None], axis=2), axis=1)
    assert d.max() < 1e-4  # the dense path is the curve itself


def test_bezier_segments_joined_without_a_corner_blend_and_export_as_one_krl_block(rv2aj):
    from assistant.export import KrlDialect
    from assistant.export.program import program_from_trajectory
    from assistant.trajectory.application import SPLINE_JOIN_BLEND

    p0, p1, p2, p3 = BEZ
    smooth = (p3, p3 + (p3 - p2), A([0.36, 0.14, Z]), A([0.32, 0.16, Z]))  # G1 at p3
    corner = (smooth[3], A([0.30, 0.10, Z]), A([0.27, 0.10, Z]), A([0.26, 0.06, Z]))
    path = ApplicationPath("chain", [PathSegment(SegmentKind.BEZIER, BEZ),
                                     PathSegment(SegmentKind.BEZIER, smooth),
                                     PathSegment(SegmentKind.BEZIER, corner)],
                           R_world_tool=DOWN, speed=0.04)
    out = application_motions(rv2aj, path,
                              params=ApplicationParams(bezier_mode=BezierMode.SPLINE))
    assert out.ok
    assert [m.blend_radius for m in out.motions] == [SPLINE_JOIN_BLEND, 0.0, 0.0]
    traj = out.to_trajectory()
    traj = replace(traj, start=replace(traj.start, name="START"))
    prog = program_from_trajectory(traj, rv2aj, name="CHAIN")
    src = KrlDialect().write(prog, rv2aj)[0].text
    assert src.count("ENDSPLINE") == 2  # segments 1+2 together; the corner stops


def test_tilted_orientation_is_projected_into_the_arm_plane_and_reported(rv2aj):
    tilt = rot_x(0.3)
    out = application_motions(rv2aj, _drawing(tilt @ DOWN))
    assert out.ok
    assert 0.05 < out.max_orientation_correction <= 0.3 + 1e-9
    for m in out.motions:
        for q in m.joint_path[::5]:
            T = rv2aj.fk(q)
            p = T[:3, 3]
            radial = np.array([-p[1], p[0], 0.0]) / np.hypot(p[0], p[1])
            assert abs(T[:3, 2] @ radial) < 1e-6  # approach vector in the arm plane


def test_world_frame_is_mapped_into_the_base_frame(rv2aj):
    T_base_world = make_T(rot_z(0.5), [0.05, 0.02, 0.0])
    path = _drawing()
    out = application_motions(rv2aj, path, T_base_world=T_base_world)
    assert out.ok
    end_world = path.segments[0].points[1]
    expected = (T_base_world @ np.append(end_world, 1.0))[:3]
    assert np.allclose(out.motions[0].target.position, expected, atol=1e-9)


def test_unreachable_path_is_refused_with_where(rv2aj):
    far = ApplicationPath("far", [PathSegment(SegmentKind.LINE, (A([0.30, 0.0, Z]),
                                                                 A([0.60, 0.0, Z])))],
                          R_world_tool=DOWN)
    out = application_motions(rv2aj, far)
    assert not out.ok
    assert out.failure.segment_index == 0 and 0.0 < out.failure.fraction < 1.0
    assert 0.3 < out.failure.tcp_position[0] < 0.6


def test_path_through_an_obstacle_fails_verification(rv2aj):
    post = box("post", [0.30, -0.07, Z + 0.06], [0.02, 0.02, 0.10])
    out = application_motions(rv2aj, _drawing(), verifier=CollisionChecker(rv2aj, [post]))
    assert not out.ok
    assert "post" in out.failure.message
    assert out.verification is not None and not out.verification.ok


def test_reversed_path_runs_the_same_geometry_backwards(rv2aj):
    path = _drawing()
    back = reversed_path(path)
    assert np.allclose(back.start, path.end) and np.allclose(back.end, path.start)
    assert back.actions_before == path.actions_before
    out = application_motions(rv2aj, back)
    assert out.ok
    assert [m.kind for m in out.motions][-2:] == [MotionKind.CIRCULAR, MotionKind.LINEAR]
    assert np.allclose(out.motions[-2].via.position, [0.33, -0.07, Z], atol=1e-9)
    assert np.allclose(out.motions[-1].target.position, path.start, atol=1e-9)


def test_empty_path_is_refused(rv2aj):
    with pytest.raises(ValueError, match="no segments"):
        application_motions(rv2aj, ApplicationPath("empty", []))
