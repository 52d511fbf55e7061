"""Dwell-to-teach: one event per dwell, with the averaged position and its uncertainty; and the
scripted-session helper running the real pipeline on rendered frames."""

from __future__ import annotations

import numpy as np
import pytest

from vision.dwell import DwellDetector, DwellParams, TaughtPoint
from vision.errors import VisionError
from vision.pointer import PointerParams, PointerSystem
from vision.scene import PointerScene
from vision.scripted import simulate_dwell
from vision.trajectories import waypoints

FPS = 60.0


def _feed(det, path, duration, noise=0.0002, seed=0, mode="stereo"):
    rng = np.random.default_rng(seed)
    events = []
    cov = np.eye(3) * noise**2
    for k in range(int(duration * FPS)):
        t = k / FPS
        p = path(t)
        if p is None:
            det.update(t, None)
            continue
        z = p + rng.normal(0, noise, 3)
        ev = det.update(t, p, z, cov, mode)
        if ev is not None:
            events.append(ev)
    return events


def test_fires_once_per_dwell_with_the_mean_position():
    a, b = np.array([0.3, 0.0, 0.3]), np.array([0.4, 0.1, 0.2])
    path = waypoints([a, b], move_s=0.5, hold_s=[3.0, 3.0])  # 3 s holds: 3x the dwell time
    events = _feed(DwellDetector(DwellParams(dwell_s=1.0)), path, 6.5)
    assert len(events) == 2
    assert np.linalg.norm(events[0].position_world - a) < 2e-4
    assert np.linalg.norm(events[1].position_world - b) < 2e-4
    assert events[0].timestamp == pytest.approx(1.0, abs=0.05)  # after exactly one dwell
    assert events[1].timestamp == pytest.approx(3.5 + 1.0, abs=0.2)
    assert events[0].n_samples >= 55 and events[0].mode == "stereo"
    assert np.all(events[0].std < 1e-4)  # 0.2 mm noise averaged over ~60 samples


def test_no_event_while_moving():
    path = waypoints([np.zeros(3), np.array([0.5, 0.0, 0.0])], move_s=3.0, hold_s=[0.0, 0.0])
    events = _feed(DwellDetector(), lambda t: path(t) if t < 3.0 else None, 3.0)
    assert events == []


def test_a_slow_drift_does_not_count_as_a_dwell():
    det = DwellDetector(DwellParams(radius=0.005, dwell_s=1.0))
    events = _feed(det, lambda t: np.array([0.012 * t, 0.0, 0.0]), 3.0)  # 12 mm/s
    assert events == []


def test_coming_back_to_the_same_spot_after_leaving_teaches_again():
    a, b = np.array([0.3, 0.0, 0.3]), np.array([0.3, 0.1, 0.3])
    path = waypoints([a, b, a], move_s=0.4, hold_s=[1.5, 0.2, 1.5])
    events = _feed(DwellDetector(), path, 4.0)
    assert len(events) == 2
    assert np.linalg.norm(events[1].position_world - a) < 3e-4


def test_losing_the_pointer_rearms_and_progress_reports():
    det = DwellDetector(DwellParams(dwell_s=1.0))
    p = np.array([0.3, 0.0, 0.3])
    assert len(_feed(det, lambda t: p, 1.5)) == 1
    det.update(2.0, None)  # lost
    assert det.armed
    for k in range(30):
        det.update(3.0 + k / FPS, p, p, np.eye(3) * 1e-8)
    assert 0.4 < det.progress() < 0.6


def test_mono_dwell_uses_the_wider_radius():
    p = np.array([0.3, 0.0, 0.3])
    rng = np.random.default_rng(1)
    jitter = {k: rng.normal(0, 0.004, 3) for k in range(200)}  # mono-like depth jitter
    path = lambda t: p + jitter[int(round(t * FPS))]  # noqa: E731
    assert _feed(DwellDetector(), path, 2.0, mode="stereo") == []
    events = _feed(DwellDetector(), path, 2.0, mode="mono")
    assert len(events) == 1 and events[0].mode == "mono"


def test_taught_point_json_round_trip():
    tp = TaughtPoint(np.array([0.1, 0.2, 0.3]), np.eye(3) * 1e-8, 60, 1.0, 2.0, "stereo", 1e-4)
    tp2 = TaughtPoint.from_dict(tp.to_dict())
    assert np.array_equal(tp2.position_world, tp.position_world) and tp2.mode == "stereo"
    assert tp.uncertainty == pytest.approx(1e-4)


def test_invalid_dwell_params():
    with pytest.raises(ValueError):
        DwellParams(dwell_s=0)


def test_simulated_dwell_on_rendered_frames_hits_the_target(stereo_rig):
    target = np.array([0.35, 0.1, 0.25])
    tp = simulate_dwell(stereo_rig, target, seed=0)
    assert tp.mode == "stereo" and tp.n_samples >= 30
    assert np.linalg.norm(tp.position_world - target) < 1.5e-3
    assert tp.uncertainty < 1e-3


def test_simulated_dwell_with_a_factory_in_single_camera_mode(stereo_rig):
    target = np.array([0.25, -0.05, 0.35])

    def factory(scene: PointerScene) -> PointerSystem:
        return PointerSystem.synthetic(stereo_rig[:1], scene, seed=3)

    tp = simulate_dwell(factory, target, seed=1)
    assert tp.mode == "mono"
    assert np.linalg.norm(tp.position_world - target) < 0.03


def test_simulated_dwell_reports_when_nothing_fires(stereo_rig):
    strict = PointerParams(dwell=DwellParams(radius=1e-6, radius_mono=1e-6))  # too strict
    with pytest.raises(VisionError, match="no dwell fired"):
        simulate_dwell(stereo_rig[:1], np.array([0.3, 0.0, 0.3]), seed=2, hold_s=1.2,
                       params=strict)
    with pytest.raises(ValueError, match="shorter than the dwell"):
        simulate_dwell(stereo_rig, np.array([0.3, 0.0, 0.3]), seed=2, hold_s=0.5)
