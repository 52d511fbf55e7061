"""Which cells start a brushfire front, and with which region label.

The thesis labels each obstacle and the border; here a *region* is a 26-connected component of
the cells of one source object, not of all blocked cells: in a real cell every part stands on
the table, so components of the union would merge O1, O2 and the table into one region and no
road would form between them. Regions:

* CAD objects: components of the occupied leaves of each object (name from the cell model);
* other evidence (button, sensors, camera): components of occupied leaves not owned by CAD;
* unreachable space (no joint position reaches the leaf): its components ("unreachable
  regions count as obstacles", thesis §8.5.5);
* *shadows* - leaves the TCP reaches only with the arm inside an obstacle (no valid joint
  position): they belong to whatever makes them blocked, so they take the label of the nearest
  region above by a brushfire restricted to the shadow cells; shadows touching no region get
  their own label;
* free leaves on the octree border (rare: the reach usually ends inside the cube).

Start and goal get the next two labels per query (`with_terminals`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from assistant.roadmap.grid_ops import components26, neighbour_any, neighbour_min

Array = np.ndarray

_BIG = np.int32(2**30)


@dataclass(frozen=True)
class SourceLabels:
    """`source`: int32 grid, region label > 0 on source cells, 0 on free cells."""

    source: Array
    names: dict[int, str] = field(default_factory=dict)

    @property
    def next_label(self) -> int:
        return max(self.names, default=0) + 1

    def terminals(self, start_cell: int, goal_cell: int) -> tuple[Array, Array]:
        """The flat cells of the start and goal leaves and their labels (the next two); one
        cell, the start's, when both lie in the same leaf."""
        s_lab = self.next_label
        if goal_cell == start_cell:
            return np.array([start_cell], dtype=np.int64), np.array([s_lab], dtype=np.int32)
        return (np.array([start_cell, goal_cell], dtype=np.int64),
                np.array([s_lab, s_lab + 1], dtype=np.int32))

    def with_terminals(self, start_cell: int, goal_cell: int) -> tuple[Array, int, int]:
        """The source grid with the start and goal leaves as sources of their own labels.

        They override whatever the leaf was (the robot stands in its start cell even if an
        indication marked it). Returns (grid, start label, goal label).
        """
        cells, labels = self.terminals(start_cell, goal_cell)
        src = self.source.copy()
        src.reshape(-1)[cells] = labels
        return src, self.next_label, self.next_label + 1


def _border(shape: tuple[int, ...]) -> Array:
    """The outer layer of the grid (axes of size 1 are a 2-D grid's thickness, not a border)."""
    edge = np.zeros(shape, dtype=bool)
    for a, n in enumerate(shape):
        if n > 1:
            idx = [slice(None)] * len(shape)
            idx[a] = [0, n - 1]
            edge[tuple(idx)] = True
    return edge


def label_sources(occupied: Array, object_ids: Array, object_names: list[str],
                  reachable: Array, has_valid: Array, *, border: bool = True) -> SourceLabels:
    """Region labels of every source cell (see the module docstring)."""
    shape = occupied.shape
    src = np.zeros(shape, dtype=np.int32)
    names: dict[int, str] = {}
    nxt = 1

    def add(mask: Array, name: str) -> None:
        nonlocal nxt
        comp, n = components26(mask)
        for k in range(1, n + 1):
            names[nxt] = name if n == 1 else f"{name}#{k}"
            src[comp == k] = nxt
            nxt += 1

    for oid in sorted(set(np.unique(object_ids[occupied]).tolist())):
        if oid > 0:
            name = object_names[oid - 1] if oid - 1 < len(object_names) else f"object{oid}"
        else:
            name = "observed"
        add(occupied & (object_ids == oid), name)
    add(~reachable & ~occupied, "unreachable")
    # Shadows take the nearest region's label.
    shadow = reachable & ~has_valid & ~occupied
    todo = shadow.copy()
    while todo.any():
        front = todo & neighbour_any(src > 0)
        if not front.any():
            break
        lab = neighbour_min(np.where(src > 0, src, _BIG), _BIG)
        src[front] = lab[front]
        todo &= ~front
    add(todo, "blocked")
    if border:
        add(_border(shape) & (src == 0), "border")
    return SourceLabels(src, names)


def relabel(prev: SourceLabels, occupied: Array, object_ids: Array, object_names: list[str],
            reachable: Array, has_valid: Array, *, border: bool = True) -> SourceLabels:
    """Source labels after the world changed, keeping every existing label where it still
    applies, so only the changed cells differ and the brushfire can update locally.

    New occupied cells join an adjacent region of the same object (or "observed" evidence),
    else form new regions; new shadows take the nearest label; cells that stopped being
    sources are freed.
    """
    shape = occupied.shape
    shadow = reachable & ~has_valid & ~occupied
    edge = _border(shape) if border else np.zeros(shape, dtype=bool)
    free = ~occupied & reachable & has_valid
    want = occupied | ~reachable | shadow | (edge & free)
    src = np.where(want, prev.source, 0).astype(np.int32)
    names = {k: v for k, v in prev.names.items() if (src == k).any()}
    nxt = max(prev.names, default=0) + 1
    new = want & (src == 0)
    by_name: dict[str, list[int]] = {}
    for k, v in names.items():
        by_name.setdefault(v.split("#")[0], []).append(k)

    def add(mask: Array, name: str) -> None:
        nonlocal nxt
        comp, n = components26(mask)
        for k in range(1, n + 1):
            cells = comp == k
            touch = neighbour_any(cells)
            same = [lab for lab in by_name.get(name, []) if (touch & (src == lab)).any()]
            if same:
                src[cells] = min(same)
            else:
                names[nxt] = f"{name}#{nxt}"
                by_name.setdefault(name, []).append(nxt)
                src[cells] = nxt
                nxt += 1

    for oid in sorted(set(np.unique(object_ids[new & occupied]).tolist())):
        name = (object_names[oid - 1] if 0 < oid <= len(object_names)
                else ("observed" if oid <= 0 else f"object{oid}"))
        add(new & occupied & (object_ids == oid), name)
    add(new & ~reachable & ~occupied, "unreachable")
    todo = new & shadow
    while todo.any():
        front = todo & neighbour_any(src > 0)
        if not front.any():
            break
        lab = neighbour_min(np.where(src > 0, src, _BIG), _BIG)
        src[front] = lab[front]
        todo &= ~front
    add(todo, "blocked")
    add(new & edge & free & (src == 0), "border")
    return SourceLabels(src, names)
