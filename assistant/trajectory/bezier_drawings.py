"""The drawing cell's nine drawings in the source's style (000 §4: a phone's frame, keyboard and
screen, three variants each), as Bezier chains on the paper plane.

The source's robot drew 9 drawings, each one pen-down stroke of cubic Bezier segments stored
as flat KRL arrays (first point, then 3 points per segment); it does not print the control
points, so these are new drawings of the same kinds and sizes (a 70 x 140 mm phone): frames
1-3, keyboards 4-6, screens 7-9, numbered like the source's DRAW1..DRAW9 services. Straight
strokes are Bezier segments with handles at a third, corners quarter arcs (k = 4/3 tan(a/4)).

Units: metres in the paper frame (x right, y up on the sheet, z out of the paper); place a
chain with `BezierChain.transformed(T_base_paper)` (the calibrated base of the source).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from assistant.trajectory.bezier import BezierChain, CubicBezier

Array = np.ndarray

MM = 1e-3


def line(a: Array, b: Array) -> CubicBezier:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return CubicBezier(np.array([a, a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b]))


def arc(center: Array, r: float, a0: float, a1: float) -> CubicBezier:
    """Cubic approximation of the circular arc from angle a0 to a1 (|a1 - a0| <= 90 deg)."""
    c = np.asarray(center, dtype=float)
    k = 4.0 / 3.0 * np.tan((a1 - a0) / 4.0)
    p0 = c + r * np.array([np.cos(a0), np.sin(a0)])
    p3 = c + r * np.array([np.cos(a1), np.sin(a1)])
    t0 = np.array([-np.sin(a0), np.cos(a0)])
    t1 = np.array([-np.sin(a1), np.cos(a1)])
    return CubicBezier(np.array([p0, p0 + k * r * t0, p3 - k * r * t1, p3]))


def polyline(points: list[tuple[float, float]]) -> list[CubicBezier]:
    P = [np.asarray(p, dtype=float) * MM for p in points]
    return [line(a, b) for a, b in zip(P[:-1], P[1:], strict=True)]


def rounded_rectangle(cx: float, cy: float, w: float, h: float, r: float) -> list[CubicBezier]:
    """Counter-clockwise from the bottom edge: 4 edges and 4 quarter arcs (mm in, m out)."""
    cx, cy, w, h, r = (v * MM for v in (cx, cy, w, h, r))
    x0, x1, y0, y1 = cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2
    q = np.pi / 2
    return [
        line((x0 + r, y0), (x1 - r, y0)), arc((x1 - r, y0 + r), r, -q, 0.0),
        line((x1, y0 + r), (x1, y1 - r)), arc((x1 - r, y1 - r), r, 0.0, q),
        line((x1 - r, y1), (x0 + r, y1)), arc((x0 + r, y1 - r), r, q, 2 * q),
        line((x0, y1 - r), (x0, y0 + r)), arc((x0 + r, y0 + r), r, 2 * q, 3 * q),
    ]


def _pebble(w: float, h: float, square: float) -> list[CubicBezier]:
    """A closed, C1 rounded outline of 4 quarter segments (square: handle / half side)."""
    a, b = w / 2 * MM, h / 2 * MM
    quarter = np.array([[a, 0.0], [a, square * b], [square * a, b], [0.0, b]])
    segs = []
    for sx, sy, rev in ((1, 1, False), (-1, 1, True), (-1, -1, False), (1, -1, True)):
        c = quarter * np.array([sx, sy])
        segs.append(CubicBezier(c[::-1] if rev else c))
    return segs


# ------------------------------------------------------------------------------ frames
def frame_rounded() -> BezierChain:
    return BezierChain(tuple(rounded_rectangle(0, 0, 70, 140, 10)), "frame 1: rounded")


def frame_slim() -> BezierChain:
    return BezierChain(tuple(rounded_rectangle(0, 0, 64, 136, 18)), "frame 2: slim")


def frame_pebble() -> BezierChain:
    return BezierChain(tuple(_pebble(72, 142, 0.8)), "frame 3: pebble")


# ------------------------------------------------------------------------------ keyboards
def keyboard_rows() -> BezierChain:
    """Four key rows drawn as one serpentine stroke (lines joined by half-circle turns)."""
    ys = [-15.0, -27.0, -39.0, -51.0]
    segs: list[CubicBezier] = []
    q = np.pi / 2
    for i, y in enumerate(ys):
        left_to_right = i % 2 == 0
        a, b = (-24.0, 24.0) if left_to_right else (24.0, -24.0)
        segs += polyline([(a, y), (b, y)])
        if i + 1 < len(ys):
            r = (y - ys[i + 1]) / 2 * MM
            c = np.array([b * MM, (y * MM) - r])
            if left_to_right:  # turn clockwise on the right
                segs += [arc(c, r, q, 0.0), arc(c, r, 0.0, -q)]
            else:
                segs += [arc(c, r, q, 2 * q), arc(c, r, 2 * q, 3 * q)]
    return BezierChain(tuple(segs), "keyboard 4: rows")


def keyboard_keys() -> BezierChain:
    """Three rows of four round-topped keys, one stroke."""
    segs: list[CubicBezier] = []
    rows = [-20.0, -35.0, -50.0]
    for i, y in enumerate(rows):
        xs = np.linspace(-24.0, 24.0, 5) if i % 2 == 0 else np.linspace(24.0, -24.0, 5)
        for x0, x1 in zip(xs[:-1], xs[1:], strict=True):
            p0, p3 = np.array([x0, y]) * MM, np.array([x1, y]) * MM
            up = np.array([0.0, 8.0]) * MM
            segs.append(CubicBezier(np.array([p0, p0 + up, p3 + up, p3])))
        if i + 1 < len(rows):
            segs += polyline([(xs[-1], y), (xs[-1], rows[i + 1])])
    return BezierChain(tuple(segs), "keyboard 5: keys")


def keyboard_grid() -> BezierChain:
    """A 3 x 3 key grid in one stroke: rows as a serpentine, then the columns."""
    xs, ys = (-24.0, -8.0, 8.0, 24.0), (-15.0, -30.0, -45.0, -60.0)
    pts = [(xs[0], ys[0]), (xs[3], ys[0]), (xs[3], ys[1]), (xs[0], ys[1]), (xs[0], ys[2]),
           (xs[3], ys[2]), (xs[3], ys[3]), (xs[0], ys[3]), (xs[0], ys[0]), (xs[1], ys[0]),
           (xs[1], ys[3]), (xs[2], ys[3]), (xs[2], ys[0])]
    return BezierChain(tuple(polyline(pts)), "keyboard 6: grid")


# ------------------------------------------------------------------------------ screens
def screen_plain() -> BezierChain:
    pts = [(-28.0, 0.0), (28.0, 0.0), (28.0, 60.0), (-28.0, 60.0), (-28.0, 0.0)]
    return BezierChain(tuple(polyline(pts)), "screen 7: plain")


def screen_rounded() -> BezierChain:
    return BezierChain(tuple(rounded_rectangle(0, 30, 56, 60, 5)), "screen 8: rounded")


def screen_curved() -> BezierChain:
    """Straight sides and bottom, a curved top edge (one segment)."""
    segs = polyline([(-28.0, 0.0), (28.0, 0.0), (28.0, 54.0)])
    p0, p3 = np.array([28.0, 54.0]) * MM, np.array([-28.0, 54.0]) * MM
    segs.append(CubicBezier(np.array([p0, p0 + np.array([-6.0, 10.0]) * MM,
                                      p3 + np.array([6.0, 10.0]) * MM, p3])))
    segs += polyline([(-28.0, 54.0), (-28.0, 0.0)])
    return BezierChain(tuple(segs), "screen 9: curved")


#: The source's nine drawing services, DRAW1..DRAW9.
DRAWINGS: dict[int, Callable[[], BezierChain]] = {
    1: frame_rounded, 2: frame_slim, 3: frame_pebble,
    4: keyboard_rows, 5: keyboard_keys, 6: keyboard_grid,
    7: screen_plain, 8: screen_rounded, 9: screen_curved,
}


def drawing(number: int) -> BezierChain:
    """Drawing 1..9 (frames, keyboards, screens) in metres on the paper plane."""
    if number not in DRAWINGS:
        raise ValueError(f"drawing {number}: the cell has drawings 1..9")
    return DRAWINGS[number]()
