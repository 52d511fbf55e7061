"""A ball merged with a same-coloured region of a real photograph (issue 33, item 4).

The photograph (scikit-image's chelsea, on a wall 1.5 m behind the workspace) carries a red
poster exactly where cam0 looks past the hold point, so while the ball is held there it is one
blob with the poster in cam0's colour mask (cam1 sees it clear). The blob detector rightly
refuses that blob; the appearance matcher (`vision.appearance`) finds the ball by its last
clean look, and the stereo fix is measured and offered. Without the matcher and the outline
finder (`vision.outline`, which seldom finds this ball: the poster is about as dark as it)
those frames are not measured at all - so these tests fail if the matcher is removed.

Then the ball is hidden while a look-alike - a red ball in front of the poster, seen by cam0
exactly where the pointer was and at its size - stays merged with the poster: nothing may be
offered.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cellteach_testing.photo_scenes import load_photo, wall_backdrop, wall_behind
from vision.appearance import AppearanceMemory, AppearanceParams
from vision.color_calibration import calibrate_ellipse
from vision.detection import BlobDetector
from vision.outline import OutlineParams
from vision.pointer import PointerSystem
from vision.render_primitives import Canvas, draw_sphere
from vision.scene import RED_BALL_BGR, Lighting, PointerScene, SensorSpec
from vision.sources import ReplaySource, SyntheticCamera
from vision.trajectories import waypoints

FPS = 30.0
HOLD = (0.9, 2.5)  # the ball is held in front of the poster (as seen by cam0)
HIDDEN = (2.6, 3.3)  # a hand in the way; the look-alike stays
POSTER_BGR = (32.0, 30.0, 150.0)  # flat red, inside the default profile like the ball


def _render(models, centre, hold_at, *, lookalike: bool, seed: int = 5):
    wall = wall_behind(models, centre)
    photo = load_photo("chelsea").astype(np.float32)
    th, tw = photo.shape[:2]
    x, y = wall.axes()
    s = wall.width_m / tw
    origin = wall.centre - 0.5 * tw * s * x - 0.5 * th * s * y
    c0 = models[0].position_world
    d = hold_at - c0
    on_wall = c0 + d * float(np.dot(wall.centre - c0, wall.normal) / np.dot(d, wall.normal))
    u, v = (float(np.dot(on_wall - origin, a) / s) for a in (x, y))
    # the poster's centre 5 cm to the side: the ball is in front of it, off its middle
    cv2.circle(photo, (int(round(u + 0.05 / s)), int(round(v))), int(0.1 / s), POSTER_BGR, -1)
    backdrops = [wall_backdrop(m, photo, wall) for m in models]
    if lookalike:  # a red ball just in front of the poster, as big in cam0 as the pointer
        q = c0 + d * 0.97 * float(np.dot(wall.centre - c0, wall.normal)
                                  / np.dot(d, wall.normal))
        r = 0.0125 * np.linalg.norm(q - c0) / np.linalg.norm(d)
        for m, bd in zip(models, backdrops, strict=True):
            draw_sphere(Canvas(bd, m.K, 0), m.T_camera_world, q, r, RED_BALL_BGR, Lighting())
    start = hold_at + np.array([0.0, 0.09, 0.04])
    path = waypoints([start, hold_at], [HOLD[0] - 0.3], [0.3, 5.0], tremor=0.0002, seed=seed)
    scene = PointerScene(path, hidden=[HIDDEN] if lookalike else [],
                         sensor=SensorSpec(blur_samples=3))
    frames = []
    for i, (m, rng) in enumerate(zip(models, np.random.SeedSequence(seed).spawn(2),
                                     strict=True)):
        cam = SyntheticCamera(m, scene, np.random.default_rng(rng), camera_id=f"cam{i}", fps=FPS)
        cam.background = backdrops[i]
        frames.append([cam.read(1.0) for _ in range(int((HIDDEN[1] + 0.2) * FPS))])
    return frames


def _profile(frames):
    """The operator's ellipse (1.3x the ball) over the ball in cam0's first frame."""
    f = frames[0][0]
    r = 1.3 * f.truth.ball_radius_px
    cal = calibrate_ellipse(f.image, f.truth.ball_px, (r, r))
    assert cal.separable, cal.message
    return cal.profile


def _run(models, frames, appearance=None):
    sources = [ReplaySource(f, f[0].camera_id) for f in frames]
    system = PointerSystem(sources, models, _profile(frames), appearance=appearance)
    return system, [system.step() for _ in range(len(frames[0]))]


def _merged_in_cam0(frame, profile) -> bool:
    """No blob of the ball's size around the truth in cam0: the ball is merged there."""
    g = frame.truth
    dets = BlobDetector(profile).detect(frame.image)
    return g.visible and not any(np.linalg.norm(dd.center_px - g.ball_px) < 3.0
                                 and abs(dd.radius_px / g.ball_radius_px - 1.0) < 0.3
                                 for dd in dets)


