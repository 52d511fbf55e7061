"""Candidate 3-D fixes of one frame: every pair of views that triangulates consistently (at
the ball's size for that distance), for `PointerSystem` to choose from."""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from vision.camera_model import CameraModel
from vision.detection import Detection
from vision.geometry import PointEstimate, expected_radius_px, sphere_ray, triangulate
from vision.pointer_types import PointerParams


@dataclass
class Hypothesis:
    """One candidate 3-D fix and the detection it uses in each camera."""

    est: PointEstimate
    used: dict[int, int]  # camera index -> detection index


def size_ok(models: Sequence[CameraModel], params: PointerParams, X: np.ndarray,
            used: dict[int, int], dets: dict[int, list[Detection]]) -> float | None:
    """Worst |log| ratio of seen to expected apparent radius, None if out of range."""
    lo, hi = params.size_ratio_range
    worst = 0.0
    for i, j in used.items():
        r_exp = expected_radius_px(models[i], X, params.ball_radius)
        ratio = dets[i][j].radius_px / r_exp if np.isfinite(r_exp) else 0.0
        if not lo <= ratio <= hi:
            return None
        worst = max(worst, abs(np.log(ratio)))
    return worst


def stereo_hypotheses(models: Sequence[CameraModel], params: PointerParams,
                      dets: dict[int, list[Detection]]) -> list[Hypothesis]:
    """Every pair of views (one candidate per camera) that triangulates within the
    reprojection gate at a plausible size, with agreeing views of further cameras added."""
    p = params
    k = p.max_candidates_per_camera
    rays = {(i, j): sphere_ray(models[i], d.center_px, d.radius_px)
            for i, ds in dets.items() for j, d in enumerate(ds[:k])}
    cams = sorted(i for i in dets if dets[i])
    out: list[Hypothesis] = []
    seen: set[frozenset] = set()
    for a, b in itertools.combinations(cams, 2):
        for ja, jb in itertools.product(range(min(k, len(dets[a]))),
                                        range(min(k, len(dets[b])))):
            used = {a: ja, b: jb}
            est = _triangulate(models, params, used, rays)
            if est is None:
                continue
            for c in cams:  # add agreeing views from further cameras
                if c in used:
                    continue
                uv = models[c].project(est.position_world)
                best = min(range(min(k, len(dets[c]))),
                           key=lambda j, c=c, uv=uv: np.linalg.norm(dets[c][j].center_px - uv),
                           default=None)
                if best is not None and np.linalg.norm(dets[c][best].center_px - uv) \
                        <= 2 * p.reprojection_gate_px:
                    more = _triangulate(models, params, {**used, c: best}, rays)
                    if more is not None:
                        used, est = {**used, c: best}, more
            key = frozenset(used.items())
            if key in seen or size_ok(models, params, est.position_world, used, dets) is None:
                continue
            seen.add(key)
            out.append(Hypothesis(est, used))
    return out


def _triangulate(models: Sequence[CameraModel], params: PointerParams, used: dict[int, int],
                 rays: dict) -> PointEstimate | None:
    idx = sorted(used)
    est = triangulate([models[i] for i in idx], [rays[(i, used[i])] for i in idx],
                      params.centre_sigma_px)
    if est is None or est.reprojection_px > params.reprojection_gate_px:
        return None
    return dataclasses.replace(est, cameras=tuple(idx))
