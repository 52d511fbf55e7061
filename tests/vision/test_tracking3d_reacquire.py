"""The 3-D track picked up again after a gap: if the first fix after the gap was a look-alike
and the next one, a few centimetres off, is the ball, the jump between them re-seeds the
filter instead of becoming a velocity that would fling the prediction (and with it the gate)
away from the ball - as on the motorcycle photo, where that lost the whole second hold."""

from __future__ import annotations

import numpy as np

from vision.geometry import PointEstimate
from vision.tracking3d import Track3D

DT = 1.0 / 60.0


def _fix(p) -> PointEstimate:
    return PointEstimate(np.asarray(p, float), np.eye(3) * 1e-7, "stereo", 0.1, (0, 1))


def _confirmed_track() -> tuple[Track3D, float]:
    tr = Track3D()
    t = 0.0
    tr.start(t, _fix([0.3, 0.0, 0.3]))
    for k in range(1, 12):
        t = k * DT
        tr.predict_to(t)
        tr.update(t, _fix([0.3 + 0.5 * t, 0.0, 0.3]))  # 0.5 m/s along x
    tr.confirmed = True  # offered by the owner
    return tr, t


def test_a_jump_from_an_unconfirmed_pick_up_re_seeds_the_filter():
    tr, t = _confirmed_track()
    t += 0.4  # hidden
    tr.predict_to(t)
    tr.update(t, _fix([0.5, 0.2, 0.3]))  # something else, in reach
    assert tr.was_confirmed and not tr.confirmed and tr.hits == 1
    t += DT
    ball = np.array([0.5, 0.15, 0.35])  # 7 cm from it
    tr.predict_to(t)
    tr.update(t, _fix(ball))
    assert tr.hits == 1 and tr.travel == 0.0  # a new start here, to be shown moving
    assert np.linalg.norm(tr.filter.velocity) < 0.1  # no velocity from the jump
    tr.predict_to(t + DT)
    assert np.linalg.norm(tr.filter.position - ball) < 0.005


def test_a_steady_track_is_still_filtered():
    tr, t = _confirmed_track()
    assert tr.hits == 12 and 0.4 < tr.filter.velocity[0] < 0.6
    t += DT
    tr.predict_to(t)
    tr.update(t, _fix([0.3 + 0.5 * t + 0.04, 0.0, 0.3]))  # a 4 cm outlier on a confirmed track
    assert tr.hits == 13  # filtered, not re-seeded: only an unconfirmed pick-up re-seeds
