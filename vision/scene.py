"""What a synthetic camera sees: the pointer ball on its stick, robot markers, calibration boards,
the background, the light and the sensor, each as plain data that can be asked "where at time t?".

Colours are BGR albedos in 0..1; positions are world-frame metres. The thesis pointer is a
2.5 cm red ball on a 50 cm stick (003, L2063).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

Vec3 = np.ndarray
PathFn = Callable[[float], "np.ndarray | None"]

#: A red whose hue sits on OpenCV's H = 0 seam, so sensor noise pushes pixels to both ends.
RED_BALL_BGR = (0.13, 0.13, 0.82)
ORANGE_BGR = (0.10, 0.45, 0.90)
BLUE_MARKER_BGR = (0.80, 0.35, 0.10)
GREEN_MARKER_BGR = (0.25, 0.70, 0.20)
YELLOW_MARKER_BGR = (0.10, 0.80, 0.85)
WOOD_BGR = (0.22, 0.38, 0.55)


def _as_path(p: PathFn | np.ndarray | tuple | None) -> PathFn:
    if p is None:
        return lambda t: None
    if callable(p):
        return p
    fixed = np.asarray(p, dtype=float)
    if fixed.shape != (3,):
        raise ValueError(f"a position must be (x, y, z), got shape {fixed.shape}")
    return lambda t: fixed


@dataclass
class StickSpec:
    """The pointer's handle: a cylinder from the ball centre towards the operator's hand."""

    direction_world: Vec3 = field(default_factory=lambda: np.array([0.55, -0.35, -0.75]))
    length: float = 0.5
    radius: float = 0.006
    bgr: tuple[float, float, float] = WOOD_BGR

    def __post_init__(self) -> None:
        d = np.asarray(self.direction_world, dtype=float)
        if np.linalg.norm(d) < 1e-9:
            raise ValueError("stick direction must be non-zero")
        self.direction_world = d / np.linalg.norm(d)


@dataclass
class SphereMarker:
    """A coloured ball (robot marker or second pointer); `path` is a fixed point or t -> point."""

    path: PathFn | np.ndarray | tuple
    radius: float = 0.0125
    bgr: tuple[float, float, float] = BLUE_MARKER_BGR
    name: str = "marker"

    def position(self, t: float) -> np.ndarray | None:
        return _as_path(self.path)(t)


@dataclass
class PlanarTarget:
    """A flat printed pattern (chessboard, ChArUco): `texture` BGR uint8 covers the board's
    [0, width_m] x [0, height_m] in its own x/y plane; `T_world_board` places it."""

    texture: np.ndarray
    width_m: float
    height_m: float
    T_world_board: np.ndarray


@dataclass
class Lighting:
    """One directional light (`direction_world` points towards the light) plus ambient."""

    direction_world: Vec3 = field(default_factory=lambda: np.array([0.35, 0.25, 1.0]))
    ambient: float = 0.35
    diffuse: float = 0.65
    specular: float = 0.45
    shininess: float = 40.0

    def __post_init__(self) -> None:
        d = np.asarray(self.direction_world, dtype=float)
        self.direction_world = d / np.linalg.norm(d)


@dataclass
class BackgroundSpec:
    """A static backdrop: "plain" grey wall or "cluttered" with random shapes.

    `n_distractors` adds red and orange things that are not the ball (bars, text, specks, large
    discs, elongated blobs, orange balls): the false-detection benchmark counts hits on them.
    """

    kind: str = "cluttered"
    n_shapes: int = 40
    n_distractors: int = 0
    base_bgr: tuple[float, float, float] = (0.52, 0.53, 0.50)

    def __post_init__(self) -> None:
        if self.kind not in ("plain", "cluttered"):
            raise ValueError(f"background kind must be 'plain' or 'cluttered', not {self.kind!r}")


@dataclass
class SensorSpec:
    """Image formation: Gaussian read noise (DN), exposure time (motion blur), gain over time."""

    noise_sigma: float = 2.0
    exposure_s: float = 0.004
    blur_samples: int = 5
    gain: Callable[[float], float] | float = 1.0

    def gain_at(self, t: float) -> float:
        return float(self.gain(t)) if callable(self.gain) else float(self.gain)


@dataclass
class PointerScene:
    """Everything in view over time. `ball_path(t)` is the ball centre (None: no ball); the ball
    (and stick) are not drawn during the `hidden` time intervals (hand or robot in the way)."""

    ball_path: PathFn | np.ndarray | tuple | None
    ball_radius: float = 0.0125
    ball_bgr: tuple[float, float, float] = RED_BALL_BGR
    stick: StickSpec | None = field(default_factory=StickSpec)
    markers: list[SphereMarker] = field(default_factory=list)
    hidden: list[tuple[float, float]] = field(default_factory=list)
    boards: Callable[[float], list[PlanarTarget]] | None = None
    lighting: Lighting = field(default_factory=Lighting)
    background: BackgroundSpec = field(default_factory=BackgroundSpec)
    sensor: SensorSpec = field(default_factory=SensorSpec)

    def __post_init__(self) -> None:
        if self.ball_radius <= 0:
            raise ValueError("ball radius must be positive")
        self._ball = _as_path(self.ball_path)

    def ball_at(self, t: float) -> np.ndarray | None:
        """Ball centre at time t, whether or not it is hidden."""
        p = self._ball(t)
        return None if p is None else np.asarray(p, dtype=float)

    def ball_hidden(self, t: float) -> bool:
        return any(a <= t < b for a, b in self.hidden)

    def boards_at(self, t: float) -> list[PlanarTarget]:
        return [] if self.boards is None else list(self.boards(t))
