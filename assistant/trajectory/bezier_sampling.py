"""Cubic Bezier chains sampled by chord error, with De Casteljau subdivision.

The source cell (000) evaluated free-shape paths at a fixed parameter step (dt 0.5 ... 0.02,
3 ... 51 points per segment) and never measured how far the robot's straight moves between
the points strayed from the curve. Here each chord is made as long as the tolerance allows
(sub-curves cut out with De Casteljau), so flat stretches get few points and tight bends
many, and the achieved maximum deviation is reported. The chord error of a piece is computed
exactly: the distance from the curve to its chord segment is piecewise the root of a
polynomial in t, so its maximum sits at a root of one of a few derivative polynomials.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as npoly

Array = np.ndarray


@dataclass(frozen=True)
class BezierSampling:
    """Polyline through the curve: points (M, 3), their chain parameters (segment index + t)."""

    points: Array
    params: Array
    #: Largest distance of the curve from the polyline (m), exact per piece.
    max_deviation: float
    #: True if the point budget or the parameter resolution stopped a piece early.
    depth_limited: bool = False


def de_casteljau(ctrl: Array, t: float) -> tuple[Array, Array, Array]:
    """Point at t and the two halves' control points (left, right) of a cubic."""
    p = np.asarray(ctrl, dtype=float)
    a = (1 - t) * p[:-1] + t * p[1:]
    b = (1 - t) * a[:-1] + t * a[1:]
    c = (1 - t) * b[:-1] + t * b[1:]
    left = np.stack([p[0], a[0], b[0], c[0]])
    right = np.stack([c[0], b[1], a[2], p[3]])
    return c[0], left, right


def evaluate(ctrl: Array, t: Array | float) -> Array:
    """Points of a cubic Bezier at parameters t (Bernstein form)."""
    p = np.asarray(ctrl, dtype=float)
    t = np.asarray(t, dtype=float)[..., None]
    s = 1.0 - t
    return s ** 3 * p[0] + 3 * s * s * t * p[1] + 3 * s * t * t * p[2] + t ** 3 * p[3]


def chord_error(ctrl: Array) -> float:
    """Exact largest distance of a cubic Bezier piece from the segment joining its ends."""
    p = np.asarray(ctrl, dtype=float)
    # Power basis of B(t) - p0, lowest degree first, one column per axis.
    coef = np.stack([np.zeros(3), 3 * (p[1] - p[0]), 3 * (p[0] - 2 * p[1] + p[2]),
                     -p[0] + 3 * p[1] - 3 * p[2] + p[3]])
    chord = p[3] - p[0]
    L = float(np.linalg.norm(chord))
    cands = [0.0, 1.0]

    def sq_norm(c: Array) -> Array:
        return sum(np.convolve(c[:, k], c[:, k]) for k in range(3))

    def crit(poly: Array) -> None:
        d = npoly.polyder(poly)
        if np.any(np.abs(d) > 0):
            for r in np.roots(d[::-1]) if len(d) > 1 else []:
                if abs(r.imag) < 1e-9 and 0.0 <= r.real <= 1.0:
                    cands.append(float(r.real))

    inside = False
    if L > 1e-12:
        u = chord / L
        proj = (p - p[0]) @ u
        # Convex hull: if every control point projects onto the chord, so does the curve,
        # and only the perpendicular distance matters.
        inside = bool(proj.min() >= 0.0 and proj.max() <= L)
    if not inside:
        crit(sq_norm(coef))  # distance to p0
        end = coef.copy()
        end[0] -= chord
        crit(sq_norm(end))  # distance to p3
    if L > 1e-12:
        s_poly = coef @ u  # projection along the chord (m)
        perp = coef - np.outer(s_poly, u)
        crit(sq_norm(perp))
        for level in (() if inside else (0.0, L)):
            q = s_poly.copy()
            q[0] -= level
            for r in np.roots(q[::-1]) if np.any(np.abs(q[1:]) > 0) else []:
                if abs(r.imag) < 1e-9 and 0.0 <= r.real <= 1.0:
                    cands.append(float(r.real))
    t = np.array(cands)
    pts = evaluate(p, t) - p[0]
    if L <= 1e-12:
        return float(np.linalg.norm(pts, axis=1).max())
    u = chord / L
    s = np.clip(pts @ u, 0.0, L)
    return float(np.linalg.norm(pts - s[:, None] * u, axis=1).max())


