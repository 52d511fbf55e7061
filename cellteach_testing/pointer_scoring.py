"""Scoring a pointer run against ground truth: the figures issue 33 asks for.

Given the `PointerState`s of a run over rendered frames (which carry `GroundTruth`) and the
script's holds, reports:
  * error of every offered position (`PointerState.offered_position`: what may be taught):
    RMS, p95, max, and RMS of the stereo ones;
  * measurable frames (every camera sees the whole ball) and how many of them were not measured;
    of those missed, how many came before the ball first moved `still_start_m` from where it
    was first seen (a new track is offered only once it moves, `PointerParams.new_track_travel`:
    a still look-alike never does), and the measured share without them;
  * how many offered positions used a view found by its look (`Detection.method ==
    "appearance"`: the ball merged with a region of its colour there) or by its outline
    (`"outline"`), and their error;
  * false positions: offered while no camera sees the ball, or more than `false_m` off;
  * coasting: longest run flagged coasting, and whether any coasting state offered a position;
  * dwells: found (a taught point within `dwell_match_m` of a hold, while or just after it is
    held), spurious (any other taught point), and the error of the found ones.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vision.pointer import PointerState


def _rms(x: Sequence[float]) -> float:
    a = np.asarray(x, float)
    return float(np.sqrt(np.mean(a**2))) if a.size else float("nan")


def _share(frames: int, missed: int) -> float:
    return (frames - missed) / frames if frames else float("nan")


def _whole_in_view(frame) -> bool:
    """The ball is drawn and wholly inside the image (a ball cut by the image edge has no
    measurable centre, so such frames do not count as measurable)."""
    g = frame.truth
    if g is None or not g.visible or g.ball_px is None:
        return False
    h, w = frame.image.shape[:2]
    m = g.ball_radius_px + 2.0
    return bool(m <= g.ball_px[0] <= w - 1 - m and m <= g.ball_px[1] <= h - 1 - m)


def score_run(states: Sequence[PointerState], holds: Sequence, *,
              false_m: float = 0.010, dwell_match_m: float = 0.005,
              late_s: float = 0.3, still_start_m: float = 0.015) -> dict:
    """Figures of one run (metres inside, millimetres in the keys that say so); `holds` are
    `photo_scenes.Hold`s (anything with t0, t1 and point)."""
    errs, stereo_errs, matched_errs, outline_errs = [], [], [], []
    measurable = missed = false = offered_unseen = 0
    coast_run, coast_max, coast_offered = 0.0, 0.0, 0
    last_t: float | None = None
    first_seen: np.ndarray | None = None
    missed_still = 0
    for s in states:
        views = [v.frame.truth for v in s.cameras.values() if v.frame is not None]
        whole = [_whole_in_view(v.frame) for v in s.cameras.values() if v.frame is not None]
        seen_all = bool(views) and all(whole)
        seen_any = any(g is not None and g.visible for g in views)
        truth = next((g.ball_world for g in views if g is not None), None)
        p = s.offered_position
        if seen_all and len(views) == len(s.cameras):
            measurable += 1
            missed += p is None
            if first_seen is None:
                first_seen = truth
            if p is None and np.linalg.norm(truth - first_seen) < still_start_m:
                missed_still += 1
        if p is not None:
            if not seen_any or truth is None:
                offered_unseen += 1
                false += 1
            else:
                e = float(np.linalg.norm(p - truth))
                errs.append(e)
                if s.mode == "stereo":
                    stereo_errs.append(e)
                methods = {v.pointer.method for v in s.cameras.values()
                           if v.pointer is not None}
                if "appearance" in methods:
                    matched_errs.append(e)
                if "outline" in methods:
                    outline_errs.append(e)
                false += e > false_m
        dt = 0.0 if last_t is None else s.timestamp - last_t
        last_t = s.timestamp
        if s.coasting:
            coast_run += dt
            coast_max = max(coast_max, coast_run)
            coast_offered += p is not None
        else:
            coast_run = 0.0
    found, spurious, taught_err = 0, 0, []
    matched: set[int] = set()
    for s in states:
        if s.taught is None:
            continue
        hit = None
        for k, h in enumerate(holds):
            if k not in matched and h.t0 <= s.timestamp <= h.t1 + late_s and \
                    np.linalg.norm(s.taught.position_world - h.point) <= dwell_match_m:
                hit = k
                break
        if hit is None:
            spurious += 1
        else:
            matched.add(hit)
            found += 1
            taught_err.append(float(np.linalg.norm(s.taught.position_world
                                                   - holds[hit].point)))
    return {
        "frames": len(states),
        "offered": len(errs) + offered_unseen,
        "rms_mm": 1e3 * _rms(errs),
        "stereo_rms_mm": 1e3 * _rms(stereo_errs),
        "p95_mm": 1e3 * float(np.percentile(errs, 95)) if errs else float("nan"),
        "max_mm": 1e3 * float(np.max(errs)) if errs else float("nan"),
        "offered_with_appearance": len(matched_errs),
        "appearance_rms_mm": 1e3 * _rms(matched_errs),
        "appearance_max_mm": 1e3 * float(np.max(matched_errs)) if matched_errs else float("nan"),
        "offered_with_outline": len(outline_errs),
        "outline_max_mm": 1e3 * float(np.max(outline_errs)) if outline_errs else float("nan"),
        "measurable_frames": measurable,
        "missed_measurable": missed,
        "measured_fraction": (measurable - missed) / measurable if measurable else float("nan"),
        "missed_before_first_move": missed_still,
        "measured_fraction_after_first_move": _share(measurable - missed_still, missed
                                                     - missed_still),
        "false_offered": false,
        "offered_while_unseen": offered_unseen,
        "coast_max_s": coast_max,
        "coasting_offered": coast_offered,
        "dwells": len(holds),
        "dwells_found": found,
        "dwells_spurious": spurious,
        "dwell_error_max_mm": 1e3 * max(taught_err) if taught_err else float("nan"),
    }


def combine(results: Sequence[dict]) -> dict:
    """Pooled figures over several runs (RMS pooled by offered counts, maxima of maxima)."""
    n = [r["offered"] for r in results]
    pooled = np.sqrt(sum(k * r["rms_mm"] ** 2 for k, r in zip(n, results, strict=True)
                         if k) / max(sum(n), 1))
    meas = sum(r["measurable_frames"] for r in results)
    missed = sum(r["missed_measurable"] for r in results)
    still = sum(r["missed_before_first_move"] for r in results)
    return {
        "runs": len(results),
        "rms_mm": float(pooled),
        "p95_mm_worst": max(r["p95_mm"] for r in results),
        "max_mm": max(r["max_mm"] for r in results),
        "measurable_frames": meas,
        "missed_measurable": missed,
        "measured_fraction": (meas - missed) / meas if meas else float("nan"),
        "missed_before_first_move": still,
        "measured_fraction_after_first_move": _share(meas - still, missed - still),
        "false_offered": sum(r["false_offered"] for r in results),
        "offered_with_appearance": sum(r.get("offered_with_appearance", 0) for r in results),
        "coast_max_s": max(r["coast_max_s"] for r in results),
        "coasting_offered": sum(r["coasting_offered"] for r in results),
        "dwells": sum(r["dwells"] for r in results),
        "dwells_found": sum(r["dwells_found"] for r in results),
        "dwells_spurious": sum(r["dwells_spurious"] for r in results),
    }
