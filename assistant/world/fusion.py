"""Fusion of occupancy observations from several sources into one probability per cell (§6.4).

Sources: CAD (rasterised models), the operator's collision button, a (simulated or real)
distance/contact sensor and the camera. Each has a reliability weight r_s in [0, 1] and a
moving-average window n_s. Per cell and source we keep that source's last n_s observations
o in [0, 1] and compute (thesis eqs. 8-12):

* SMA_s = mean of the last n_s values                       (eq. 9, per source)
* rel_s = 1 - mean |o_k - o_(k-1)| over those values          (eqs. 10-11; 1 with one value)
* P_s   = SMA_s * rel_s                                      (eq. 12)
* P     = sum_s r_s P_s / sum_s r_s over the sources that observed the cell   (eq. 8)

and the roadmap's binary occupancy is P >= threshold (eq. 50). Why per source and not one
history per cell as in the thesis: the SMA is linear, so with equal windows and synchronous
sources both orders give the same value; but the sources here are asynchronous (the button
fires once, the camera at frame rate), and a shared history would let the next camera frame
dilute an indication the operator just gave. With its own window of 1 the button registers at
once and stays; a flickering sensor loses weight through its own reliability term.

Thesis values: the reliabilities were "predefined based on experience" and the window order
and threshold symbols were lost in extraction, so every default below is ours (documented
per field); only the structure of the formulas is the thesis'.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

Array = np.ndarray


class Source(str, Enum):
    CAD = "cad"
    BUTTON = "button"
    SENSOR = "sensor"
    CAMERA = "camera"


@dataclass(frozen=True)
class SourceParams:
    """Reliability weight r_s in [0, 1] and moving-average window n_s >= 1 of one source."""

    reliability: float
    window: int

    def __post_init__(self) -> None:
        if not 0.0 <= self.reliability <= 1.0:
            raise ValueError("reliability must lie in [0, 1]")
        if self.window < 1:
            raise ValueError("window must be >= 1")


def _default_sources() -> dict[Source, SourceParams]:
    return {
        # Models are often inaccurate (thesis §6.3) but static: one observation is the truth
        # of the model. Less reliable than the operator (thesis §6.4).
        Source.CAD: SourceParams(0.7, 1),
        # The operator is the reference collision sensor: full weight, window 1 so a single
        # press registers at once.
        Source.BUTTON: SourceParams(1.0, 1),
        # Noisy sources are smoothed over 5 observations.
        Source.SENSOR: SourceParams(0.6, 5),
        Source.CAMERA: SourceParams(0.5, 5),
    }


@dataclass(frozen=True)
class FusionConfig:
    """Per-source parameters and the occupancy threshold (ours: 0.5, the thesis' was lost)."""

    sources: Mapping[Source, SourceParams] = field(default_factory=_default_sources)
    threshold: float = 0.5

    def params(self, source: Source) -> SourceParams:
        try:
            return self.sources[Source(source)]
        except KeyError as e:
            raise KeyError(f"no fusion parameters for source {source!r}") from e

    def to_json(self) -> dict:
        return {"threshold": self.threshold,
                "sources": {s.value: [p.reliability, p.window] for s, p in self.sources.items()}}


@dataclass(frozen=True)
class FusionUpdate:
    """Cells touched by one `observe` call with their probability before and after."""

    cells: Array
    before: Array
    after: Array
    threshold: float

    @property
    def flipped(self) -> Array:
        """Cells whose binary occupancy (P >= threshold) changed."""
        return self.cells[(self.before >= self.threshold) != (self.after >= self.threshold)]


def source_probability(values: Iterable[float]) -> tuple[float, float, float]:
    """(SMA, reliability, P) of one source's window of observations."""
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return 0.0, 1.0, 0.0
    sma = float(v.mean())
    rel = 1.0 - float(np.abs(np.diff(v)).mean()) if v.size > 1 else 1.0
    return sma, rel, sma * rel


class OccupancyFusion:
    """Per-cell, per-source observation windows and the fused probability.

    Cells are any hashable integer key (the world uses leaf Morton codes). Sparse: a cell
    exists only once some source observed it.
    """

    def __init__(self, config: FusionConfig | None = None):
        self.config = config or FusionConfig()
        self._cells: dict[int, dict[Source, deque[float]]] = {}

    def __len__(self) -> int:
        return len(self._cells)

    def observe(self, source: Source | str, cells: Array, values: Array | float) -> FusionUpdate:
        """Add one observation o in [0, 1] per cell from `source`; returns P before/after."""
        source = Source(source)
        params = self.config.params(source)
        cells = np.asarray(cells, dtype=np.int64).reshape(-1)
        vals = np.clip(np.broadcast_to(np.asarray(values, dtype=float), cells.shape), 0.0, 1.0)
        before = self.probability(cells)
        for c, v in zip(cells.tolist(), vals.tolist(), strict=True):
            per_source = self._cells.setdefault(c, {})
            win = per_source.get(source)
            if win is None:
                win = per_source[source] = deque(maxlen=params.window)
            win.append(float(v))
        after = self.probability(cells)
        return FusionUpdate(cells, before, after, self.config.threshold)

    def forget(self, source: Source | str, cells: Array) -> FusionUpdate:
        """Drop a source's observations of cells (e.g. a CAD object was removed or moved)."""
        source = Source(source)
        cells = np.asarray(cells, dtype=np.int64).reshape(-1)
        before = self.probability(cells)
        for c in cells.tolist():
            per_source = self._cells.get(c)
            if per_source is not None:
                per_source.pop(source, None)
                if not per_source:
                    del self._cells[c]
        return FusionUpdate(cells, before, self.probability(cells), self.config.threshold)

    def probability(self, cells: Array) -> Array:
        cells = np.asarray(cells, dtype=np.int64).reshape(-1)
        return np.array([self._p(c) for c in cells.tolist()], dtype=float)

    def _p(self, cell: int) -> float:
        per_source = self._cells.get(cell)
        if not per_source:
            return 0.0
        num = den = 0.0
        for source, win in per_source.items():
            r = self.config.params(source).reliability
            num += r * source_probability(win)[2]
            den += r
        return num / den if den > 0.0 else 0.0

    def breakdown(self, cell: int) -> dict[str, tuple[float, float, float]]:
        """Per source (SMA, reliability, P) of one cell, for the UI and for tests."""
        per_source = self._cells.get(int(cell), {})
        return {s.value: source_probability(w) for s, w in per_source.items()}

    def cells(self) -> Array:
        return np.fromiter(self._cells.keys(), dtype=np.int64, count=len(self._cells))
