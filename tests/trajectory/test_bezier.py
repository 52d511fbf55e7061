"""Bezier free shapes: De Casteljau, continuity, adaptive sampling vs the source's fixed step."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest

from assistant.trajectory.bezier import (
    BezierChain,
    CubicBezier,
    de_casteljau,
    sample_bezier_chain,
    sample_fixed_dt,
)
from assistant.trajectory.bezier_drawings import DRAWINGS, drawing


def _bernstein(P, t):
    n = len(P) - 1
    return sum(comb(n, i) * (1 - t) ** (n - i) * t ** i * P[i] for i in range(n + 1))


def _polyline_distance(points, poly):
    """Distance of each point to the polyline (independent of the module's own measure)."""
    best = np.full(len(points), np.inf)
    for a, b in zip(poly[:-1], poly[1:], strict=True):
        d = b - a
        L2 = float(d @ d)
        s = np.zeros(len(points)) if L2 == 0 else np.clip((points - a) @ d / L2, 0, 1)
        best = np.minimum(best, np.linalg.norm(points - (a + s[:, None] * d), axis=1))
    return best


def test_de_casteljau_equals_the_bernstein_form(rng):
    for dim in (2, 3):
        P = rng.normal(size=(4, dim))
        for t in rng.uniform(0, 1, 20):
            assert np.allclose(de_casteljau(P, t), _bernstein(P, t))
    P5 = rng.normal(size=(6, 3))  # any degree
    assert np.allclose(de_casteljau(P5, 0.3), _bernstein(P5, 0.3))


def test_split_and_sub_reproduce_the_curve(rng):
    c = CubicBezier(rng.normal(size=(4, 3)))
    left, right = c.split(0.3)
    t = np.linspace(0, 1, 11)
    assert np.allclose(left.point(t), c.point(0.3 * t))
    assert np.allclose(right.point(t), c.point(0.3 + 0.7 * t))
    mid = c.sub(0.2, 0.7)
    assert np.allclose(mid.point(t), c.point(0.2 + 0.5 * t))


def test_chord_bound_is_an_upper_bound(rng):
    for _ in range(200):
        c = CubicBezier(rng.normal(size=(4, 3)) * rng.uniform(0.01, 1.0))
        pts = c.point(np.linspace(0, 1, 400))
        true = _polyline_distance(pts, np.array([c.start, c.end])).max()
        assert c.chord_error_bound() >= true - 1e-12


def test_chains_must_be_c0_and_c1_can_be_checked_and_enforced():
    a = CubicBezier(np.array([[0, 0], [1, 0], [2, 1], [3, 1.0]]))
    b = CubicBezier(np.array([[3.1, 1], [4, 1], [5, 0], [6, 0.0]]))
    with pytest.raises(ValueError, match="not C0"):
        BezierChain((a, b))
    frame = drawing(1)  # lines and quarter arcs: tangent-continuous, speed jumps
    assert frame.is_g1(1e-6) and not frame.is_c1(1e-6)
    smooth = frame.enforce_c1()
    assert smooth.is_c1(1e-9)
    for s0, s1 in zip(frame.segments, smooth.segments, strict=True):
        assert np.allclose(s0.start, s1.start) and np.allclose(s0.end, s1.end)
    keys = drawing(6)  # the grid's corners are real corners
    assert not keys.is_g1(np.radians(1.0))


def test_flat_layout_of_the_source_round_trips():
    c = drawing(8)
    flat = c.to_flat()
    assert len(flat) == 2 + 6 * len(c.segments)
    back = BezierChain.from_flat(flat)
    for a, b in zip(c.segments, back.segments, strict=True):
        assert np.allclose(a.control, b.control)
    with pytest.raises(ValueError, match="2 \\+ 6n"):
        BezierChain.from_flat(flat[:-1])


def test_fixed_step_reproduces_the_sources_counts():
    c = drawing(1)
    for dt, per_segment in ((0.5, 3), (0.25, 5), (0.1, 11), (0.05, 21), (0.02, 51)):
        s = sample_fixed_dt(c, dt)
        assert set(s.per_segment) == {per_segment}  # Table 7 of source 000
        assert s.n_points == (per_segment - 1) * len(c.segments) + 1


@pytest.mark.parametrize("number", sorted(DRAWINGS))
@pytest.mark.parametrize("tol", [1e-3, 1e-4, 1e-5])
def test_adaptive_sampling_meets_its_tolerance(number, tol):
    c = drawing(number)
    s = sample_bezier_chain(c, tol)
    assert s.max_deviation <= tol * (1 + 1e-9)
    dense = np.vstack([seg.point(np.linspace(0, 1, 2000)) for seg in c.segments])
    assert _polyline_distance(dense, s.points).max() <= tol * (1 + 1e-6)
    assert s.tolerance == tol
    # Every segment's end point is a sample (corners are kept exactly).
    for seg in c.segments:
        assert np.min(np.linalg.norm(s.points - seg.end, axis=1)) < 1e-12


def test_straight_segments_need_two_points():
    line = CubicBezier(np.array([[0, 0, 0], [1, 1, 0], [2, 2, 0], [3, 3, 0.0]]))
    assert sample_bezier_chain([line], 1e-6).n_points == 2


@pytest.mark.parametrize("number", [1, 2, 3, 4, 5, 8, 9])
def test_fewer_points_than_the_fixed_step_at_equal_deviation(number):
    c = drawing(number)
    fixed = sample_fixed_dt(c, 0.05)
    adaptive = sample_bezier_chain(c, fixed.max_deviation)
    assert adaptive.max_deviation <= fixed.max_deviation * (1 + 1e-9)
    assert adaptive.n_points < fixed.n_points


def test_sampling_in_3d_after_placing_on_the_paper():
    from assistant.export.samples import paper_frame

    T = paper_frame()
    c3 = drawing(3).transformed(T)
    s = sample_bezier_chain(c3, 1e-4)
    assert s.points.shape[1] == 3
    assert np.allclose(s.points[:, 2], T[2, 3])
    assert s.max_deviation <= 1e-4


def test_lines_and_arcs_are_recognised_within_tolerance():
    from assistant.trajectory.bezier import fit_primitives

    kinds = [p.kind for p in fit_primitives(drawing(1), 1e-4)]
    assert kinds == ["line", "arc"] * 4  # a rounded rectangle: 4 strokes, 4 quarter arcs
    for n in DRAWINGS:
        for piece in fit_primitives(drawing(n), 1e-4):
            assert piece.max_deviation <= 1e-4
    # A quarter arc drawn with the usual k = 0.5523 is 0.027 % off the circle: refused at a
    # tolerance below that, sampled instead.
    tight = fit_primitives(drawing(1), 1e-7)
    assert [p.kind for p in tight][1] == "curve"
    s_curve = CubicBezier(np.array([[0, 0], [1, 1], [2, -1], [3, 0.0]]))
    assert fit_primitives([s_curve], 1e-3)[0].kind == "curve"
