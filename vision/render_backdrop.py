"""The synthetic camera's static backdrop: a lit grey wall, optionally cluttered with shapes
in colours the ball detector must ignore and with red/orange distractors (bars, signs, specks,
discs, a pointer-sized orange ball) that a naive colour threshold would take for the ball.

Drawn once per camera and scene by the caller; `vision.render` composes frames over it.
"""

from __future__ import annotations

import cv2
import numpy as np

from vision.scene import BackgroundSpec


def _hsv_to_bgr(h: float, s: float, v: float) -> tuple[float, float, float]:
    px = np.uint8([[[int(h) % 180, int(s), int(v)]]])
    b, g, r = cv2.cvtColor(px, cv2.COLOR_HSV2BGR)[0, 0]
    return float(b), float(g), float(r)


def _safe_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    """A clutter colour that is not red or orange (hue 25..160) or is nearly grey."""
    if rng.random() < 0.4:
        g = rng.uniform(30, 230)
        return _hsv_to_bgr(0, rng.uniform(0, 30), g)
    return _hsv_to_bgr(rng.uniform(25, 160), rng.uniform(40, 255), rng.uniform(60, 240))


def _distractor_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    h = rng.choice([rng.uniform(0, 6), rng.uniform(172, 180), rng.uniform(8, 22)])
    return _hsv_to_bgr(h, rng.uniform(150, 255), rng.uniform(120, 240))


def make_background(width: int, height: int, spec: BackgroundSpec,
                    rng: np.random.Generator) -> np.ndarray:
    """Static backdrop (float32 0..255): a lit grey wall, optionally cluttered and with
    red/orange distractors that a naive colour threshold would take for the ball."""
    y = np.linspace(0.0, 1.0, height, dtype=np.float32)[:, None]
    x = np.linspace(0.0, 1.0, width, dtype=np.float32)[None, :]
    shade = 0.85 + 0.25 * (1.0 - y) * (0.7 + 0.3 * x)
    img = (np.asarray(spec.base_bgr, dtype=np.float32) * 255.0)[None, None, :] * shade[..., None]
    img = np.ascontiguousarray(img, dtype=np.float32)
    if spec.kind == "plain":
        return img
    diag = float(np.hypot(width, height))
    for _ in range(spec.n_shapes):
        colour = _safe_colour(rng)
        kind = rng.integers(0, 4)
        cx, cy = int(rng.uniform(0, width)), int(rng.uniform(0, height))
        if kind == 0:
            w, h = rng.uniform(0.02, 0.25, 2) * diag
            box = ((cx, cy), (float(w), float(h)), float(rng.uniform(0, 180)))
            cv2.fillConvexPoly(img, cv2.boxPoints(box).astype(np.int32), colour, cv2.LINE_AA)
        elif kind == 1:
            cv2.circle(img, (cx, cy), int(rng.uniform(0.01, 0.08) * diag), colour, -1,
                       cv2.LINE_AA)
        elif kind == 2:
            p2 = (int(rng.uniform(0, width)), int(rng.uniform(0, height)))
            cv2.line(img, (cx, cy), p2, colour, int(rng.integers(1, 8)), cv2.LINE_AA)
        else:
            cv2.ellipse(img, (cx, cy), tuple(int(a) for a in rng.uniform(5, 0.1 * diag, 2)),
                        float(rng.uniform(0, 180)), 0, 360, colour, -1, cv2.LINE_AA)
    for _ in range(spec.n_distractors):
        _draw_distractor(img, rng, width, height)
    # a little surface texture so the wall is not perfectly flat
    img += rng.normal(0.0, 3.0, img.shape).astype(np.float32)
    return np.clip(img, 0, 255, out=img)


def _draw_distractor(img: np.ndarray, rng: np.random.Generator, width: int, height: int) -> None:
    """One red/orange thing that is not a 2.5 cm ball: the shapes a shop floor offers."""
    colour = _distractor_colour(rng)
    cx, cy = int(rng.uniform(0, width)), int(rng.uniform(0, height))
    kind = int(rng.integers(0, 7))
    if kind == 0:  # bar / label / cable
        w, h = rng.uniform(30, 160), rng.uniform(3, 12)
        box = ((cx, cy), (float(w), float(h)), float(rng.uniform(0, 180)))
        cv2.fillConvexPoly(img, cv2.boxPoints(box).astype(np.int32), colour, cv2.LINE_AA)
    elif kind == 1:  # text on a warning sign
        cv2.putText(img, "STOP", (cx, cy), cv2.FONT_HERSHEY_SIMPLEX, rng.uniform(0.6, 1.5),
                    colour, int(rng.integers(2, 4)), cv2.LINE_AA)
    elif kind == 2:  # dust of red specks (sensor or paint): the median filter's job
        for _ in range(12):
            p = (int(cx + rng.normal(0, 25)), int(cy + rng.normal(0, 25)))
            cv2.circle(img, p, 1, colour, -1)
    elif kind == 3:  # a big red disc (emergency stop button up close, a lamp)
        cv2.circle(img, (cx, cy), int(rng.uniform(28, 60)), colour, -1, cv2.LINE_AA)
    elif kind == 4:  # elongated blob (hose, hand in a red glove seen edge-on)
        a = rng.uniform(15, 40)
        cv2.ellipse(img, (cx, cy), (int(a), int(a * rng.uniform(0.2, 0.45))),
                    float(rng.uniform(0, 180)), 0, 360, colour, -1, cv2.LINE_AA)
    elif kind == 5:  # an orange ball of pointer size: hue must reject it
        cv2.circle(img, (cx, cy), int(rng.uniform(4, 10)),
                   _hsv_to_bgr(rng.uniform(12, 22), 230, 230), -1, cv2.LINE_AA)
    else:  # a red square sticker: round by moments, not by shape
        s = rng.uniform(10, 18)
        box = ((cx, cy), (float(s), float(s)), float(rng.uniform(0, 90)))
        cv2.fillConvexPoly(img, cv2.boxPoints(box).astype(np.int32), colour, cv2.LINE_AA)
