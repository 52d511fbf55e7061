"""Colour calibration from an ellipse drawn over the ball, red hue wrap-around, profiles."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from vision.color import ColorProfile, ColorProfileSet
from vision.color_calibration import calibrate_from_ellipse
from vision.errors import ColorCalibrationError
from vision.scene import BLUE_MARKER_BGR, BackgroundSpec, PointerScene, SensorSpec
from vision.sources import SyntheticCamera


def _ball_frame(stereo_rig, centre, bgr=None, seed=0):
    kw = {} if bgr is None else {"ball_bgr": bgr}
    scene = PointerScene(centre, background=BackgroundSpec(n_distractors=8),
                         sensor=SensorSpec(exposure_s=0.0), **kw)
    return SyntheticCamera(stereo_rig[0], scene, np.random.default_rng(seed)).read(1.0)


def test_red_ball_gives_a_wrapping_profile_that_covers_the_ball(stereo_rig, centre):
    f = _ball_frame(stereo_rig, centre)
    r = f.truth.ball_radius_px
    prof = calibrate_from_ellipse(f.image, f.truth.ball_px, (0.8 * r, 0.8 * r), 0.0)
    assert prof.wraps and prof.h_min > prof.h_max  # straddles H = 0
    assert prof.h_min >= 160 and prof.h_max <= 15  # and is still a narrow red range
    mask = prof.mask_bgr(f.image)
    disc = np.zeros_like(mask)
    cv2.circle(disc, tuple(int(round(v)) for v in f.truth.ball_px), int(0.7 * r), 255, -1)
    inside = mask[disc > 0] > 0
    assert inside.mean() > 0.9  # the ball's own pixels, highlight and all, mostly pass


def test_red_hue_wrap_accepts_both_ends_and_rejects_orange():
    prof = ColorProfile("red", h_min=172, h_max=6, s_min=100, v_min=50)
    hsv = np.array([[[178, 200, 200], [2, 200, 200], [90, 200, 200], [15, 200, 200],
                     [0, 200, 30], [179, 60, 200]]], np.uint8)
    assert prof.mask(hsv).ravel().tolist() == [255, 255, 0, 0, 0, 0]
    assert prof.contains_hsv(178, 200, 200) and prof.contains_hsv(2, 200, 200)
    assert not prof.contains_hsv(15, 200, 200)
    assert prof.hue_width == 15


def test_non_red_ball_gives_a_plain_range(stereo_rig, centre):
    f = _ball_frame(stereo_rig, centre, bgr=BLUE_MARKER_BGR)
    r = f.truth.ball_radius_px
    prof = calibrate_from_ellipse(f.image, f.truth.ball_px, (0.8 * r, 0.6 * r), 30.0,
                                  name="robot")
    assert not prof.wraps and 95 <= prof.h_min <= prof.h_max <= 125
    assert prof.name == "robot"


def test_sloppy_ellipse_with_background_is_still_a_red_profile(stereo_rig, centre):
    """A quarter of the ellipse over grey wall: grey carries no hue and is ignored."""
    f = _ball_frame(stereo_rig, centre)
    r = f.truth.ball_radius_px
    prof = calibrate_from_ellipse(f.image, f.truth.ball_px + [0.3 * r, 0], (r, r), 0.0)
    assert prof.wraps and prof.hue_width < 30


@pytest.mark.parametrize("axes", [(0.0, 0.0), (0.4, 5.0), (float("nan"), 3.0)])
def test_empty_ellipse_is_a_clear_error(stereo_rig, centre, axes):
    f = _ball_frame(stereo_rig, centre)
    with pytest.raises(ColorCalibrationError, match="empty"):
        calibrate_from_ellipse(f.image, f.truth.ball_px, axes, 0.0)


def test_ellipse_outside_the_image_is_a_clear_error(stereo_rig, centre):
    f = _ball_frame(stereo_rig, centre)
    with pytest.raises(ColorCalibrationError, match="outside"):
        calibrate_from_ellipse(f.image, (-100, -100), (10, 10), 0.0)


def test_non_finite_centre_is_a_clear_error(stereo_rig, centre):
    f = _ball_frame(stereo_rig, centre)
    with pytest.raises(ColorCalibrationError, match="finite"):
        calibrate_from_ellipse(f.image, (float("nan"), 10.0), (5, 5), 0.0)


def test_ellipse_over_grey_only_is_a_clear_error():
    grey = np.full((100, 100, 3), 128, np.uint8)
    with pytest.raises(ColorCalibrationError, match="coloured pixels"):
        calibrate_from_ellipse(grey, (50, 50), (10, 10), 0.0)


def test_not_an_image_is_a_clear_error():
    with pytest.raises(ColorCalibrationError):
        calibrate_from_ellipse(np.zeros((10, 10), np.float32), (5, 5), (3, 3), 0.0)


def test_profiles_are_json_serialisable_and_named():
    s = ColorProfileSet([ColorProfile("pointer", 172, 6, 100, 255, 50),
                         ColorProfile("robot", 100, 120, 80, 255, 40)])
    s2 = ColorProfileSet.from_dict(json.loads(json.dumps(s.to_dict())))
    assert s2.names() == ["pointer", "robot"] and s2["pointer"] == s["pointer"]
    s2.add(ColorProfile("pointer", 170, 8, 90))  # recalibration replaces by name
    assert s2["pointer"].h_min == 170 and len(s2.names()) == 2
    with pytest.raises(KeyError, match="no colour profile named 'tool'"):
        s2["tool"]


@pytest.mark.parametrize("kw", [dict(h_min=180), dict(s_min=200, s_max=100), dict(v_min=-1),
                                dict(name="")])
def test_invalid_profiles_are_refused(kw):
    args = dict(name="p", h_min=0, h_max=10, s_min=100, s_max=255, v_min=0)
    args.update(kw)
    with pytest.raises(ValueError):
        ColorProfile(**args)


def _ball_over_deeper_red(stereo_rig, centre, seed=0):
    """The ball in front of a deeper red than its own, as the red cup on the coffee
    photograph: a hue five steps off (as measured there), more saturated, grainy."""
    rng = np.random.default_rng(seed)
    m = stereo_rig[0]
    hsv = np.empty((m.height, m.width, 3), np.uint8)
    hsv[..., 0] = np.clip(rng.normal(5.0, 1.0, (m.height, m.width)), 0, 179).round()
    hsv[..., 1] = np.clip(rng.normal(248.0, 3.0, (m.height, m.width)), 0, 255).round()
    hsv[..., 2] = np.clip(rng.normal(150.0, 12.0, (m.height, m.width)), 0, 255).round()
    scene = PointerScene(centre, sensor=SensorSpec(exposure_s=0.0))
    cam = SyntheticCamera(m, scene, rng)
    cam.background = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR).astype(np.float32)
    return cam.read(1.0)


def test_a_more_saturated_background_is_cut_off_by_the_saturation_bound(stereo_rig, centre):
    """Hue alone cannot separate the ball from a deeper red right behind it; the upper
    saturation bound can (a gain scales every channel: the ball's saturation stays put), and
    then the detector measures the ball whole instead of with the grain stuck to it."""
    from vision.color_calibration import calibrate_ellipse
    from vision.detection import BlobDetector

    f = _ball_over_deeper_red(stereo_rig, centre)
    r, c = f.truth.ball_radius_px, f.truth.ball_px
    cal = calibrate_ellipse(f.image, c, (1.3 * r, 1.3 * r))
    assert cal.separable and cal.background_fraction <= 0.03, cal.message  # 53-86 % without
    hsv = cv2.cvtColor(f.image, cv2.COLOR_BGR2HSV)
    yy, xx = np.mgrid[: f.image.shape[0], : f.image.shape[1]]
    ball = np.hypot(xx - c[0], yy - c[1]) < r - 1
    assert cal.profile.s_max < np.percentile(hsv[..., 1][~ball], 5)  # ball ~ 216, wall 248
    dets = BlobDetector(cal.profile).detect(f.image, None, (0.6 * r, 1.6 * r + 1))
    assert dets and np.linalg.norm(dets[0].center_px - c) < 0.5
    assert dets[0].axis_ratio >= 0.9 and dets[0].fill >= 0.8
