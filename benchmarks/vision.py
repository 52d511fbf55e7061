"""Marker-pointer benchmark on rendered sequences with exact ground truth.

Measures, for the default stereo rig of the sample cells (two 640x480, 60 degree cameras 1 m
from the workspace centre, 0.5 m apart):
  * 3-D RMS error of stereo (target <= 2 mm) and of single-camera mode (reported),
  * detection throughput per camera on one core (target >= 300 frames/s) and the end-to-end
    latency of one `PointerSystem.step()`,
  * track continuity through a 0.5 s occlusion,
  * false detections per frame on cluttered backgrounds with red/orange look-alikes
    (target <= 1 %),
  * "a pointer that never lies" (issue 33) on rendered sequences and on sequences composited
    over real photographs (scikit-image's bundled photos: tuned on TUNED_PHOTOS, the
    HELD_OUT_PHOTOS never used in tuning, reported apart): RMS, p95 and max error of every
    offered position, missed measurable frames, false positions offered, longest coasting,
    dwells found / spurious (targets: RMS <= 1 mm, max <= 10 mm, >= 98 % of measurable frames
    measured, every dwell found, none spurious),
and runs the bare threshold-and-centroid baseline on the same frames in the same process
(ratios of error and of time). Rendering is done up front and never timed. Times are CPU
time of this process (`time.process_time`, OpenCV on one thread), which other jobs on a busy
machine do not inflate; wall-clock figures are printed next to them.

Usage: python benchmarks/vision.py [--quick] [--seed N]
The last line printed is one JSON object with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

# This file is named like the package it measures; run as a script, its own folder would come
# first on sys.path and `import vision` would import this file. Drop that folder.
_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != _HERE]

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from vision.calibration_targets import ChessboardSpec  # noqa: E402
from vision.camera_model import CameraModel  # noqa: E402
from vision.color import DEFAULT_POINTER_RED, ColorProfile  # noqa: E402
from vision.color_calibration import calibrate_from_ellipse  # noqa: E402
from vision.detection import BlobDetector, threshold_centroid, window_around  # noqa: E402
from vision.frame import Frame  # noqa: E402
from vision.geometry import sphere_ray, triangulate  # noqa: E402
from vision.intrinsics import calibrate_chessboard  # noqa: E402
from vision.pointer import PointerParams, PointerSystem  # noqa: E402
from vision.rigs import default_stereo_rig  # noqa: E402
from vision.scene import BackgroundSpec, PointerScene, SensorSpec  # noqa: E402
from vision.scripted import board_poses, render_board_views, simulate_dwell  # noqa: E402
from vision.sources import ReplaySource, synthetic_cameras  # noqa: E402
from vision.trajectories import lissajous  # noqa: E402

CENTRE = np.array([0.3, 0.0, 0.3])


def render(models: list[CameraModel], scene: PointerScene, n: int, seed: int,
           fps: float = 60.0) -> list[list[Frame]]:
    """n frames from every camera (rendering is not part of any timing)."""
    cams = synthetic_cameras(models, scene, seed=seed, fps=fps)
    return [[c.read(1.0) for _ in range(n)] for c in cams]


def run_system(models, frames, profile, params=None):
    sources = [ReplaySource(f, f[0].camera_id) for f in frames]
    system = PointerSystem(sources, models, profile, params)
    states, cpu, wall = [], [], []
    for _ in range(len(frames[0])):
        c0, w0 = time.process_time(), time.perf_counter()
        states.append(system.step())
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return states, np.array(cpu), np.array(wall)


def rms(x) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def calibrated_profile(models, seed) -> ColorProfile:
    """What the operator would do: draw an ellipse over the ball in a live view."""
    f = render(models[:1], PointerScene(CENTRE, background=BackgroundSpec(n_distractors=5)),
               1, seed)[0][0]
    r = f.truth.ball_radius_px
    return calibrate_from_ellipse(f.image, f.truth.ball_px, (0.8 * r, 0.8 * r), 0.0)


def baseline_points(models, frames, profile):
    """Bare threshold-and-centroid per camera, triangulated: None when a view has no pixel."""
    out, cpu = [], []
    for fs in zip(*frames, strict=True):
        c0 = time.process_time()
        cents = [threshold_centroid(f.image, profile) for f in fs]
        if any(c is None for c in cents):
            out.append(None)
        else:
            est = triangulate(models, [sphere_ray(m, c, 0.0) for m, c in zip(models, cents,
                                                                              strict=True)])
            out.append(None if est is None else est.position_world)
        cpu.append(time.process_time() - c0)
    return out, np.array(cpu)


# -- sections -----------------------------------------------------------------------------------
def accuracy(models, profile, n, seed, n_distractors=0):
    """A moving ball (Lissajous, +-20 cm, up to ~0.4 m/s, 4 ms motion blur) over clutter."""
    scene = PointerScene(lissajous(CENTRE, [0.2, 0.2, 0.15]),
                         background=BackgroundSpec(n_distractors=n_distractors))
    frames = render(models, scene, n, seed)
    truth = [f.truth.ball_world for f in frames[0]]

    def errors(states):
        meas = [np.linalg.norm(s.measurement.position_world - g)
                for s, g in zip(states, truth, strict=True) if s.measurement is not None]
        filt = [np.linalg.norm(s.position_world - g) for s, g in
                list(zip(states, truth, strict=True))[10:] if s.measured]
        return meas, filt

    states, _, _ = run_system(models, frames, profile)
    stereo = [s.measurement is not None and s.measurement.mode == "stereo" for s in states]
    meas_st = [e for e, st in zip(errors(states)[0], [s for s in states
                                                       if s.measurement is not None],
                                  strict=True) if st.measurement.mode == "stereo"]
    _, filt = errors(states)
    mono_states, _, _ = run_system(models[:1], frames[:1], profile)
    mono_meas, mono_filt = errors(mono_states)
    base, _ = baseline_points(models, frames, profile)
    base_err = [np.linalg.norm(p - g) for p, g in zip(base, truth, strict=True) if p is not None]
    dist = float(np.mean([np.linalg.norm(g - models[0].position_world) for g in truth]))
    return {
        "frames": n,
        "red_distractors": n_distractors,
        "stereo_fraction": float(np.mean(stereo)),
        "stereo_rms_mm": 1e3 * rms(meas_st),
        "stereo_p95_mm": 1e3 * float(np.percentile(meas_st, 95)),
        "stereo_max_mm": 1e3 * float(np.max(meas_st)),
        "filtered_rms_mm": 1e3 * rms(filt),
        "mono_fraction_measured": len(mono_meas) / n,
        "mono_rms_mm": 1e3 * rms(mono_meas),
        "mono_filtered_rms_mm": 1e3 * rms(mono_filt),
        "mono_rms_percent_of_distance": 100 * rms(mono_meas) / dist,
        "baseline_rms_mm": 1e3 * rms(base_err),
        "baseline_fix_fraction": len(base_err) / n,
    }


def static_points(models, profile, n, seed):
    """Ball held still at random points (no motion blur): pure measurement accuracy."""
    rng = np.random.default_rng(seed)
    pts = CENTRE + rng.uniform(-0.2, 0.2, (n, 3))
    pos = {"p": pts[0]}
    scene = PointerScene(lambda t: pos["p"], background=BackgroundSpec(),
                         sensor=SensorSpec(exposure_s=0.0))
    cams = synthetic_cameras(models, scene, seed=seed)
    det = BlobDetector(profile)
    err = []
    for p in pts:
        pos["p"] = p
        fs = [c.render(0.0) for c in cams]
        ds = [det.detect(f.image) for f in fs]
        if not all(ds):
            continue
        est = triangulate(models, [sphere_ray(m, d[0].center_px, d[0].radius_px)
                                   for m, d in zip(models, ds, strict=True)], 0.15)
        err.append(np.linalg.norm(est.position_world - p))
    return {"points": n, "found": len(err), "stereo_static_rms_mm": 1e3 * rms(err),
            "stereo_static_max_mm": 1e3 * float(np.max(err))}


def throughput(models, profile, n, seed):
    cv2.setNumThreads(1)
    scene = PointerScene(lissajous(CENTRE, [0.2, 0.2, 0.15]),
                         background=BackgroundSpec(n_distractors=10))
    frames = render(models, scene, n, seed)
    imgs = [f.image for f in frames[0]]
    det = BlobDetector(profile)
    reps = max(1, 300 // n)

    def timed(fn):
        c0, w0 = time.process_time(), time.perf_counter()
        for _ in range(reps):
            for k, im in enumerate(imgs):
                fn(k, im)
        m = reps * len(imgs)
        return (time.process_time() - c0) / m, (time.perf_counter() - w0) / m

    full = timed(lambda k, im: det.detect(im))
    windows = [window_around(f.truth.ball_px, 30, 640, 480) for f in frames[0]]
    win = timed(lambda k, im: det.detect(im, windows[k], (3.0, 14.0)))
    base = timed(lambda k, im: threshold_centroid(im, profile))
    states, cpu, wall = run_system(models, frames, profile)
    return {
        "frames": n,
        "detect_full_frame_fps": 1.0 / full[0],
        "detect_full_frame_fps_wall": 1.0 / full[1],
        "detect_locked_window_fps": 1.0 / win[0],
        "baseline_fps": 1.0 / base[0],
        "step_latency_ms_median": 1e3 * float(np.median(cpu[5:])),
        "step_latency_ms_p95": 1e3 * float(np.percentile(cpu[5:], 95)),
        "step_latency_ms_wall_median": 1e3 * float(np.median(wall[5:])),
        "time_ratio_full_vs_baseline": full[0] / base[0],
    }


def occlusion(models, profile, trials, seed):
    """Ball hidden for 0.5 s mid-motion: is the same track still there when it reappears?"""
    out = []
    for k in range(trials):
        phase = np.random.default_rng(seed + k).uniform(0, 2 * np.pi, 3)
        scene = PointerScene(lissajous(CENTRE, [0.15, 0.15, 0.1], phase=phase),
                             hidden=[(0.6, 1.1)], background=BackgroundSpec(n_distractors=5))
        frames = render(models, scene, 90, seed + 10 * k)
        states, _, _ = run_system(models, frames, profile)
        during = [s for s in states if 0.6 <= s.timestamp < 1.1]
        after = [s for s in states if s.timestamp >= 1.1]
        before_id = [s.track_id for s in states if s.timestamp < 0.6][-1]
        reacq = next((i for i, s in enumerate(after) if s.measured), None)
        drift = max(np.linalg.norm(s.position_world - s.cameras["cam0"].frame.truth.ball_world)
                    for s in during if s.position_world is not None)
        out.append({
            "held": all(s.position_world is not None for s in during),
            "same_track": reacq is not None and after[reacq].track_id == before_id,
            "reacquire_frames": reacq,
            "coast_drift_mm": 1e3 * drift,
        })
    return {
        "trials": trials,
        "held_fraction": float(np.mean([o["held"] for o in out])),
        "same_track_fraction": float(np.mean([o["same_track"] for o in out])),
        "reacquire_frames_max": max(999 if o["reacquire_frames"] is None
                                    else o["reacquire_frames"] for o in out),
        "coast_drift_mm_max": max(o["coast_drift_mm"] for o in out),
    }


def false_detections(models, profile, n, seed):
    """Clutter with 20 red/orange look-alikes per view; half the frames have no ball."""
    det = BlobDetector(profile)
    res = {"frames_per_camera": 2 * n}
    counts = {"det_false": 0, "pipe_false": 0, "base_false": 0, "pipe_fix_absent": 0,
              "det_miss": 0, "views": 0}
    for part, ball in (("absent", None), ("present", lissajous(CENTRE, [0.2, 0.2, 0.15]))):
        scene = PointerScene(ball, background=BackgroundSpec(n_distractors=20))
        frames = render(models, scene, n, seed + (0 if ball is None else 1))
        states, _, _ = run_system(models, frames, profile)
        for cam_frames in frames:
            for f in cam_frames:
                counts["views"] += 1
                ds = det.detect(f.image)
                near = [d for d in ds if f.truth.visible
                        and np.linalg.norm(d.center_px - f.truth.ball_px) < 3.0]
                counts["det_false"] += len(ds) - len(near)
                counts["det_miss"] += f.truth.visible and not near
                c = threshold_centroid(f.image, profile)
                if c is not None and not (f.truth.visible and
                                          np.linalg.norm(c - f.truth.ball_px) < 3.0):
                    counts["base_false"] += 1
        for s in states:
            for v in s.cameras.values():
                if v.pointer is not None and not (v.frame.truth.visible and np.linalg.norm(
                        v.pointer.center_px - v.frame.truth.ball_px) < 3.0):
                    counts["pipe_false"] += 1
            if part == "absent" and s.measured:
                counts["pipe_fix_absent"] += 1
    views = counts["views"]
    res.update({
        "detector_false_per_frame": counts["det_false"] / views,
        "detector_miss_rate": counts["det_miss"] / (views / 2),
        "pipeline_false_per_frame": counts["pipe_false"] / views,
        "pipeline_3d_fix_without_ball": counts["pipe_fix_absent"],
        "baseline_false_per_frame": counts["base_false"] / views,
    })
    return res


def calibration(seed):
    true = CameraModel.from_fov(640, 480, 60.0, dist=[-0.12, 0.05, 0.0005, -0.0003, 0.0])
    spec = ChessboardSpec(9, 6, 0.025)
    tex, w, h = spec.texture()
    imgs = render_board_views(true, [spec.target(T) for T in board_poses(true, w, h, 12,
                                                                          seed=seed)],
                              seed=seed)
    res = calibrate_chessboard(imgs, spec)
    return {"views_used": res.n_views, "reprojection_rms_px": res.rms_px,
            "focal_error_percent": 100 * abs(res.K[0, 0] / true.K[0, 0] - 1),
            "principal_point_error_px": float(np.linalg.norm(res.K[:2, 2] - true.K[:2, 2]))}


def dwell(models, n, seed):
    rng = np.random.default_rng(seed)
    errs, unc = [], []
    for k in range(n):
        target = CENTRE + rng.uniform(-0.15, 0.15, 3)
        tp = simulate_dwell(models, target, seed=seed + k)
        errs.append(np.linalg.norm(tp.position_world - target))
        unc.append(tp.uncertainty)
    return {"dwells": n, "taught_error_rms_mm": 1e3 * rms(errs),
            "taught_error_max_mm": 1e3 * float(np.max(errs)),
            "reported_uncertainty_mm_mean": 1e3 * float(np.mean(unc))}


def honesty(models, profile, seed, photos, quick):
    """Issue 33 figures: real-photo sequences (operator's ellipse calibration, 1.3x the ball)
    and the rendered dwell scene with the same script, scored by
    `cellteach_testing.pointer_scoring`."""
    from cellteach_testing.photo_scenes import operator_calibration, photo_sequence
    from cellteach_testing.pointer_scoring import combine, score_run

    runs = {}
    for name in photos:
        seq = photo_sequence(name, models, CENTRE, seed=seed, fps=30 if quick else 60)
        cal, _ = operator_calibration(seq)
        states, cpu, _ = run_system(models, seq.frames, cal.profile)
        runs[name] = score_run(states, seq.holds)
        runs[name]["profile"] = cal.profile.to_dict()
        # CPU time of one step (both cameras), with the appearance matcher where it runs
        runs[name]["step_cpu_ms_p95"] = 1e3 * float(np.percentile(cpu, 95))
    pooled = combine(list(runs.values()))
    pooled["step_cpu_ms_p95_worst"] = max(r["step_cpu_ms_p95"] for r in runs.values())
    return {"per_photo": runs, "pooled": pooled,
            "targets_met": {"rms_le_1mm": pooled["rms_mm"] <= 1.0,
                            "max_le_10mm": pooled["max_mm"] <= 10.0,
                            "measured_ge_98pct": pooled["measured_fraction"] >= 0.98,
                            "all_dwells_found": pooled["dwells_found"] == pooled["dwells"],
                            "no_spurious_dwell": pooled["dwells_spurious"] == 0}}


def rendered_honesty(models, profile, seed, quick):
    """The same scoring on a rendered sequence (cluttered grey wall, 20 red/orange
    look-alikes, occlusion, exposure drift, three dwells)."""
    from cellteach_testing.pointer_scoring import score_run
    from vision.trajectories import waypoints

    rng = np.random.default_rng(seed)
    pts = [CENTRE + rng.uniform(-0.12, 0.12, 3) for _ in range(4)]
    holds_t, moves = [0.2, 1.6, 1.6, 1.6], [0.7, 1.2, 0.7]
    path = waypoints(pts, moves, holds_t, tremor=0.0003, seed=seed)
    t, holds = 0.9, []
    from cellteach_testing.photo_scenes import Hold
    for k in range(3):
        holds.append(Hold(t, t + 1.6, pts[k + 1]))
        t += 1.6 + (moves[k + 1] if k < 2 else 0)
    hidden = [(2.5 + 0.35, 2.5 + 0.85)]
    scene = PointerScene(path, hidden=hidden, background=BackgroundSpec(n_distractors=20),
                         sensor=SensorSpec(gain=lambda tt: 1.0 + 0.2 * np.sin(1.6 * tt)))
    fps = 30 if quick else 60
    frames = render(models, scene, int((t + 0.1) * fps), seed, fps=fps)
    states, _, _ = run_system(models, frames, profile)
    return score_run(states, holds)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sample sizes (< 1 min)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--no-photos", action="store_true",
                    help="skip the real-photo sequences (they need scikit-image)")
    args = ap.parse_args()
    q = args.quick
    t0 = time.perf_counter()
    cv2.setNumThreads(1)
    models = default_stereo_rig(CENTRE, distance=1.0, baseline=0.5, fov_deg=60, size=(640, 480))
    profile = calibrated_profile(models, args.seed)
    print(f"colour profile from an ellipse over the ball: {profile}")
    out: dict = {"rig": "2 x 640x480, 60 deg FOV, 1 m, 0.5 m baseline", "quick": q}
    sections = [
        ("accuracy", lambda: accuracy(models, profile, 90 if q else 600, args.seed)),
        ("accuracy_red_clutter", lambda: accuracy(models, profile, 90 if q else 600,
                                                  args.seed + 1, n_distractors=10)),
        ("static", lambda: static_points(models, profile, 30 if q else 200, args.seed)),
        ("throughput", lambda: throughput(models, profile, 30 if q else 120, args.seed)),
        ("occlusion", lambda: occlusion(models, profile, 2 if q else 10, args.seed)),
        ("false_detections", lambda: false_detections(models, profile, 30 if q else 250,
                                                      args.seed)),
        ("calibration", lambda: calibration(args.seed)),
        ("dwell", lambda: dwell(models, 1 if q else 5, args.seed)),
        ("honesty_rendered", lambda: rendered_honesty(models, profile, args.seed, q)),
    ]
    if not args.no_photos:
        from cellteach_testing.photo_scenes import HELD_OUT_PHOTOS, TUNED_PHOTOS
        sections += [
            ("honesty_photos_tuned", lambda: honesty(models, profile, 1, TUNED_PHOTOS, q)),
            ("honesty_photos_held_out", lambda: honesty(models, profile, 1, HELD_OUT_PHOTOS,
                                                        q)),
        ]
    for name, fn in sections:
        ts = time.perf_counter()
        out[name] = fn()
        shown = out[name].get("pooled", out[name])
        print(f"{name:17s} ({time.perf_counter() - ts:5.1f} s) "
              + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                          for k, v in shown.items()))
    acc, thr, fd = out["accuracy"], out["throughput"], out["false_detections"]
    out["targets"] = {
        "stereo_rms_le_2mm": acc["stereo_rms_mm"] <= 2.0,
        "throughput_ge_300fps": thr["detect_full_frame_fps"] >= 300.0,
        "false_detections_le_1pct": fd["pipeline_false_per_frame"] <= 0.01,
        "occlusion_same_track": out["occlusion"]["same_track_fraction"] == 1.0,
    }
    red = out["accuracy_red_clutter"]
    views = 2 * fd["frames_per_camera"]
    out["vs_baseline"] = {
        "error_ratio_baseline_over_full": acc["baseline_rms_mm"] / acc["stereo_rms_mm"],
        "error_ratio_baseline_over_full_red_clutter": red["baseline_rms_mm"]
        / red["stereo_rms_mm"],
        "time_ratio_full_over_baseline": thr["time_ratio_full_vs_baseline"],
        # with no false detection at all, the ratio is only bounded: one in `views` at most
        "false_ratio_baseline_over_full_at_least": fd["baseline_false_per_frame"]
        / max(fd["pipeline_false_per_frame"], 1.0 / views),
    }
    out["default_profile"] = DEFAULT_POINTER_RED.to_dict()
    out["elapsed_s"] = time.perf_counter() - t0
    out["params"] = {"centre_sigma_px": PointerParams().centre_sigma_px,
                     "hold_s": PointerParams().hold_s}
    print(json.dumps(out, default=float))


if __name__ == "__main__":
    main()
