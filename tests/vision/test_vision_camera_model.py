"""Camera model: projection, rays, JSON, validation; rigs look where they are told."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vision.camera_model import CameraModel
from vision.rigs import default_stereo_rig, look_at, ring_rig


def test_projection_of_a_point_on_the_axis_is_the_principal_point():
    T = look_at([1.0, 0.0, 0.5], [0.0, 0.0, 0.5])
    m = CameraModel.from_fov(640, 480, 60.0, T)
    uv = m.project(np.array([-2.0, 0.0, 0.5]))
    assert np.allclose(uv, m.K[:2, 2])
    assert m.focal_px == pytest.approx(320 / np.tan(np.radians(30)))


def test_world_up_appears_up_in_the_image():
    m = CameraModel.from_fov(640, 480, 60.0, look_at([1.0, 0.0, 0.5], [0.0, 0.0, 0.5]))
    below, above = m.project(np.array([[0.0, 0.0, 0.4], [0.0, 0.0, 0.6]]))
    assert above[1] < below[1]


def test_points_behind_the_camera_project_to_nan():
    m = CameraModel.from_fov(640, 480, 60.0)
    uv = m.project(np.array([[0.0, 0.0, -1.0], [0.1, 0.0, 1.0]]))
    assert np.all(np.isnan(uv[0])) and np.all(np.isfinite(uv[1]))


def test_rays_invert_projection_with_distortion():
    rng = np.random.default_rng(0)
    m = CameraModel.from_fov(640, 480, 70.0, look_at([0.8, 0.3, 0.6], [0.2, 0.0, 0.2]),
                             dist=[-0.15, 0.06, 0.001, -0.001, 0.0])
    P = np.array([0.2, 0.0, 0.2]) + rng.uniform(-0.2, 0.2, (50, 3))
    rays = m.rays_world(m.project(P))
    expected = P - m.position_world
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    assert np.max(np.linalg.norm(rays - expected, axis=1)) < 1e-6


def test_json_round_trip_is_exact():
    m = default_stereo_rig()[1]
    m2 = CameraModel.from_dict(json.loads(json.dumps(m.to_dict())))
    assert np.array_equal(m.K, m2.K) and np.array_equal(m.T_world_camera, m2.T_world_camera)
    assert (m2.width, m2.height) == (640, 480)


@pytest.mark.parametrize("bad", [
    dict(K=np.eye(2)),
    dict(K=np.diag([-500.0, 500.0, 1.0])),
    dict(T_world_camera=np.diag([2.0, 1.0, 1.0, 1.0])),
    dict(dist=np.zeros(3)),
    dict(width=0),
])
def test_invalid_models_are_refused_with_a_reason(bad):
    args = dict(width=640, height=480, K=np.diag([500.0, 500.0, 1.0]))
    args.update(bad)
    with pytest.raises(ValueError):
        CameraModel(**args)


def test_missing_json_fields_are_named():
    with pytest.raises(ValueError, match="K"):
        CameraModel.from_dict({"width": 640, "height": 480})


def test_default_rig_geometry(centre):
    cams = default_stereo_rig(centre, distance=1.0, baseline=0.5)
    a, b = (c.position_world for c in cams)
    assert np.linalg.norm(a - b) == pytest.approx(0.5)
    assert np.linalg.norm(0.5 * (a + b) - centre) == pytest.approx(1.0)
    for c in cams:  # both look at the centre
        assert np.allclose(c.project(centre), c.K[:2, 2], atol=1e-9)


def test_ring_rig_cameras_all_see_the_centre(centre):
    for c in ring_rig(centre, 4):
        assert np.allclose(c.project(centre), c.K[:2, 2], atol=1e-9)
