"""Real photographs (scikit-image's bundled photos) for the pointer: the colour calibration
from an ellipse that holds background, the colour that cannot be told from the background (said,
with the mask), the photo lists, and what the page is handed (issue 33, item 4). The pointer
sequences over the photographs are in `test_real_photos_sequences.py` (marked slow).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cellteach_testing.photo_scenes import (  # noqa: E402
    HELD_OUT_PHOTOS,
    NON_SEPARABLE_PHOTO,
    TUNED_PHOTOS,
    colour_hotspot,
    load_photo,
    wall_backdrop,
    wall_behind,
)
from vision.color_calibration import calibrate_ellipse, calibrate_from_ellipse  # noqa: E402
from vision.errors import ColorNotSeparable  # noqa: E402
from vision.scene import PointerScene  # noqa: E402
from vision.sources import SyntheticCamera  # noqa: E402


def test_photo_lists_are_disjoint_and_bundled():
    assert not set(TUNED_PHOTOS) & set(HELD_OUT_PHOTOS)
    for name in TUNED_PHOTOS + HELD_OUT_PHOTOS + (NON_SEPARABLE_PHOTO,):
        img = load_photo(name)
        assert img.dtype == np.uint8 and img.ndim == 3 and min(img.shape[:2]) >= 300


def test_ellipse_with_background_still_calibrates_on_the_ball(stereo_rig, centre):
    """An ellipse 1.6x the ball, over the astronaut's orange suit (hue ~8) right behind it:
    the suit must not widen the ball's red range, and the profile must take little of it."""
    photo = load_photo("astronaut")
    wall = wall_behind(stereo_rig, centre)
    backdrop = wall_backdrop(stereo_rig[0], photo, wall)
    at = colour_hotspot(stereo_rig[0], backdrop, stereo_rig[1:], 1.0)
    assert at is not None
    cam = SyntheticCamera(stereo_rig[0], PointerScene(at), np.random.default_rng(3))
    cam.background = backdrop
    f = cam.read(1.0)
    r = f.truth.ball_radius_px
    cal = calibrate_ellipse(f.image, f.truth.ball_px, (1.6 * r, 1.6 * r))
    assert cal.separable, cal.message
    assert cal.ball_coverage >= 0.6
    # what remains of the background (dark red-brown folds) is reported, not hidden
    assert cal.background_fraction <= 0.15 and f"{cal.background_fraction:.0%}" in cal.message
    assert cal.profile.wraps and cal.profile.hue_width <= 16
    assert not cal.profile.contains_hsv(9, 200, 160)  # the suit's colour is out
    assert cal.mask.shape == f.image.shape[:2] and cal.mask.dtype == np.uint8
    disc = np.zeros(cal.mask.shape, np.uint8)
    cv2.circle(disc, tuple(int(round(v)) for v in f.truth.ball_px), int(0.7 * r), 255, -1)
    assert (cal.mask[disc > 0] > 0).mean() > 0.8  # and the ball's own pixels pass


def test_colour_not_separable_from_the_background_is_said_and_the_mask_shown():
    """An orange-red ball held in front of a retina photograph of its own colour."""
    img = cv2.resize(load_photo(NON_SEPARABLE_PHOTO), (640, 480), interpolation=cv2.INTER_AREA)
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    h, s, v = (int(np.median(hsv[200:280, 280:360, k])) for k in range(3))
    ball = cv2.cvtColor(np.uint8([[[h, s, min(255, v + 10)]]]), cv2.COLOR_HSV2BGR)[0, 0]
    cv2.circle(img, (320, 240), 9, tuple(int(c) for c in ball), -1, cv2.LINE_AA)
    cal = calibrate_ellipse(img, (320, 240), (12, 12))
    assert not cal.separable
    assert "not separable" in cal.message and "%" in cal.message
    assert cal.background_fraction > 0.25
    # the mask shows what the best range would pick up: far more than the ball (~250 px)
    assert (cal.mask > 0).sum() > 10 * np.pi * 9**2
    with pytest.raises(ColorNotSeparable, match="not separable") as err:
        calibrate_from_ellipse(img, (320, 240), (12, 12))
    assert err.value.calibration is not None and err.value.calibration.mask.shape == (480, 640)


def test_the_page_is_shown_only_measured_or_flagged_coasting_positions():
    """`LivePointer` hands the page `shown_state(state)`: an unmeasured track position is
    never passed on as the pointer."""
    from assistant.session.pointer_live import shown_state
    from vision.pointer import PointerState

    def state(**kw):
        base = dict(timestamp=1.0, position_world=np.array([0.3, 0.0, 0.3]),
                    covariance=np.eye(3) * 1e-6, mode="stereo", measured=False, track_id=1)
        base.update(kw)
        return PointerState(**base)

    from vision.geometry import PointEstimate

    fix = PointEstimate(np.array([0.301, 0.0, 0.3]), np.eye(3) * 1e-7, "stereo", 0.1, (0, 1))
    measured = state(measured=True, offered=True, since_measured_s=0.0, measurement=fix)
    shown = shown_state(measured)
    assert shown.mode == "stereo" and measured.status == "measured"
    assert np.array_equal(shown.position_world, fix.position_world)  # the fix, not the filter
    coasting = shown_state(state(since_measured_s=0.1))
    assert coasting.mode == "coasting" and coasting.position_world is not None
    stale = shown_state(state(since_measured_s=0.5))
    assert stale.mode == "not measured" and stale.position_world is None
    mono = shown_state(state(measured=True, mode="mono", since_measured_s=0.0))
    assert mono.mode == "single view" and mono.offered_position is None
    assert mono.position_world is not None  # shown, named as less accurate, never taught
