"""The ball found by its outline where its colour merged with a red box behind it
(`vision.outline`): found to a fraction of a pixel, and refused wherever it is not
unmistakable (a flat red sticker, nothing there, two balls side by side)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vision.color import DEFAULT_POINTER_RED
from vision.detection import BlobDetector
from vision.outline import find_outline
from vision.scene import PointerScene, SensorSpec
from vision.sources import SyntheticCamera

BOX_BGR = (45.0, 40.0, 215.0)  # a bright red box, as the motorcycle photo's


def _frame(stereo_rig, centre, *, box=True, seed=0):
    m = stereo_rig[0]
    wall = np.full((m.height, m.width, 3), 120.0, np.float32)
    u, v = (int(round(x)) for x in m.project(centre))
    if box:
        wall[v - 60:v + 60, u - 80:u + 80] = BOX_BGR
    cam = SyntheticCamera(m, PointerScene(centre, sensor=SensorSpec(exposure_s=0.0)),
                          np.random.default_rng(seed))
    cam.background = wall
    return cam.read(1.0)


def test_a_ball_merged_with_a_red_box_is_found_by_its_outline(stereo_rig, centre):
    f = _frame(stereo_rig, centre)
    c, r = f.truth.ball_px, f.truth.ball_radius_px
    dets = BlobDetector(DEFAULT_POINTER_RED).detect(f.image, None, (0.6 * r, 1.6 * r + 1))
    assert not any(np.linalg.norm(d.center_px - c) < 1.0 for d in dets)  # merged: no blob
    for off in ([0.0, 0.0], [2.0, -1.5], [-3.0, 2.0]):
        det, why = find_outline(f.image, DEFAULT_POINTER_RED, c + off, 8.0, r)
        assert det is not None, why
        assert det.method == "outline" and np.linalg.norm(det.center_px - c) < 0.3
        assert 0.9 < det.radius_px / r < 1.2


def test_a_flat_red_disc_of_the_size_is_refused(stereo_rig, centre):
    """A sticker has the outline but not the shading of a lit sphere."""
    f = _frame(stereo_rig, centre)
    img = f.image.copy()
    c, r = f.truth.ball_px, f.truth.ball_radius_px
    fake = c + [40.0, 0.0]
    cv2.circle(img, tuple(int(round(x)) for x in fake), int(round(r)), (20, 20, 150), -1,
               cv2.LINE_AA)
    det, why = find_outline(img, DEFAULT_POINTER_RED, fake, 6.0, r)
    assert det is None and why


def test_nothing_there_is_refused_with_a_reason(stereo_rig, centre):
    f = _frame(stereo_rig, centre)
    c, r = f.truth.ball_px, f.truth.ball_radius_px
    det, why = find_outline(f.image, DEFAULT_POINTER_RED, c + [0.0, -45.0], 6.0, r)
    assert det is None and why
    det, why = find_outline(f.image, DEFAULT_POINTER_RED, c, 6.0, float("nan"))
    assert det is None and "prediction" in why


@pytest.mark.parametrize("dx", [3.0, 4.0])
def test_two_balls_side_by_side_are_ambiguous(stereo_rig, centre, dx):
    f = _frame(stereo_rig, centre)
    c, r = f.truth.ball_px, f.truth.ball_radius_px
    twin = f.image.copy()
    h = int(np.ceil(1.3 * r))
    x0, y0 = int(round(c[0])) - h, int(round(c[1])) - h
    patch = f.image[y0:y0 + 2 * h + 1, x0:x0 + 2 * h + 1]  # the ball, and a rim of box
    sx = int(round(dx * r))
    twin[y0:y0 + patch.shape[0], x0 + sx:x0 + sx + patch.shape[1]] = patch
    det, why = find_outline(twin, DEFAULT_POINTER_RED, c + [0.5 * sx, 0.0], 0.5 * sx + 4, r)
    assert det is None and "two" in why
