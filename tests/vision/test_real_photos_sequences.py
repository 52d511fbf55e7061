"""The pointer over real photographs (scikit-image's bundled photos hung as a wall behind the
workspace): a 25 mm red ball on a stick rendered into the calibrated stereo rig, red/orange
clutter, a 0.5 s occlusion, exposure drift and three dwells (issue 33, item 4).

Runs astronaut (the issue's orange suit and red flag), coffee (a red cup right behind the
ball in both views) and motorcycle_left (the ball held in front of a red box in one view and a
red motorcycle tank in the other), all three tuned on. `benchmarks/vision.py` reports them
and the photographs held out of tuning (`HELD_OUT_PHOTOS`).

What is asserted is what a pointer that never lies must do everywhere: no offered position
more than 10 mm off, none while no camera sees the ball, coasting flagged and at most 0.2 s,
never offered; dwells only from measured frames and never spurious; stereo RMS of offered
positions <= 1.5 mm (target 1 mm; measured 1.0, 1.3 and 0.6 mm). The share of measurable
frames that are measured is asserted as a per-photo floor: the 98 % target is NOT met
(astronaut 97.5 %, coffee 91 %, motorcycle 93.5 % at 30 fps): a new track is offered only
once it moves 15 mm (the script starts the ball still in view). A ball merged with a part of
the photo of its own colour is found by its last clean look (`vision.appearance`) when that
was learnt within 10 cm, else by its outline (`vision.outline`), else not measured rather
than guessed. Coffee was 32 % before the calibration bounded the saturation from above (the
cup's shadow is a deeper red than the ball), motorcycle 63 % before the outline finder and
the re-seeded re-acquisition.
"""

from __future__ import annotations

import pytest

from cellteach_testing.photo_scenes import operator_calibration, photo_sequence  # noqa: E402
from cellteach_testing.pointer_scoring import score_run  # noqa: E402
from vision.pointer import PointerSystem  # noqa: E402
from vision.sources import ReplaySource  # noqa: E402

pytestmark = pytest.mark.slow  # renders two 7.7 s sequences: ~1-2 min on a busy machine


def _run(seq, profile):
    sources = [ReplaySource(f, f[0].camera_id) for f in seq.frames]
    system = PointerSystem(sources, seq.models, profile)
    return [system.step() for _ in range(seq.n_frames)]


#: photo -> (floor of the measured share of measurable frames, dwells that must be found);
#: measured at 30 fps, seed 1: astronaut 0.975 and 3/3, coffee 0.912 and 3/3 (0.32 and 1/3
#: without the saturation bound), motorcycle_left 0.935 and 3/3 (0.634 and 2/3 without the
#: outline finder)
FLOORS = {"astronaut": (0.93, 3), "coffee": (0.85, 3), "motorcycle_left": (0.85, 3)}


@pytest.fixture(scope="module", params=sorted(FLOORS))
def photo_run(request, stereo_rig, centre):
    seq = photo_sequence(request.param, stereo_rig, centre, seed=1, fps=30)
    cal, _ = operator_calibration(seq)
    states = _run(seq, cal.profile)
    return seq, states, score_run(states, seq.holds)


def test_no_offered_position_lies(photo_run):
    seq, states, r = photo_run
    assert r["offered"] >= 50  # it does measure: not a pointer that is simply silent
    assert r["false_offered"] == 0 and r["offered_while_unseen"] == 0
    assert r["max_mm"] <= 10.0
    assert r["stereo_rms_mm"] <= 1.5  # target 1 mm; measured 1.0, 1.3 and 0.6 mm
    # the teaching position is always a measurement of this frame
    assert all(s.measured and s.measurement is not None for s in states if s.offered)


def test_coasting_is_bounded_flagged_and_never_offered(photo_run):
    seq, states, r = photo_run
    assert r["coasting_offered"] == 0
    assert r["coast_max_s"] <= 0.2 + 1e-9
    hidden = [s for s in states if any(a <= s.timestamp < b for a, b in seq.hidden)]
    assert hidden and not any(s.offered for s in hidden)  # nothing to measure: nothing taught
    for s in hidden:  # anything shown is named for what it is
        if s.drawn_position is not None:
            assert s.status in ("coasting", "unconfirmed", "single view")
    # well into the occlusion no coasting is shown any more, whatever the track still holds
    late = [s for s in hidden if s.timestamp > seq.hidden[0][0] + 0.25]
    assert late and not any(s.coasting or s.status == "measured" for s in late)


def test_dwells_come_from_measured_frames_only_and_none_is_spurious(photo_run):
    seq, states, r = photo_run
    assert r["dwells_spurious"] == 0
    assert r["dwells_found"] >= FLOORS[seq.photo][1]  # target: all 3; see the docstring
    for s in states:
        if s.taught is not None:
            assert s.offered  # emitted on a measured frame
            assert s.taught.mode == "stereo"


def test_measured_share_of_measurable_frames_has_a_floor(photo_run):
    seq, states, r = photo_run
    assert r["measurable_frames"] >= 150
    assert r["measured_fraction"] >= FLOORS[seq.photo][0]  # target 0.98: see the docstring
