"""Line/arc fitting: known shapes come back as exactly those primitives, within tolerance."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.trajectory.fit_growth import fit_primitives
from assistant.trajectory.primitives import (
    ArcPrimitive,
    FitParams,
    LinePrimitive,
    PrimitiveKind,
    sample_primitive,
)
from assistant.transforms import rot_x, rot_z

TOL = 0.001


def _line(a, b, spacing):
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(1, int(round(np.linalg.norm(b - a) / spacing)))
    return a + np.linspace(0, 1, n + 1)[:, None] * (b - a)


def _arc(centre, radius, a0, a1, spacing):
    n = max(2, int(round(abs(a1 - a0) * radius / spacing)))
    a = np.linspace(a0, a1, n + 1)
    return np.stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a),
                     np.zeros_like(a)], axis=1)


def _chain(*parts):
    out = [parts[0]]
    for p in parts[1:]:
        out.append(p[1:])
    return np.concatenate(out)


def _rounded_corner(spacing=0.01, radius=0.08):
    """Line along +x, a 90 deg arc turning left, line along +y (all tangent), in the xy plane."""
    l1 = _line([0, 0, 0], [0.15, 0, 0], spacing)
    arc = _arc([0.15, radius], radius, -np.pi / 2, 0.0, spacing)
    l2 = _line([0.15 + radius, radius, 0], [0.15 + radius, 0.26, 0], spacing)
    return _chain(l1, arc, l2), radius


def _place(P, R, t):
    return P @ R.T + t


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_two_lines_and_an_arc_come_back_as_exactly_those_three(seed):
    rng = np.random.default_rng(seed)
    P, radius = _rounded_corner()
    R = rot_z(rng.uniform(-np.pi, np.pi)) @ rot_x(rng.uniform(-1.2, 1.2))
    t = rng.uniform(-0.3, 0.3, 3)
    truth = _place(P, R, t)
    nodes = truth + rng.normal(0.0, 0.00015, truth.shape)
    nodes[0], nodes[-1] = truth[0], truth[-1]

    fit = fit_primitives(nodes, FitParams(tolerance=TOL))

    assert [p.kind for p in fit.primitives] == [PrimitiveKind.LINE, PrimitiveKind.ARC,
                                               PrimitiveKind.LINE]
    assert fit.max_deviation <= TOL
    # Both joints involve the arc, so both must be tangent (within the documented slack).
    assert all(e is not None and e <= np.radians(1.0) + 1e-9 for e in fit.tangency_error)
    arc = fit.primitives[1]
    assert arc.radius == pytest.approx(radius, rel=0.03)
    assert np.linalg.norm(arc.centre - (R @ [0.15, radius, 0] + t)) < 0.003
    assert abs(abs(arc.normal @ (R @ [0, 0, 1.0])) - 1.0) < 1e-3
    assert np.degrees(arc.sweep) == pytest.approx(90.0, abs=4.0)
    d1 = fit.primitives[0].direction
    assert np.degrees(np.arccos(np.clip(d1 @ (R @ [1.0, 0, 0]), -1, 1))) < 1.0
    # The chain starts at the first node, ends at the last, and is continuous.
    assert np.allclose(fit.primitives[0].start, nodes[0])
    assert np.allclose(fit.primitives[-1].end, nodes[-1])
    for a, b in zip(fit.primitives[:-1], fit.primitives[1:], strict=True):
        assert np.allclose(a.end, b.start)


def test_line_line_corner_is_left_to_the_controller():
    P = _chain(_line([0, 0, 0], [0.2, 0, 0], 0.01), _line([0.2, 0, 0], [0.2, 0.15, 0.05], 0.01))
    fit = fit_primitives(P, FitParams(tolerance=TOL))
    assert [p.kind for p in fit.primitives] == [PrimitiveKind.LINE, PrimitiveKind.LINE]
    assert fit.tangency_error == [None]
    assert np.linalg.norm(fit.primitives[0].end - [0.2, 0, 0]) <= TOL
    assert fit.max_deviation <= 1e-9


def test_s_curve_gives_two_tangent_arcs_of_opposite_turn():
    a1 = _arc([0.0, 0.1], 0.1, -np.pi / 2, 0.0, 0.008)  # left turn about +z
    a2 = _arc([0.2, 0.1], 0.1, np.pi, np.pi / 2, 0.008)  # right turn, tangent at (0.1, 0.1)
    fit = fit_primitives(_chain(a1, a2), FitParams(tolerance=TOL))
    assert [p.kind for p in fit.primitives] == [PrimitiveKind.ARC, PrimitiveKind.ARC]
    assert fit.primitives[0].normal @ fit.primitives[1].normal < -0.99
    assert fit.tangency_error[0] <= np.radians(1.0)
    assert fit.max_deviation <= TOL


def test_a_large_arc_is_one_primitive():
    P = _arc([0.0, 0.0], 0.12, 0.0, np.radians(270.0), 0.01)
    fit = fit_primitives(P, FitParams(tolerance=TOL))
    assert len(fit.primitives) == 1
    arc = fit.primitives[0]
    assert arc.kind == PrimitiveKind.ARC
    assert np.degrees(arc.sweep) == pytest.approx(270.0, abs=1e-6)
    assert arc.radius == pytest.approx(0.12, abs=1e-9)


def test_any_path_is_covered_within_tolerance_and_continuous():
    """A noisy helix-like curve: whatever the split, every node is within tolerance."""
    rng = np.random.default_rng(11)
    s = np.linspace(0.0, 1.0, 90)
    P = np.stack([0.2 * np.cos(3 * s) + 0.05 * s, 0.15 * np.sin(4 * s), 0.1 * s ** 2], axis=1)
    P += rng.normal(0.0, 0.0002, P.shape)
    fit = fit_primitives(P, FitParams(tolerance=TOL))
    assert fit.max_deviation <= TOL
    assert len(fit.primitives) < len(P) / 4  # it did compress
    covered = [n for p in fit.primitives for n in range(p.first_node + 1, p.last_node + 1)]
    assert covered == list(range(1, len(P)))
    for a, b in zip(fit.primitives[:-1], fit.primitives[1:], strict=True):
        assert np.allclose(a.end, b.start)


def test_arc_through_three_points_and_its_distance():
    a, v, b = np.array([0.1, 0, 0]), np.array([0, 0.1, 0]), np.array([-0.1, 0, 0])
    arc = ArcPrimitive.through(a, v, b)
    assert arc.radius == pytest.approx(0.1)
    assert np.degrees(arc.sweep) == pytest.approx(180.0)
    assert np.allclose(arc.via, v)
    # The other half of the circle is not on the arc: the distance there is to an end point.
    assert arc.distance(np.array([[0, -0.1, 0]]))[0] == pytest.approx(np.hypot(0.1, 0.1))
    assert arc.distance(np.array([[0, 0.1, 0.02]]))[0] == pytest.approx(0.02)
    u, pts = sample_primitive(arc, 0.005)
    assert u[len(u) // 2] == 0.5 and np.allclose(pts[len(u) // 2], v)
    assert np.all(np.linalg.norm(np.diff(pts, axis=0), axis=1) <= 0.005 + 1e-12)


def test_line_distance_is_to_the_segment():
    line = LinePrimitive(np.zeros(3), np.array([1.0, 0, 0]), 0, 1)
    d = line.distance(np.array([[0.5, 0.2, 0], [2.0, 0, 0], [-1.0, 0, 0]]))
    assert np.allclose(d, [0.2, 1.0, 1.0])


def test_primitive_poses_are_the_sampled_points_and_slerped_rotations():
    """`primitive_poses` (one compiled pass) gives `sample_primitive`'s fractions and
    points with `slerp_rotations`' turns, stacked as `poses_from` does, to the bit: lines
    and arcs of many lengths and sweeps, no turn, small turns and half turns."""
    from assistant.trajectory.cartesian_follow import poses_from, slerp_rotations
    from assistant.trajectory.primitives import primitive_poses
    from assistant.transforms import axis_angle

    rng = np.random.default_rng(8)
    kinds = set()
    for k in range(300):
        a, v, b = rng.uniform(-0.5, 0.5, (3, 3)) * rng.uniform(0.01, 1.0)
        prim = LinePrimitive(a, b, 0, 1) if k % 2 else ArcPrimitive.through(a, v, b, 0, 1)
        R0 = _rotation(rng)
        turn = [0.0, 1e-9, rng.uniform(0.0, 1.0), np.pi][k % 4]
        axis = rng.normal(size=3)
        R1 = R0 @ axis_angle(axis / np.linalg.norm(axis), turn)
        step = float(rng.choice([0.002, 0.005, 0.02]))
        u, T = primitive_poses(prim, step, R0, R1)
        u_ref, pts = sample_primitive(prim, step)
        T_ref = poses_from(pts, slerp_rotations(R0, R1, u_ref))
        # The sample count is an integer (a length over the step, rounded up); 1e-12 (m, and
        # unitless rotation entries): sample parameters and slerp'd rotations over a chain
        # of a few products, ~1e-16 relative each, compiled vs numpy (FMA may differ)
        assert T.shape == T_ref.shape
        np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(T, T_ref, rtol=0, atol=1e-12, err_msg=str(k))
        kinds.add((prim.kind, len(u) > 3))
    assert len(kinds) == 4  # lines and arcs, short and long


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))
