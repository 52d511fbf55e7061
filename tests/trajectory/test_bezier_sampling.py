"""Bezier sampling by chord error: exact error, tolerance met, fewer points than a fixed step."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.trajectory.bezier_sampling import (
    chord_error,
    de_casteljau,
    evaluate,
    fixed_step_samples,
    sample_bezier_chain,
    sample_cubic_bezier,
)


def _dense_deviation(ctrl, polyline, n=20001):
    """Brute force: largest distance of dense curve points to the polyline."""
    C = evaluate(ctrl, np.linspace(0.0, 1.0, n))
    best = np.full(len(C), np.inf)
    for a, b in zip(polyline[:-1], polyline[1:], strict=True):
        d = b - a
        L2 = float(d @ d)
        s = np.clip((C - a) @ d / L2, 0, 1) if L2 > 0 else np.zeros(len(C))
        best = np.minimum(best, np.linalg.norm(C - a - s[:, None] * d, axis=1))
    return float(best.max())


CURVES = [
    np.array([[0, 0, 0], [0.05, 0.1, 0], [0.15, -0.05, 0.02], [0.2, 0.05, 0]]),
    np.array([[0, 0, 0], [0.3, 0.1, 0], [-0.1, 0.1, 0], [0.2, 0, 0]]),  # overshoots its chord
    np.array([[0, 0, 0], [0.1, 0.1, 0], [-0.1, 0.1, 0], [0, 0, 0.0]]),  # closed loop
    np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0.0]]),  # sharp bend
]


@pytest.mark.parametrize("ctrl", CURVES)
def test_chord_error_is_exact(ctrl):
    assert chord_error(ctrl) == pytest.approx(_dense_deviation(ctrl, ctrl[[0, 3]]), abs=1e-7)


@pytest.mark.parametrize("ctrl", CURVES)
def test_samples_meet_the_tolerance_with_fewer_points_than_a_fixed_step(ctrl):
    tol = 0.0005
    s = sample_cubic_bezier(ctrl, tol)
    assert s.max_deviation <= tol
    assert _dense_deviation(ctrl, s.points) <= tol + 1e-7
    assert _dense_deviation(ctrl, s.points) == pytest.approx(s.max_deviation, abs=2e-7)
    assert np.allclose(s.points[0], ctrl[0]) and np.allclose(s.points[-1], ctrl[3])
    # The source's way: a fixed dt. The coarsest dt that meets the same tolerance needs more.
    n = 2
    while _dense_deviation(ctrl, fixed_step_samples(ctrl, 1.0 / n), 4001) > tol:
        n += 1
    assert len(s.points) <= n + 1


def test_de_casteljau_halves_reproduce_the_curve():
    ctrl = CURVES[0]
    mid, left, right = de_casteljau(ctrl, 0.3)
    assert np.allclose(mid, evaluate(ctrl, 0.3))
    t = np.linspace(0, 1, 7)
    assert np.allclose(evaluate(left, t), evaluate(ctrl, 0.3 * t))
    assert np.allclose(evaluate(right, t), evaluate(ctrl, 0.3 + 0.7 * t))


def test_chain_shares_end_points_and_orders_parameters():
    a = CURVES[0]
    b = np.array([a[3], a[3] + [0.05, 0.05, 0], a[3] + [0.1, -0.02, 0], a[3] + [0.15, 0, 0]])
    s = sample_bezier_chain([a, b], 0.001)
    assert np.all(np.diff(s.params) > 0)
    assert s.params[0] == 0.0 and s.params[-1] == 2.0
    assert np.sum(np.all(np.isclose(s.points, a[3]), axis=1)) == 1
    assert s.max_deviation <= 0.001


def test_tighter_tolerance_needs_more_points():
    counts = [len(sample_cubic_bezier(CURVES[0], tol).points) for tol in (0.002, 0.0005, 0.0001)]
    assert counts[0] < counts[1] < counts[2]


def test_bad_input_is_refused():
    with pytest.raises(ValueError):
        sample_cubic_bezier(CURVES[0], 0.0)
    with pytest.raises(ValueError):
        sample_cubic_bezier(CURVES[0][:3], 0.001)
