"""Free-shape paths as chained cubic Bezier segments (source 000), sampled by chord error.

The source evaluated each segment inside the KUKA controller with De Casteljau at a fixed
parameter step (dt = 0.05 -> 21 points per segment) and moved linearly between the points;
it never measured how far those chords are from the curve. Here a segment is cut where the
chord error would exceed a tolerance, using a certified bound (the curve lies in the convex
hull of its control points), so flat parts get two points and tight corners many; the
achieved maximum deviation is then measured densely and reported with the point count.

Chains are C0 by construction (checked); C1 (equal derivatives at the joints) can be checked
and enforced. Points may be 2-D (a drawing on paper) or 3-D (metres in the base frame).
`sample_bezier_chain(segments, tol) -> BezierSampling` is the stable entry point the
trajectory planner imports.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from assistant.transforms import angle_between

Array = np.ndarray

#: Samples per chord used to measure the achieved deviation.
DENSE_SAMPLES = 64


def de_casteljau(control: Array, t: Array | float) -> Array:
    """Points of the Bezier curve with these control points at parameter(s) t.

    The source's algorithm: repeated linear interpolation of the control polygon (six for a
    cubic); numerically stable for any degree. Returns shape (len(t), dim) or (dim,).
    """
    P = np.asarray(control, dtype=float)
    scalar = np.ndim(t) == 0
    ts = np.atleast_1d(np.asarray(t, dtype=float))[:, None, None]
    pts = np.broadcast_to(P, (ts.shape[0],) + P.shape).copy()
    for _ in range(1, len(P)):
        pts = (1.0 - ts) * pts[:, :-1] + ts * pts[:, 1:]
    out = pts[:, 0]
    return out[0] if scalar else out


@dataclass(frozen=True)
class CubicBezier:
    """One cubic segment: start, two handles, end (shape (4, dim))."""

    control: Array

    def __post_init__(self) -> None:
        c = np.asarray(self.control, dtype=float)
        if c.ndim != 2 or c.shape[0] != 4 or c.shape[1] not in (2, 3):
            raise ValueError(f"a cubic Bezier needs 4 control points in 2-D or 3-D, got "
                             f"{c.shape}")
        if not np.all(np.isfinite(c)):
            raise ValueError("Bezier control points must be finite")
        object.__setattr__(self, "control", c)

    @property
    def start(self) -> Array:
        return self.control[0]

    @property
    def end(self) -> Array:
        return self.control[3]

    def point(self, t: Array | float) -> Array:
        return de_casteljau(self.control, t)

    def derivative(self, t: Array | float) -> Array:
        """dB/dt (a quadratic Bezier of the control differences times 3)."""
        return 3.0 * de_casteljau(np.diff(self.control, axis=0), t)

    def split(self, t: float) -> tuple[CubicBezier, CubicBezier]:
        """The two halves at t (De Casteljau's intermediate points are their controls)."""
        P = self.control
        a = (1 - t) * P[:-1] + t * P[1:]
        b = (1 - t) * a[:-1] + t * a[1:]
        c = (1 - t) * b[0] + t * b[1]
        return (CubicBezier(np.array([P[0], a[0], b[0], c])),
                CubicBezier(np.array([c, b[1], a[2], P[3]])))

    def sub(self, t0: float, t1: float) -> CubicBezier:
        """The piece between parameters t0 < t1: its controls are the blossoms
        b(t0,t0,t0), b(t0,t0,t1), b(t0,t1,t1), b(t1,t1,t1) (De Casteljau with mixed t)."""
        if t0 <= 0.0 and t1 >= 1.0:
            return self
        P = self.control
        return CubicBezier(np.array([_blossom(P, t0, t0, t0), _blossom(P, t0, t0, t1),
                                     _blossom(P, t0, t1, t1), _blossom(P, t1, t1, t1)]))

    def chord_error_bound(self) -> float:
        """Certified upper bound of the distance from the curve to its chord (segment).

        If every control point projects inside the chord, so does the curve (convex hull)
        and the distance to the segment is the distance to its line: the perpendicular
        offsets u1, u2 of the handles give |d(t)| <= 3t(1-t)^2 |u1| + 3t^2(1-t) |u2|.
        Otherwise B(t) is compared with the chord point (1-t) P0 + t P3 (degree-elevated
        to handles at 1/3 and 2/3), which bounds the distance to the segment from above.
        """
        P = self.control
        d = P[3] - P[0]
        L2 = float(d @ d)
        if L2 < 1e-24:
            return float(max(np.linalg.norm(P[1] - P[0]), np.linalg.norm(P[2] - P[0])))
        s = ((P[1:3] - P[0]) @ d) / L2
        if np.all(s >= 0.0) and np.all(s <= 1.0):
            perp = (P[1:3] - P[0]) - s[:, None] * d
            a, b = np.linalg.norm(perp, axis=1)
        else:
            a = float(np.linalg.norm(P[1] - (2 * P[0] + P[3]) / 3.0))
            b = float(np.linalg.norm(P[2] - (P[0] + 2 * P[3]) / 3.0))
        return _max_bernstein_mix(float(a), float(b))

    def transformed(self, T: Array) -> CubicBezier:
        """3-D copy under a rigid transform (2-D points are placed at z = 0 first)."""
        return CubicBezier(_apply(T, self.control))


def _blossom(P: Array, u: float, v: float, w: float) -> Array:
    a = (1 - u) * P[:-1] + u * P[1:]
    b = (1 - v) * a[:-1] + v * a[1:]
    return (1 - w) * b[0] + w * b[1]


def _max_bernstein_mix(a: float, b: float) -> float:
    """max over t in [0,1] of 3t(1-t)^2 a + 3t^2(1-t) b (roots of the derivative)."""
    # f(t) = 3a t - 6a t^2 + 3a t^3 + 3b t^2 - 3b t^3
    c3, c2, c1 = 3 * a - 3 * b, -6 * a + 3 * b, 3 * a
    cands = [0.0, 1.0]
    roots = np.roots([3 * c3, 2 * c2, c1]) if abs(c3) > 1e-300 else (
        [-c1 / (2 * c2)] if abs(c2) > 1e-300 else [])
    cands += [float(r.real) for r in np.atleast_1d(roots)
              if abs(np.imag(r)) < 1e-12 and 0.0 <= r.real <= 1.0]
    return max(c3 * t ** 3 + c2 * t ** 2 + c1 * t for t in cands)


def _apply(T: Array, pts: Array) -> Array:
    P = np.asarray(pts, dtype=float)
    if P.shape[1] == 2:
        P = np.c_[P, np.zeros(len(P))]
    return P @ np.asarray(T, dtype=float)[:3, :3].T + np.asarray(T, dtype=float)[:3, 3]


@dataclass(frozen=True)
class BezierChain:
    """Consecutive cubic segments, each starting where the previous ended (C0)."""

    segments: tuple[CubicBezier, ...]
    name: str = ""

    def __post_init__(self) -> None:
        segs = tuple(s if isinstance(s, CubicBezier) else CubicBezier(np.asarray(s))
                     for s in self.segments)
        if not segs:
            raise ValueError("a Bezier chain needs at least one segment")
        dims = {s.control.shape[1] for s in segs}
        if len(dims) != 1:
            raise ValueError("all segments of a chain must have the same dimension")
        scale = max(float(np.ptp(np.vstack([s.control for s in segs]), axis=0).max()), 1e-12)
        for i in range(1, len(segs)):
            gap = float(np.linalg.norm(segs[i].start - segs[i - 1].end))
            if gap > 1e-9 * scale:
                raise ValueError(f"segment {i + 1} does not start where segment {i} ends "
                                 f"(gap {gap:.3g}): the chain is not C0")
        object.__setattr__(self, "segments", segs)

    @staticmethod
    def from_flat(values: Sequence[float], *, scale: float = 1.0, name: str = "") -> BezierChain:
        """The source's KRL data layout: x0, y0, then (x1, y1, x2, y2, x3, y3) per segment."""
        v = np.asarray(values, dtype=float) * scale
        if len(v) < 8 or (len(v) - 2) % 6:
            raise ValueError("flat Bezier data must hold 2 + 6n numbers")
        pts = v.reshape(-1, 2)
        segs = [CubicBezier(pts[3 * i:3 * i + 4]) for i in range((len(pts) - 1) // 3)]
        return BezierChain(tuple(segs), name)

    def to_flat(self) -> Array:
        pts = [self.segments[0].start] + [p for s in self.segments for p in s.control[1:]]
        return np.asarray(pts)[:, :2].ravel()

    def transformed(self, T: Array) -> BezierChain:
        return BezierChain(tuple(s.transformed(T) for s in self.segments), self.name)

    def c1_defects(self, tol: float = 1e-9, *, geometric: bool = False) -> list[int]:
        """Indices j of joints (between segment j-1 and j) where the derivatives differ.

        `geometric` compares only the tangent directions (G1: no corner, speeds may jump);
        `tol` is relative to the larger derivative (C1) or an angle in rad (G1).
        """
        out = []
        for j in range(1, len(self.segments)):
            d_in = self.segments[j - 1].derivative(1.0)
            d_out = self.segments[j].derivative(0.0)
            n_in, n_out = float(np.linalg.norm(d_in)), float(np.linalg.norm(d_out))
            if geometric:
                if n_in < 1e-15 or n_out < 1e-15:
                    out.append(j)
                    continue
                if angle_between(d_in, d_out) > tol:
                    out.append(j)
            elif float(np.linalg.norm(d_in - d_out)) > tol * max(n_in, n_out, 1e-12):
                out.append(j)
        return out

    def is_c1(self, tol: float = 1e-9) -> bool:
        return not self.c1_defects(tol)

    def is_g1(self, tol: float = 1e-6) -> bool:
        return not self.c1_defects(tol, geometric=True)

    def enforce_c1(self) -> BezierChain:
        """Equal derivatives at every joint: both handles moved to the mean derivative.

        Joints and end points stay; corners are rounded (that is the point). A closed chain
        (end == start) gets its closing joint smoothed too.
        """
        ctrl = [s.control.copy() for s in self.segments]
        n = len(ctrl)
        closed = bool(np.allclose(ctrl[0][0], ctrl[-1][3]))
        joints = list(range(1, n)) + ([0] if closed and n > 1 else [])
        for j in joints:
            a, b = ctrl[j - 1], ctrl[j]
            P = b[0]
            d = 0.5 * ((P - a[2]) + (b[1] - P))
            a[2] = P - d
            b[1] = P + d
        return BezierChain(tuple(CubicBezier(c) for c in ctrl), self.name)

    def length(self, samples: int = 256) -> float:
        t = np.linspace(0.0, 1.0, samples)
        return float(sum(np.linalg.norm(np.diff(s.point(t), axis=0), axis=1).sum()
                         for s in self.segments))


@dataclass(frozen=True)
class BezierSampling:
    """Points on the chain (joints shared once), where they came from, and how good they are."""

    points: Array  # (N, dim)
    segment_index: Array  # (N,) segment of each point (a joint belongs to the later one)
    t: Array  # (N,) parameter within that segment
    #: Largest distance from the curve to the polyline through the points, measured densely.
    max_deviation: float
    #: The tolerance asked for (None for fixed-step sampling).
    tolerance: float | None = None
    #: Points per segment including both ends (the source's "number of interpolations").
    per_segment: tuple[int, ...] = ()

    @property
    def n_points(self) -> int:
        return len(self.points)


def sample_bezier_chain(segments: Sequence[CubicBezier] | BezierChain, tol: float, *,
                        max_points_per_segment: int = 10_000) -> BezierSampling:
    """Adaptive sampling: each chord stays within `tol` of the curve (certified).

    Greedy longest step: from each point, the farthest parameter whose sub-curve passes the
    certified chord bound (found by bisection), so the count is close to the minimum for
    the bound. The achieved deviation is measured densely and returned.
    """
    segs = _segments(segments)
    if not tol > 0.0:
        raise ValueError("the tolerance must be > 0")
    params: list[list[float]] = []
    for s in segs:
        ts = [0.0]
        while ts[-1] < 1.0:
            if len(ts) > max_points_per_segment:
                raise ValueError(f"more than {max_points_per_segment} points for one segment; "
                                 "the tolerance is too small for the curve's size")
            ts.append(_farthest(s, ts[-1], tol))
        params.append(ts)
    return _assemble(segs, params, tol)


def sample_fixed_dt(segments: Sequence[CubicBezier] | BezierChain, dt: float) -> BezierSampling:
    """The source's sampling: t = 0, dt, 2 dt, ..., 1 in every segment (0.05 -> 21 points)."""
    segs = _segments(segments)
    n = int(round(1.0 / dt))
    if n < 1 or abs(n * dt - 1.0) > 1e-9:
        raise ValueError("dt must divide 1 (0.5, 0.25, 0.1, 0.05, 0.02, ...)")
    params = [list(np.linspace(0.0, 1.0, n + 1)) for _ in segs]
    return _assemble(segs, params, None)


def measure_deviation(segments: Sequence[CubicBezier] | BezierChain,
                      params: Sequence[Sequence[float]], dense: int = DENSE_SAMPLES) -> float:
    """Largest distance from the curve to the chords between consecutive parameters."""
    worst = 0.0
    for s, ts in zip(_segments(segments), params, strict=True):
        for t0, t1 in zip(ts[:-1], ts[1:], strict=True):
            tt = np.linspace(t0, t1, dense)
            c = s.point(tt)
            worst = max(worst, float(_dist_to_segment(c, c[0], c[-1]).max()))
    return worst


def _farthest(s: CubicBezier, t0: float, tol: float) -> float:
    if s.sub(t0, 1.0).chord_error_bound() <= tol:
        return 1.0
    lo, hi = t0, 1.0  # lo passes (trivially), hi fails
    while hi - lo > 1e-7:  # a step shorter by 1e-7 of the segment costs nothing
        mid = 0.5 * (lo + hi)
        if s.sub(t0, mid).chord_error_bound() <= tol:
            lo = mid
        else:
            hi = mid
    if lo <= t0:
        lo = min(1.0, t0 + 1e-9)
    return lo


@dataclass(frozen=True)
class PathPiece:
    """A piece of a chain as a controller primitive: a line, an arc or sampled points."""

    kind: str  # "line" (start, end) | "arc" (start, via, end) | "curve" (samples, ends incl.)
    points: Array
    #: Largest distance from the Bezier segment to this piece, measured densely.
    max_deviation: float
    segment: int


def fit_primitives(segments: Sequence[CubicBezier] | BezierChain, tol: float
                   ) -> list[PathPiece]:
    """Each segment as the simplest primitive within `tol`: a line, a circular arc, else the
    adaptive samples. The drawings' straight strokes and rounded corners (quarter arcs) then
    need 2 and 3 positions instead of a sampled polyline: what a person would program, and
    what the source (000 §2.6) notes arcs are better at, done only where they fit.
    """
    out: list[PathPiece] = []
    for i, s in enumerate(_segments(segments)):
        t = np.linspace(0.0, 1.0, 257)
        pts = s.point(t)
        line_dev = float(_dist_to_segment(pts, s.start, s.end).max())
        if line_dev <= tol:
            out.append(PathPiece("line", np.array([s.start, s.end]), line_dev, i))
            continue
        arc = _arc_deviation(pts, s.point(0.5))
        if arc is not None and arc <= tol:
            out.append(PathPiece("arc", np.array([s.start, s.point(0.5), s.end]), arc, i))
            continue
        samp = sample_bezier_chain([s], tol)
        out.append(PathPiece("curve", samp.points, samp.max_deviation, i))
    return out


def _arc_deviation(pts: Array, mid: Array) -> float | None:
    """Largest radial distance of the dense points from the circle through start, mid, end
    (None if they are collinear or the points do not sweep the arc monotonically)."""
    P = pts if pts.shape[1] == 3 else np.c_[pts, np.zeros(len(pts))]
    m = mid if mid.shape[0] == 3 else np.r_[mid, 0.0]
    p0, p1 = P[0], P[-1]
    a, b = m - p0, p1 - p0
    n = np.cross(a, b)
    nn = float(np.linalg.norm(n))
    if nn < 1e-12 * max(float(a @ a), float(b @ b), 1e-30):
        return None
    c = p0 + (np.cross(n, a) * (b @ b) + np.cross(b, n) * (a @ a)) / (2.0 * nn * nn)
    r = float(np.linalg.norm(p0 - c))
    u = (p0 - c) / r
    v = np.cross(n / nn, u)
    d = P - c
    ang = np.unwrap(np.arctan2(d @ v, d @ u))
    if np.any(np.diff(ang) < -1e-12):
        return None
    off_plane = np.abs(d @ (n / nn))
    return float(np.max(np.hypot(np.linalg.norm(d - np.outer(d @ (n / nn), n / nn), axis=1) - r,
                                 off_plane)))


def _assemble(segs: list[CubicBezier], params: list[list[float]],
              tol: float | None) -> BezierSampling:
    pts, seg_idx, ts = [], [], []
    for i, (s, tt) in enumerate(zip(segs, params, strict=True)):
        p = s.point(np.asarray(tt))
        start = 0 if i == 0 else 1  # the joint is the previous segment's end
        pts.append(p[start:])
        seg_idx += [i] * (len(tt) - start)
        ts += list(tt[start:])
    dev = measure_deviation(segs, params)
    return BezierSampling(np.vstack(pts), np.asarray(seg_idx), np.asarray(ts), dev, tol,
                          tuple(len(t) for t in params))


def _segments(segments: Sequence[CubicBezier] | BezierChain) -> list[CubicBezier]:
    if isinstance(segments, BezierChain):
        return list(segments.segments)
    segs = [s if isinstance(s, CubicBezier) else CubicBezier(np.asarray(s)) for s in segments]
    if not segs:
        raise ValueError("no Bezier segments")
    return segs


def _dist_to_segment(p: Array, a: Array, b: Array) -> Array:
    d = b - a
    L2 = float(d @ d)
    if L2 < 1e-30:
        return np.linalg.norm(p - a, axis=1)
    s = np.clip(((p - a) @ d) / L2, 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * d), axis=1)