@pytest.fixture(scope="module")
def hold_at(stereo_rig, centre):
    return centre + np.array([0.02, 0.03, -0.02])


@pytest.fixture(scope="module")
def merged_frames(stereo_rig, centre, hold_at):
    return _render(stereo_rig, centre, hold_at, lookalike=False)


def test_a_ball_merged_in_one_view_is_measured_and_taught(stereo_rig, merged_frames, hold_at):
    held = [k for k, f in enumerate(merged_frames[0])
            if HOLD[0] + 0.2 <= f.timestamp <= HOLD[1]]
    prof = _profile(merged_frames)
    merged = [k for k in held if _merged_in_cam0(merged_frames[0][k], prof)]
    assert len(merged) >= 0.9 * len(held)  # the scene does what it says: cam0 sees one blob
    _, states = _run(stereo_rig, merged_frames)
    offered = [k for k in merged if states[k].offered_position is not None]
    assert len(offered) >= 0.9 * len(merged)  # measured: 0 of them without the matcher
    errs = [np.linalg.norm(states[k].offered_position - merged_frames[0][k].truth.ball_world)
            for k in offered]
    # measured: RMS 0.9 mm, max 1.8 mm (the look was learnt up to 10 cm away, where the
    # highlight sat a little differently); a view one pixel off would be ~4 mm off in depth
    assert max(errs) <= 3.0e-3 and np.sqrt(np.mean(np.square(errs))) <= 1.3e-3
    for k in offered:  # cam0's view is the marked appearance match, cam1's a whole blob
        views = states[k].cameras
        assert views["cam0"].pointer.method == "appearance"
        assert views["cam0"].pointer.match >= AppearanceParams().min_ncc
        assert views["cam1"].pointer.method == "blob"
    taught = [s.taught for s in states if s.taught is not None]
    assert len(taught) == 1 and np.linalg.norm(taught[0].position_world - hold_at) <= 2.0e-3


def _merged(merged_frames):
    prof = _profile(merged_frames)
    return [k for k, f in enumerate(merged_frames[0])
            if HOLD[0] + 0.2 <= f.timestamp <= HOLD[1] and _merged_in_cam0(f, prof)]


def test_without_the_matcher_or_the_outline_those_frames_are_not_measured(stereo_rig,
                                                                          merged_frames):
    """The same frames with the matcher and the outline finder switched off: what the first
    test gains is theirs."""
    off = AppearanceParams(min_ncc=1.01, outline=OutlineParams(min_support=1.01))
    _, states = _run(stereo_rig, merged_frames, appearance=off)
    merged = _merged(merged_frames)
    assert merged and not any(states[k].offered for k in merged)
    assert not any(s.taught is not None for s in states)


def test_without_the_matcher_what_the_outline_offers_is_right(stereo_rig, merged_frames,
                                                               hold_at):
    """The matcher off, the outline finder on (`vision.outline`). This poster is about as dark
    as the ball, so its outline is seen on too little of the rim and the finder mostly refuses
    (it finds the ball where the background differs in brightness: the red box and tank of
    the motorcycle sequence). Whatever it does offer must be within 5 mm (measured: one frame,
    3.1 mm off - a weak-contrast outline is less exact than a blob; the 10 mm bound of a
    position that may be offered holds), and nothing wrong taught."""
    _, states = _run(stereo_rig, merged_frames, appearance=AppearanceParams(min_ncc=1.01))
    for k in _merged(merged_frames):
        if states[k].offered:
            assert states[k].cameras["cam0"].pointer.method == "outline"
            truth = merged_frames[0][k].truth.ball_world
            assert np.linalg.norm(states[k].offered_position - truth) <= 5.0e-3
    for s in states:
        if s.taught is not None:
            assert np.linalg.norm(s.taught.position_world - hold_at) <= 2.0e-3


