"""Placement: N-point rigid fit (the thesis' 4-point method for N = 4), refusals, mm/deg edge."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from assistant.cell.model import Cell, CellError, CellObject
from assistant.cell.placement import (
    PlacementError,
    fit_pose,
    place_by_points,
    pose_mm_deg,
    set_pose_mm_deg,
)

#: Four corners of a 300 x 200 x 100 mm part, as one would measure them with the pointer.
CORNERS = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.3, 0.2, 0.0], [0.0, 0.2, 0.1]])


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return T


def _apply(T: np.ndarray, P: np.ndarray) -> np.ndarray:
    return P @ T[:3, :3].T + T[:3, 3]


def test_four_point_method_recovers_an_exact_pose():
    T = _random_pose(np.random.default_rng(0))
    fit = fit_pose(CORNERS, _apply(T, CORNERS))
    np.testing.assert_allclose(fit.T_world_object, T, atol=1e-12)
    assert fit.rms_m < 1e-12 and fit.max_error_m < 1e-12
    assert fit.per_point_error_m.shape == (4,)
    assert fit.warnings == ()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 12))
def test_any_pose_is_recovered_from_any_well_spread_points(seed, n):
    rng = np.random.default_rng(seed)
    model = rng.uniform(-0.3, 0.3, (n, 3))
    try:
        fit = fit_pose(model, _apply(_random_pose(rng), model))
    except PlacementError:
        return  # random points that happen to be nearly collinear are rightly refused
    T = fit.T_world_object
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    assert fit.max_error_m < 1e-9


def test_noisy_points_give_rms_close_to_the_noise():
    # With sigma-noise on every coordinate, E[sum of squared residuals] = sigma^2 (3N - 6):
    # 6 of the 3N degrees of freedom are absorbed by the pose.
    rng = np.random.default_rng(42)
    sigma, n, trials = 0.0005, 10, 200
    model = rng.uniform(-0.25, 0.25, (n, 3))
    rms2, rot_err, pos_err = [], [], []
    for _ in range(trials):
        T = _random_pose(rng)
        fit = fit_pose(model, _apply(T, model) + rng.normal(0.0, sigma, (n, 3)))
        rms2.append(fit.rms_m**2)
        dR = fit.T_world_object[:3, :3] @ T[:3, :3].T
        rot_err.append(np.linalg.norm(Rotation.from_matrix(dR).as_rotvec()))
        pos_err.append(np.linalg.norm(fit.T_world_object[:3, 3] - T[:3, 3]))
        assert fit.max_error_m == pytest.approx(fit.per_point_error_m.max())
    expected = sigma**2 * (3 * n - 6) / n
    assert np.mean(rms2) == pytest.approx(expected, rel=0.1)
    assert np.mean(rot_err) < np.radians(0.3)
    assert np.mean(pos_err) < 3 * sigma


def test_a_misordered_point_is_named_in_a_warning():
    T = _random_pose(np.random.default_rng(3))
    measured = _apply(T, CORNERS)[[0, 1, 3, 2]]  # two corners swapped
    fit = fit_pose(CORNERS, measured)
    assert fit.max_error_m > 0.05
    assert any("same order" in w for w in fit.warnings)
    assert f"point {fit.worst_point + 1}" in fit.summary()


def test_mirrored_points_never_give_a_reflection():
    mirrored = CORNERS * np.array([1.0, 1.0, -1.0])
    fit = fit_pose(CORNERS, mirrored)
    assert np.linalg.det(fit.T_world_object[:3, :3]) == pytest.approx(1.0)
    assert fit.max_error_m > 0.01 and fit.warnings


@pytest.mark.parametrize(("model", "measured", "match"), [
    (CORNERS[:2], CORNERS[:2], "at least 3"),
    (CORNERS, CORNERS[:3], "4 model points but 3 measured"),
    (CORNERS[:, :2], CORNERS[:, :2], "x, y, z"),
    (np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0], [0, 0.1, 0]]), CORNERS,
     "points 2 and 3 are the same point"),
    (CORNERS, np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0.001, 0], [0.3, 0, 0.001]]),
     "measured points: the points are nearly on a line.*measure a point off the line"),
    (np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]), CORNERS[:3],
     "model points: the points are nearly on a line"),
    (np.array([[0, 0, 0], [0.1, np.nan, 0], [0.2, 0, 0]]), CORNERS[:3], "NaN"),
])
def test_unusable_points_are_refused(model, measured, match):
    with pytest.raises(PlacementError, match=match):
        fit_pose(model, measured)


def test_place_by_points_applies_the_fit_or_changes_nothing():
    cell = Cell()
    cell.add_object(CellObject.box("part", (0.3, 0.2, 0.1)))
    T = _random_pose(np.random.default_rng(5))
    fit = place_by_points(cell, "part", CORNERS, _apply(T, CORNERS))
    np.testing.assert_allclose(cell.objects["part"].T_world_object, T, atol=1e-12)
    assert fit.rms_m < 1e-12
    with pytest.raises(PlacementError):
        place_by_points(cell, "part", CORNERS, np.zeros((4, 3)))
    np.testing.assert_allclose(cell.objects["part"].T_world_object, T, atol=1e-12)
    with pytest.raises(CellError, match="no object named 'ghost'"):
        place_by_points(cell, "ghost", CORNERS, CORNERS)


def test_pose_in_mm_and_degrees_at_the_edge():
    cell = Cell()
    cell.add_object(CellObject.cylinder("post", 0.02, 0.2))
    obj = set_pose_mm_deg(cell, "post", [250.0, -100.0, 50.0, 90.0, 0.0, 0.0])
    np.testing.assert_allclose(obj.T_world_object[:3, 3], (0.25, -0.1, 0.05))
    np.testing.assert_allclose(obj.T_world_object[:3, 0], (0.0, 1.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(pose_mm_deg(cell, "post"), [250, -100, 50, 90, 0, 0], atol=1e-9)
    with pytest.raises(PlacementError, match="6 numbers"):
        set_pose_mm_deg(cell, "post", [1, 2, 3])
    with pytest.raises(PlacementError, match="NaN"):
        set_pose_mm_deg(cell, "post", [1, 2, 3, 0, float("nan"), 0])
    np.testing.assert_allclose(pose_mm_deg(cell, "post"), [250, -100, 50, 90, 0, 0], atol=1e-9)
