"""The candidates of a study: a grid of (x, y) positions over a rectangle on the floor or
table, times a number of yaw steps (all in the world frame)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: More candidates than this is a typing mistake (a step in metres given as millimetres...).
MAX_CANDIDATES = 20000


@dataclass(frozen=True)
class Candidate:
    """One placement to try: the subject's x, y (m) and yaw (rad) in the world frame."""

    index: int
    x: float
    y: float
    yaw: float

    def label(self) -> str:
        return (f"#{self.index} ({self.x * 1000:.0f}, {self.y * 1000:.0f}) mm, "
                f"{math.degrees(self.yaw):.0f} deg")

    def to_json(self) -> dict:
        return {"index": self.index, "x_mm": round(self.x * 1000.0, 3),
                "y_mm": round(self.y * 1000.0, 3), "yaw_deg": round(math.degrees(self.yaw), 4)}


@dataclass(frozen=True)
class Region:
    """A rectangle [x0, x1] x [y0, y1] (m) stepped every `step` (m), each point at
    `yaw_steps` yaws evenly around the circle starting at `yaw0` (rad)."""

    x0: float
    y0: float
    x1: float
    y1: float
    step: float
    yaw_steps: int = 1
    yaw0: float = 0.0

    def __post_init__(self) -> None:
        vals = (self.x0, self.y0, self.x1, self.y1, self.step, self.yaw0)
        if not all(math.isfinite(v) for v in vals):
            raise ValueError("the region needs finite numbers")
        if self.x1 < self.x0 or self.y1 < self.y0:
            raise ValueError("the region's corners: give X0,Y0,X1,Y1 with X0 <= X1 and Y0 <= Y1")
        if self.step <= 0:
            raise ValueError("the step must be positive")
        if int(self.yaw_steps) != self.yaw_steps or self.yaw_steps < 1:
            raise ValueError("yaw steps must be a whole number >= 1")
        n = self.count()
        if n > MAX_CANDIDATES:
            raise ValueError(f"{n} candidates is too many (at most {MAX_CANDIDATES}); "
                             "use a larger step or fewer yaw steps")

    @staticmethod
    def from_mm(text: str, step_mm: float, yaw_steps: int = 1,
                yaw0_deg: float = 0.0) -> Region:
        """From the operator's 'X0,Y0,X1,Y1' in millimetres and a step in millimetres."""
        try:
            parts = [float(v) for v in str(text).replace(";", ",").split(",")]
        except ValueError:
            raise ValueError(f"region {text!r}: give four numbers X0,Y0,X1,Y1 in mm") from None
        if len(parts) != 4:
            raise ValueError(f"region {text!r}: give four numbers X0,Y0,X1,Y1 in mm")
        x0, y0, x1, y1 = (v / 1000.0 for v in parts)
        return Region(x0, y0, x1, y1, float(step_mm) / 1000.0, int(yaw_steps),
                      math.radians(float(yaw0_deg)))

    def xs(self) -> np.ndarray:
        return _steps(self.x0, self.x1, self.step)

    def ys(self) -> np.ndarray:
        return _steps(self.y0, self.y1, self.step)

    def yaws(self) -> np.ndarray:
        k = np.arange(int(self.yaw_steps))
        return np.mod(self.yaw0 + 2.0 * np.pi * k / int(self.yaw_steps) + np.pi,
                      2.0 * np.pi) - np.pi

    def count(self) -> int:
        return len(self.xs()) * len(self.ys()) * int(self.yaw_steps)

    def candidates(self) -> list[Candidate]:
        """Row by row (y outer, x inner), each position's yaws together: indices are stable."""
        out = []
        for y in self.ys():
            for x in self.xs():
                for yaw in self.yaws():
                    out.append(Candidate(len(out), float(x), float(y), float(yaw)))
        return out

    def to_json(self) -> dict:
        return {"x0_mm": self.x0 * 1000, "y0_mm": self.y0 * 1000, "x1_mm": self.x1 * 1000,
                "y1_mm": self.y1 * 1000, "step_mm": self.step * 1000,
                "yaw_steps": int(self.yaw_steps), "yaw0_deg": math.degrees(self.yaw0)}


def _steps(a: float, b: float, step: float) -> np.ndarray:
    """a, a + step, ... up to b (b itself when it falls on the grid within 1 um)."""
    n = int(math.floor((b - a) / step + 1e-6)) + 1
    return a + step * np.arange(n)
