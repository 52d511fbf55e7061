"""Memory of the still things in each view that are *not* the pointer ball.

While the pointer is measured with confidence, every other round blob of the ball's colour
that a camera sees at the same moment is something else: a red sign, a ball on a shelf, a
button. Those stay where they are, so remembering where they were lets the tracker refuse them
later, when the ball is hidden and they are all there is (the issue's "locks onto background
blobs during the occlusion"). Moving look-alikes are not remembered (they do not come back to
the same pixel); the hue test and the gates are what keep those out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision.detection import Detection


@dataclass
class _Blob:
    center_px: np.ndarray
    radius_px: float
    last_seen: float
    seen: int = 1


class ClutterMemory:
    """Per-camera lists of remembered still look-alikes."""

    def __init__(self, n_cameras: int, *, match_px: float = 2.5, forget_s: float = 30.0,
                 max_blobs: int = 64) -> None:
        self.blobs: list[list[_Blob]] = [[] for _ in range(n_cameras)]
        self.match_px = match_px
        self.forget_s = forget_s
        self.max_blobs = max_blobs

    def reset(self) -> None:
        for b in self.blobs:
            b.clear()

    def _find(self, i: int, d: Detection) -> _Blob | None:
        for b in self.blobs[i]:
            tol = self.match_px + 0.25 * b.radius_px
            if np.linalg.norm(b.center_px - d.center_px) <= tol and \
                    0.7 <= d.radius_px / max(b.radius_px, 1e-6) <= 1.4:
                return b
        return None

    def learn(self, i: int, t: float, detections: list[Detection],
              pointer: Detection) -> None:
        """Remember every detection of camera i well away from the pointer's own blob."""
        for d in detections:
            if np.linalg.norm(d.center_px - pointer.center_px) <= 3.0 * max(
                    pointer.radius_px, d.radius_px):
                continue
            b = self._find(i, d)
            if b is None:
                self.blobs[i].append(_Blob(np.asarray(d.center_px, float).copy(), d.radius_px,
                                           t))
            else:
                b.last_seen, b.seen = t, b.seen + 1
        live = [b for b in self.blobs[i] if t - b.last_seen <= self.forget_s]
        self.blobs[i] = sorted(live, key=lambda b: -b.last_seen)[: self.max_blobs]

    def is_clutter(self, i: int, d: Detection) -> bool:
        return self._find(i, d) is not None
