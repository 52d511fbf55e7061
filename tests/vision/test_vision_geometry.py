"""3-D geometry: exact triangulation, the sphere-centre correction, single-camera distance."""

from __future__ import annotations

import numpy as np
import pytest

from vision.camera_model import CameraModel
from vision.geometry import (
    expected_radius_px,
    mono_from_size,
    sphere_ray,
    triangulate,
)
from vision.rigs import look_at
from vision.scene import PointerScene, SensorSpec
from vision.sources import SyntheticCamera


def _pixel_ray(model, X):
    """A ray through the exact projection of X (a vanishing ball: no ellipse correction)."""
    return sphere_ray(model, model.project(X), 1e-9)


def test_triangulation_of_exact_rays_is_exact(stereo_rig):
    rng = np.random.default_rng(0)
    for X in np.array([0.3, 0.0, 0.3]) + rng.uniform(-0.3, 0.3, (20, 3)):
        est = triangulate(stereo_rig, [_pixel_ray(m, X) for m in stereo_rig])
        assert np.linalg.norm(est.position_world - X) < 1e-9
        assert est.reprojection_px < 1e-6


def test_covariance_is_longest_along_the_viewing_direction(stereo_rig, centre):
    est = triangulate(stereo_rig, [_pixel_ray(m, centre) for m in stereo_rig], sigma_px=0.3)
    w, v = np.linalg.eigh(est.covariance)
    view = centre - 0.5 * (stereo_rig[0].position_world + stereo_rig[1].position_world)
    view /= np.linalg.norm(view)
    assert abs(v[:, -1] @ view) > 0.95
    assert 0.2e-3 < np.sqrt(w[-1]) < 3e-3  # ~1 mm along, sub-mm across at 1 m


def test_parallel_rays_do_not_triangulate():
    m1 = CameraModel.from_fov(640, 480, 60, look_at([0, 0, 0], [0, 0, 5]))
    m2 = CameraModel.from_fov(640, 480, 60, look_at([0, 0, -1], [0, 0, 5]))
    X = np.array([0.0, 0.0, 5.0])
    assert triangulate([m1, m2], [_pixel_ray(m1, X), _pixel_ray(m2, X)]) is None
    with pytest.raises(ValueError):
        triangulate([m1], [_pixel_ray(m1, X)])


def test_sphere_centre_correction_matches_the_exact_image_of_a_sphere():
    """Far off-axis a sphere images to an ellipse whose centroid is not the projection of
    its centre; `sphere_ray` must undo that. The image is integrated numerically here."""
    m = CameraModel.from_fov(640, 480, 90.0)
    c = np.array([0.55, 0.35, 0.6])  # ~47 degrees off-axis
    R = 0.06
    # integrate the sphere's image on a fine grid of normalised coordinates
    g = np.linspace(-0.15, 0.15, 1201)
    xc, yc = c[0] / c[2], c[1] / c[2]
    X, Y = np.meshgrid(xc + g, yc + g)
    d = np.stack([X, Y, np.ones_like(X)], -1)
    b = d @ c
    hit = b**2 - (d * d).sum(-1) * (c @ c - R * R) > 0
    assert not hit[0].any() and not hit[-1].any()  # the grid holds the whole image
    f = m.K[0, 0]
    area_px = hit.sum() * (g[1] - g[0]) ** 2 * f * f
    cen = np.array([X[hit].mean(), Y[hit].mean()]) * f + m.K[:2, 2]
    naive_px = m.project(c)
    assert np.linalg.norm(cen - naive_px) > 0.5  # the effect is real at this size and angle
    ray = sphere_ray(m, cen, np.sqrt(area_px / np.pi))
    true_dir = c / np.linalg.norm(c)
    assert np.degrees(np.arccos(min(1.0, ray.direction_world @ true_dir))) < 0.002
    assert np.sin(ray.half_angle) == pytest.approx(R / np.linalg.norm(c), rel=5e-4)


def test_single_camera_distance_from_the_rendered_ball(stereo_rig, centre):
    from vision.color import ColorProfile
    from vision.detection import BlobDetector

    det = BlobDetector(ColorProfile("p", 172, 8, 100, 255, 45))
    rng = np.random.default_rng(4)
    rel = []
    for X in centre + rng.uniform(-0.2, 0.2, (12, 3)):
        scene = PointerScene(X, sensor=SensorSpec(exposure_s=0.0))
        f = SyntheticCamera(stereo_rig[0], scene, np.random.default_rng(1)).read(1.0)
        d = det.detect(f.image)[0]
        est = mono_from_size(stereo_rig[0], sphere_ray(stereo_rig[0], d.center_px, d.radius_px),
                             0.0125)
        D_true = np.linalg.norm(X - stereo_rig[0].position_world)
        D = np.linalg.norm(est.position_world - stereo_rig[0].position_world)
        rel.append((D - D_true) / D_true)
        assert est.mode == "mono"
    assert np.sqrt(np.mean(np.square(rel))) < 0.05  # a size estimate: a few per cent


def test_expected_radius(stereo_rig, centre):
    r = expected_radius_px(stereo_rig[0], centre, 0.0125)
    assert r == pytest.approx(stereo_rig[0].focal_px * 0.0125 / 1.0308, rel=0.01)