def test_a_merged_lookalike_without_the_ball_is_never_offered(stereo_rig, centre, hold_at):
    frames = _render(stereo_rig, centre, hold_at, lookalike=True)
    system, states = _run(stereo_rig, frames)
    hidden = [k for k, f in enumerate(frames[0]) if HIDDEN[0] <= f.timestamp < HIDDEN[1]]
    assert hidden and not any(states[k].offered for k in hidden)
    assert not any(states[k].drawn_position is not None and states[k].status == "measured"
                   for k in hidden)
    # a matched look in cam0 during the hiding is never the pointer of an offered fix
    for k in hidden:
        p = states[k].cameras["cam0"].pointer
        assert p is None or not states[k].offered
    # before the hand came in, the ball itself was measured in front of the poster
    before = [k for k, f in enumerate(frames[0]) if HOLD[0] + 0.3 <= f.timestamp <= HOLD[1]]
    assert sum(states[k].offered for k in before) >= 0.8 * len(before)
    for s in states:
        if s.taught is not None:
            assert np.linalg.norm(s.taught.position_world - hold_at) <= 2.0e-3


def test_the_matcher_refuses_a_flat_patch_and_a_stale_or_distant_look(stereo_rig,
                                                                     merged_frames):
    """Unit level: a look is learnt from a clean frame; the poster alone (no ball) is refused,
    and so is a look from too long ago or too far away, each with its reason."""
    prof = _profile(merged_frames)
    f_clean = merged_frames[0][2]  # at the start, away from the poster
    g = f_clean.truth
    det = next(d for d in BlobDetector(prof).detect(f_clean.image)
               if np.linalg.norm(d.center_px - g.ball_px) < 1.0)
    import dataclasses
    det = dataclasses.replace(det, ring_fraction=0.0)
    mem = AppearanceMemory(2)
    mem.learn(0, 0.0, f_clean.image, det, g.ball_world, g.ball_radius_px, 0.1)
    assert mem.has_template(0, 0.0)
    f_held = next(f for f in merged_frames[0] if f.timestamp >= HOLD[0] + 0.5)
    gh = f_held.truth
    found = mem.find(0, 0.1, f_held.image, prof, gh.ball_px, 12,
                     gh.ball_radius_px, gh.ball_world)
    assert found is not None and np.linalg.norm(found.center_px - gh.ball_px) <= 0.5
    # the poster a little to the side of the ball, where only red paper is
    side = gh.ball_px + np.array([0.0, 3.2 * gh.ball_radius_px])
    poster = f_held.image.copy()
    cv2.circle(poster, tuple(int(round(c)) for c in gh.ball_px), int(gh.ball_radius_px + 3),
               POSTER_BGR, -1)
    assert mem.find(0, 0.1, poster, prof, gh.ball_px, 8,
                    gh.ball_radius_px, gh.ball_world) is None
    assert mem.last_refusal
    assert mem.find(0, 0.1, f_held.image, prof, side, 4,
                    gh.ball_radius_px, gh.ball_world) is None
    assert mem.find(0, 100.0, f_held.image, prof, gh.ball_px, 12,
                    gh.ball_radius_px, gh.ball_world) is None
    assert "no clean look" in mem.last_refusal
    far = gh.ball_world + np.array([0.2, 0.0, 0.0])
    assert mem.find(0, 0.1, f_held.image, prof, gh.ball_px, 12,
                    gh.ball_radius_px, far) is None
    assert "mm from where its look was learnt" in mem.last_refusal
    # a blob touching its colour is not learnt from (its centre may be a pixel off)
    fresh = AppearanceMemory(1)
    fresh.learn(0, 0.0, f_clean.image, dataclasses.replace(det, ring_fraction=0.3),
                g.ball_world, g.ball_radius_px, 0.1)
    assert not fresh.has_template(0, 0.0)
