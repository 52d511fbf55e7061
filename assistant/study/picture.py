"""The study as a picture (PNG, OpenCV): the region seen from above, a dot per position
coloured by its best candidate and a tick per yaw coloured by that candidate - planned ones
green (best) to red (worst), screened but not planned blue, failed grey - the objects'
outlines, the current placement (black cross) and the best (ring). Millimetres on the axes.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from assistant.study.study import FAILED, PLANNED, SCREENED, CandidateResult, StudyResult

GREY = (170, 170, 170)
BLUE = (220, 160, 60)  # BGR
BLACK = (0, 0, 0)


def rank_colour(k: int, n: int) -> tuple[int, int, int]:
    """Green (best, k=0) through yellow to red (worst, k=n-1), BGR."""
    t = 0.0 if n <= 1 else k / (n - 1)
    r = int(255 * min(1.0, 2 * t))
    g = int(200 * min(1.0, 2 * (1 - t)))
    return (40, g, r)


def colours(result: StudyResult) -> dict[int, tuple[int, int, int]]:
    """The colour of each candidate (by index), as on the map and in the page's markers."""
    planned = [r for r in result.ranked() if r.status == PLANNED]
    out = {}
    for r in result.candidates:
        if r.status == PLANNED:
            out[r.candidate.index] = rank_colour(planned.index(r), len(planned))
        elif r.status == SCREENED:
            out[r.candidate.index] = BLUE
        else:
            out[r.candidate.index] = GREY
    return out


def render_map(result: StudyResult, path: str | Path, width_px: int = 900) -> Path:
    reg = result.region
    lo = np.array([reg.x0, reg.y0])
    hi = np.array([reg.x1, reg.y1])
    boxes = _object_boxes(result)
    for b0, b1 in boxes:
        lo, hi = np.minimum(lo, b0), np.maximum(hi, b1)
    pad = max(0.05, 0.08 * float(np.max(hi - lo)))
    lo, hi = lo - pad, hi + pad
    span = np.maximum(hi - lo, 1e-3)
    scale = (width_px - 120) / span[0]
    h_px = int(span[1] * scale) + 140
    img = np.full((h_px, width_px, 3), 255, np.uint8)

    def px(x: float, y: float) -> tuple[int, int]:
        return (int(round(60 + (x - lo[0]) * scale)), int(round(h_px - 80 - (y - lo[1]) * scale)))

    for b0, b1 in boxes:
        cv2.rectangle(img, px(b0[0], b0[1]), px(b1[0], b1[1]), (120, 120, 120), 1)
    col = colours(result)
    tick = max(6, int(0.35 * reg.step * scale))
    by_pos: dict[tuple[float, float], list[CandidateResult]] = {}
    for r in result.candidates:
        by_pos.setdefault((round(r.candidate.x, 6), round(r.candidate.y, 6)), []).append(r)
    order = {r.candidate.index: k for k, r in enumerate(result.ranked())}
    dot = max(3, min(10, tick // 3))
    for (x, y), rs in by_pos.items():
        c = px(x, y)
        for r in rs:
            e = (int(round(c[0] + tick * np.cos(r.candidate.yaw))),
                 int(round(c[1] - tick * np.sin(r.candidate.yaw))))
            cv2.line(img, c, e, col[r.candidate.index], 2, cv2.LINE_AA)
        best = min(rs, key=lambda r: (r.status == FAILED, order[r.candidate.index]))
        cv2.circle(img, c, dot, col[best.candidate.index], -1, cv2.LINE_AA)
    top = result.best()
    if top is not None:
        cv2.circle(img, px(top.candidate.x, top.candidate.y), dot + 6, BLACK, 2, cv2.LINE_AA)
    if result.current is not None:
        cx, cy = px(result.current.candidate.x, result.current.candidate.y)
        cv2.drawMarker(img, (cx, cy), BLACK, cv2.MARKER_CROSS, 18, 2)
    _axes(img, lo, hi, px)
    counts = result.counts
    lines = [f"placement of {result.subject}: {counts['candidates']} candidates, "
             f"{counts['screened_ok']} passed the screen, {counts['planned_ok']}/"
             f"{counts['planned']} planned",
             "green best .. red worst (planned), blue screened only, grey failed; "
             "+ current, ring best"]
    for k, text in enumerate(lines):
        cv2.putText(img, text, (10, 20 + 18 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.45, BLACK, 1,
                    cv2.LINE_AA)
    path = Path(path)
    if not cv2.imwrite(str(path), img):
        raise OSError(f"cannot write {path}")
    return path


def _axes(img: np.ndarray, lo: np.ndarray, hi: np.ndarray, px) -> None:
    step = _nice_step(float(np.max(hi - lo)))
    for x in np.arange(np.ceil(lo[0] / step) * step, hi[0] + 1e-9, step):
        p = px(float(x), float(lo[1]))
        cv2.line(img, (p[0], p[1]), (p[0], p[1] + 5), BLACK, 1)
        cv2.putText(img, f"{x * 1000:.0f}", (p[0] - 14, p[1] + 20), cv2.FONT_HERSHEY_SIMPLEX,
                    0.4, BLACK, 1, cv2.LINE_AA)
    for y in np.arange(np.ceil(lo[1] / step) * step, hi[1] + 1e-9, step):
        p = px(float(lo[0]), float(y))
        cv2.line(img, (p[0] - 5, p[1]), (p[0], p[1]), BLACK, 1)
        cv2.putText(img, f"{y * 1000:.0f}", (2, p[1] + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    BLACK, 1, cv2.LINE_AA)
    a, b = px(float(lo[0]), float(lo[1])), px(float(hi[0]), float(hi[1]))
    cv2.rectangle(img, (a[0], b[1]), (b[0], a[1]), BLACK, 1)
    cv2.putText(img, "x (mm)", (b[0] - 50, a[1] + 40), cv2.FONT_HERSHEY_SIMPLEX, 0.45, BLACK,
                1, cv2.LINE_AA)


def _nice_step(span: float) -> float:
    raw = span / 6.0
    mag = 10 ** np.floor(np.log10(raw))
    for m in (1, 2, 5, 10):
        if m * mag >= raw:
            return float(m * mag)
    return float(10 * mag)


def _object_boxes(result: StudyResult) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each object's outline (x, y bounds in the world), skipping ones far larger than the
    region (a table under everything says nothing)."""
    prob = result.problem
    if prob is None:
        return []
    reg = result.region
    size = max(reg.x1 - reg.x0, reg.y1 - reg.y0, reg.step)
    out = []
    for obj in prob.cell.objects.values():
        pts = []
        for shape in obj.collision:
            m = shape.to_trimesh()
            m.apply_transform(np.asarray(obj.T_world_object, dtype=float))
            pts.append(np.asarray(m.bounds)[:, :2])
        if not pts:
            continue
        b = np.concatenate(pts)
        b0, b1 = b.min(axis=0), b.max(axis=0)
        if float(np.max(b1 - b0)) > 3 * size + 0.5:
            continue
        out.append((b0, b1))
    return out