def sample_cubic_bezier(ctrl: Array, tolerance: float, *, max_points: int = 2000,
                        resolution: float = 1e-4, segment_index: int = 0) -> BezierSampling:
    """Adaptive polyline of one cubic within `tolerance` (m) of the curve.

    Greedy farthest reach: from each chosen parameter, the largest next parameter whose
    sub-curve (De Casteljau) has a chord error within the tolerance is found by bisection
    to `resolution` in t. Chord error grows as a piece is extended, so this greedy uses the
    fewest points (up to that resolution). `max_points` is the budget; hitting it is
    reported through `depth_limited`.
    """
    if tolerance <= 0.0:
        raise ValueError("tolerance must be positive")
    ctrl = np.asarray(ctrl, dtype=float)
    if ctrl.shape != (4, 3):
        raise ValueError(f"a cubic Bezier needs 4 control points (x, y, z), got {ctrl.shape}")
    ts = [0.0]
    worst = 0.0
    limited = False
    while ts[-1] < 1.0:
        t0 = ts[-1]
        if len(ts) >= max_points:
            limited = True
            worst = max(worst, chord_error(sub_curve(ctrl, t0, 1.0)))
            ts.append(1.0)
            break
        err = chord_error(sub_curve(ctrl, t0, 1.0))
        if err <= tolerance:
            worst = max(worst, err)
            ts.append(1.0)
            break
        lo, hi = t0, 1.0  # chord error at hi exceeds the tolerance
        lo_err = 0.0
        while hi - lo > resolution:
            mid = 0.5 * (lo + hi)
            e = chord_error(sub_curve(ctrl, t0, mid))
            if e <= tolerance:
                lo, lo_err = mid, e
            else:
                hi = mid
        if lo <= t0:  # tolerance below what the resolution can resolve
            lo, lo_err = hi, chord_error(sub_curve(ctrl, t0, hi))
            limited = limited or lo_err > tolerance
        worst = max(worst, lo_err)
        ts.append(lo)
    t = np.array(ts)
    return BezierSampling(evaluate(ctrl, t), segment_index + t, worst, limited)


def sample_bezier_chain(segments: Sequence[Array], tolerance: float) -> BezierSampling:
    """Sample consecutive cubics (each (4, 3)); shared end points appear once."""
    if not segments:
        raise ValueError("no Bezier segments")
    parts = [sample_cubic_bezier(c, tolerance, segment_index=i)
             for i, c in enumerate(segments)]
    points = np.concatenate([parts[0].points] + [p.points[1:] for p in parts[1:]])
    params = np.concatenate([parts[0].params] + [p.params[1:] for p in parts[1:]])
    return BezierSampling(points, params, max(p.max_deviation for p in parts),
                          any(p.depth_limited for p in parts))


def fixed_step_samples(ctrl: Array, dt: float) -> Array:
    """The source's fixed parameter step (for comparison): points at t = 0, dt, ..., 1."""
    n = max(1, int(round(1.0 / dt)))
    return evaluate(ctrl, np.linspace(0.0, 1.0, n + 1))


def polyline_deviation(ctrl: Array, ts: Array) -> float:
    """Exact max distance of the curve from the polyline through B(ts) (sorted t's)."""
    ctrl = np.asarray(ctrl, dtype=float)
    worst = 0.0
    for a, b in zip(ts[:-1], ts[1:], strict=True):
        worst = max(worst, chord_error(sub_curve(ctrl, float(a), float(b))))
    return worst


def sub_curve(ctrl: Array, t0: float, t1: float) -> Array:
    """Control points of the piece of a cubic between t0 and t1."""
    _, _, right = de_casteljau(ctrl, t0)
    if t1 >= 1.0 or t0 >= 1.0:
        return right
    _, left, _ = de_casteljau(right, (t1 - t0) / (1.0 - t0))
    return left
