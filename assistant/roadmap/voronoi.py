"""Cell-extension Voronoi roadmap: multi-source brushfire with labels (thesis Listings 7-9).

Sources are the cells of obstacles, unreachable regions, the border and (per query) the start
and goal, each with a region label > 0. Fronts grow from all sources at once, one layer of the
26-neighbourhood per step (Chebyshev distance). A free cell reached at distance d takes the
label of its neighbours at distance d - 1; if those carry different labels (fronts of two
regions meet in it) it becomes a road: ROAD (-1) if reachable, ROAD_UNREACHABLE (0) if not
(Listing 7, 2.2.1). Roads do not propagate a label.

Two details the thesis leaves open, fixed here so the result does not depend on processing
order (and so an incremental update can equal a rebuild exactly):

* Even gaps: two fronts can meet *between* cells - neighbours at the same distance with
  different labels, neither seeing two labels below it. Then the one with the smaller label
  becomes a road, so roads stay connected across even gaps.
* A free cell whose predecessors are all roads becomes a road too.

Incremental update (Listing 9): when sources change (new obstacle cells, start/goal), cells
within `d_min` of the change are reset and the extension re-runs over that region with the
values outside held fixed. The thesis stops there; we then check the ring just outside the
region and, where a value there would change, grow the region and repeat - every cell then
satisfies the local brushfire equations, whose solution is unique, so the result equals a full
rebuild (tested on random grids).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.roadmap import brushfire
from assistant.roadmap.brushfire import ROAD, ROAD_UNREACHABLE, UNREACHED, brushfire_region
from assistant.roadmap.grid_ops import bbox
from assistant.roadmap.voronoi_update import terminal_round, update_rounds

Array = np.ndarray

__all__ = ["INF", "ROAD", "ROAD_UNREACHABLE", "UNREACHED", "VoronoiMap", "VoronoiUpdate",
           "build_voronoi", "terminal_labels", "update_voronoi"]

#: Distance of cells no front reaches.
INF = np.int32(brushfire.INF)


@dataclass
class VoronoiMap:
    """The brushfire result on a grid.

    `source`: label > 0 of source cells, 0 elsewhere. `dist`: layer at which a front reached
    the cell (0 for sources, INF if never). `tent`: the label seen from below before the
    even-gap rule (>= 1, or ROAD for several/none). `label`: the final mark: a region label,
    ROAD, ROAD_UNREACHABLE, or UNREACHED.
    """

    source: Array
    reachable: Array
    dist: Array
    tent: Array
    label: Array

    @property
    def shape(self) -> tuple[int, ...]:
        return self.source.shape

    def roads(self) -> Array:
        return self.label == ROAD

    def region(self, label: int) -> Array:
        """Cells carrying `label` (its source cells and the free cells its front took)."""
        return self.label == label

    def copy(self) -> VoronoiMap:
        return VoronoiMap(self.source.copy(), self.reachable.copy(), self.dist.copy(),
                          self.tent.copy(), self.label.copy())

    def same_as(self, other: VoronoiMap) -> bool:
        return (np.array_equal(self.source, other.source)
                and np.array_equal(self.dist, other.dist)
                and np.array_equal(self.tent, other.tent)
                and np.array_equal(self.label, other.label))


@dataclass(frozen=True)
class VoronoiUpdate:
    vmap: VoronoiMap
    changed: Array  # bool grid: dist, tentative or final label changed
    region_cells: int  # cells recomputed in the last round
    rounds: int
    rebuilt: bool  # the region kept growing past the budget: fell back to a full rebuild


def _empty(source: Array, reachable: Array) -> VoronoiMap:
    shape = source.shape
    return VoronoiMap(source.astype(np.int32), reachable.astype(bool),
                      np.full(shape, INF, dtype=np.int32), np.full(shape, UNREACHED, np.int32),
                      np.full(shape, UNREACHED, np.int32))


def build_voronoi(source: Array, reachable: Array | None = None) -> VoronoiMap:
    """Full brushfire over the grid. `source`: int grid, label > 0 for sources."""
    source = np.asarray(source, dtype=np.int32)
    if source.ndim != 3:
        raise ValueError("grids are 3-D; give a 2-D grid as shape (n, m, 1)")
    reachable = np.ones(source.shape, bool) if reachable is None else np.asarray(reachable, bool)
    vmap = _empty(source, reachable)
    _recompute(vmap, np.ones(source.shape, dtype=bool))
    return vmap


def _recompute(vmap: VoronoiMap, region: Array) -> None:
    """Recompute dist/tent/label inside `region` with the values outside held fixed
    (compiled: `brushfire.brushfire_region`, on the region's bounding box)."""
    sl = bbox(region, margin=1)
    if sl is None:
        return
    R = np.ascontiguousarray(region[sl])
    D, T, L = vmap.dist[sl].copy(), vmap.tent[sl].copy(), vmap.label[sl].copy()
    brushfire_region(D, T, L, np.ascontiguousarray(vmap.source[sl]),
                     np.ascontiguousarray(vmap.reachable[sl]), R)
    vmap.dist[sl][R] = D[R]
    vmap.tent[sl][R] = T[R]
    vmap.label[sl][R] = L[R]


def update_voronoi(vmap: VoronoiMap, source: Array, *, d_min: int = 3,
                   max_rounds: int = 12) -> VoronoiUpdate:
    """The map for new `source` labels, recomputed locally around the changed cells.

    `d_min` (cells) is the thesis' reset radius around a new obstacle; the region then grows
    only as far as the change really reaches (module docstring). Past `max_rounds` growth
    rounds it falls back to a full rebuild (reported in `rebuilt`).
    """
    source = np.asarray(source, dtype=np.int32)
    changed_src = source != vmap.source
    if not changed_src.any():
        return VoronoiUpdate(vmap.copy(), np.zeros(vmap.shape, bool), 0, 0, False)
    D, T, L, diff, cells, rounds, done = update_rounds(
        vmap.dist, vmap.tent, vmap.label, source, np.ascontiguousarray(vmap.reachable),
        changed_src, int(d_min), int(max_rounds))
    if done:
        return VoronoiUpdate(VoronoiMap(source, vmap.reachable, D, T, L), diff, cells, rounds,
                             False)
    full = build_voronoi(source, vmap.reachable)
    return VoronoiUpdate(full, _differs(full, vmap), int(np.prod(vmap.shape)), max_rounds, True)


def terminal_labels(vmap: VoronoiMap, cells: Array, labels: Array, *, d_min: int = 3,
                    max_rounds: int = 12) -> Array:
    """`update_voronoi(vmap, source).vmap.label` for the source grid with `labels` put on
    the flat `cells` (a query's start and goal), without building the updated map: the
    compiled first round on its own box (`voronoi_update.terminal_round`), and the whole
    update only when that round's ring changed."""
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    labels = np.ascontiguousarray(labels, dtype=np.int32)
    label, done = terminal_round(vmap.dist, vmap.tent, vmap.label, vmap.source,
                                 np.ascontiguousarray(vmap.reachable), cells, labels,
                                 int(d_min))
    if done:
        return label
    source = vmap.source.copy()
    source.reshape(-1)[cells] = labels
    return update_voronoi(vmap, source, d_min=d_min, max_rounds=max_rounds).vmap.label


def _differs(a: VoronoiMap, b: VoronoiMap) -> Array:
    return (a.dist != b.dist) | (a.tent != b.tent) | (a.label != b.label)
