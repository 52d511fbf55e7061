"""Linear octree (Gargantini 1982): cells addressed by Morton/octal codes, only occupied stored.

Two parts:

* `OctreeGrid` is the geometry: a cube of side `size` centred on the robot base (world ->
  octree is a pure translation, thesis §6.1.3), split `depth` times. It converts, vectorised,
  between points, integer grid indices (i, j, k), Morton codes at any level and flat dense
  indices. A child's code is its parent's code with one octal digit appended
  (digit = x_bit + 2 y_bit + 4 z_bit), so ``parent = code >> 3``.
* `LinearOctree` stores values (occupancy probabilities) sparsely, one dict per level keyed by
  code. Only cells with a value > 0 are stored; a parent holds the max of its children (thesis
  §6.1.2). A node with stored children is *internal*; one without is *terminal* and stands for
  its whole block (that is how a coarse observation or a compacted full parent is kept).

Query semantics for a cell that is not stored: walk up to the nearest stored ancestor; if that
ancestor is terminal, the cell inherits its value (the thesis rule); if it is internal, its
children are stored explicitly, so a missing child is empty (0). This is Gargantini's reading;
the thesis' literal "inherit the parent's value" would make every empty sibling of an occupied
leaf look occupied.

Planners work on dense grids exported by `LinearOctree.to_dense` (32^3 = 32 k cells at the
default 62.5 mm leaves, 64^3 at 31.25 mm): neighbour loops over numpy arrays are far faster
than dict walks and the sizes are small; the octree stays the store of record.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from assistant.world.leaf_lookup import leaf_indices

Array = np.ndarray

#: Morton codes are uint64: 3 bits per level, so up to 21 levels.
MAX_DEPTH = 21


def _part1by2(v: Array) -> Array:
    """Spread the low 21 bits of v so that bit b lands on bit 3b."""
    x = v.astype(np.uint64) & np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)
    return x


def _compact1by2(x: Array) -> Array:
    """Inverse of `_part1by2`."""
    x = x.astype(np.uint64) & np.uint64(0x1249249249249249)
    x = (x | (x >> np.uint64(2))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x >> np.uint64(4))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x >> np.uint64(8))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x >> np.uint64(16))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x >> np.uint64(32))) & np.uint64(0x1FFFFF)
    return x


def morton_encode(ijk: Array) -> Array:
    """Morton codes (uint64) of integer cell indices, shape (N, 3) -> (N,)."""
    ijk = np.asarray(ijk, dtype=np.int64).reshape(-1, 3)
    return (_part1by2(ijk[:, 0]) | (_part1by2(ijk[:, 1]) << np.uint64(1))
            | (_part1by2(ijk[:, 2]) << np.uint64(2)))


def morton_decode(codes: Array) -> Array:
    """Integer cell indices (N, 3) int64 of Morton codes."""
    c = np.asarray(codes, dtype=np.uint64).reshape(-1)
    return np.stack([_compact1by2(c), _compact1by2(c >> np.uint64(1)),
                     _compact1by2(c >> np.uint64(2))], axis=1).astype(np.int64)


@dataclass(frozen=True)
class OctreeGrid:
    """A cube of side `size` (m) centred at `centre` (base frame), subdivided `depth` times.

    Build it with `OctreeGrid.for_leaf` to ask for a leaf size; the depth is rounded up so
    the real leaf is never coarser than asked (thesis: "the required number of subdivisions
    is automatically determined").
    """

    size: float = 2.0
    depth: int = 5
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not 0 <= self.depth <= MAX_DEPTH:
            raise ValueError(f"octree depth {self.depth} outside 0..{MAX_DEPTH}")
        if self.size <= 0:
            raise ValueError("octree size must be positive")

    @staticmethod
    def for_leaf(size: float = 2.0, leaf: float = 0.0625,
                 centre: Iterable[float] = (0.0, 0.0, 0.0)) -> OctreeGrid:
        """Smallest depth whose leaves are no larger than `leaf` (2 m / 62.5 mm -> depth 5)."""
        depth = max(0, math.ceil(math.log2(size / leaf) - 1e-9))
        c = tuple(float(v) for v in centre)
        return OctreeGrid(float(size), depth, (c[0], c[1], c[2]))

    # ---------------------------------------------------------------- sizes
    @property
    def n(self) -> int:
        """Leaves per axis."""
        return 1 << self.depth

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.n, self.n, self.n)

    @property
    def n_cells(self) -> int:
        return self.n ** 3

    @property
    def leaf(self) -> float:
        """Edge length of a leaf (m)."""
        return self.size / self.n

    @property
    def origin(self) -> Array:
        """The cube's minimum corner in the base frame."""
        return np.asarray(self.centre, dtype=float) - self.size / 2.0

    def cell_size(self, level: int) -> float:
        return self.size / (1 << level)

    # ---------------------------------------------------------------- conversions
    def ijk_of_points(self, P_base: Array) -> Array:
        """Leaf indices (N, 3) int64 of points in the base frame; see `inside`.

        Points outside the cube get an index just outside it (-1 or n) and non-finite ones -1,
        so a far or broken coordinate (1e27 m, NaN) can never wrap around into the cube
        through an overflowing integer cast."""
        P = np.asarray(P_base, dtype=float).reshape(-1, 3)
        q = (P - self.origin) / self.leaf
        q = np.nan_to_num(q, nan=-1.0, posinf=float(self.n), neginf=-1.0)
        return np.floor(np.clip(q, -1.0, float(self.n))).astype(np.int64)

    def inside(self, ijk: Array) -> Array:
        ijk = np.asarray(ijk).reshape(-1, 3)
        return np.all((ijk >= 0) & (ijk < self.n), axis=1)

    def centres_of_ijk(self, ijk: Array, level: int | None = None) -> Array:
        """Centres (N, 3) of cells given by their indices at `level` (default: leaves)."""
        level = self.depth if level is None else level
        s = self.cell_size(level)
        return self.origin + (np.asarray(ijk, dtype=float).reshape(-1, 3) + 0.5) * s

    def codes_of_ijk(self, ijk: Array, level: int | None = None) -> Array:
        """Morton codes at `level` of leaf indices (the leaves' ancestors at that level)."""
        level = self.depth if level is None else level
        shift = self.depth - level
        return morton_encode(np.asarray(ijk, dtype=np.int64).reshape(-1, 3) >> shift)

    def ijk_of_codes(self, codes: Array, level: int | None = None) -> Array:
        """Cell indices at `level` (not leaves unless level == depth) of Morton codes."""
        return morton_decode(codes)

    def codes_of_points(self, P_base: Array, level: int | None = None) -> Array:
        return self.codes_of_ijk(self.ijk_of_points(P_base), level)

    def flat_of_ijk(self, ijk: Array) -> Array:
        """Flat index into a dense (n, n, n) C-order array."""
        ijk = np.asarray(ijk, dtype=np.int64).reshape(-1, 3)
        return (ijk[:, 0] * self.n + ijk[:, 1]) * self.n + ijk[:, 2]

    def ijk_of_flat(self, flat: Array) -> Array:
        f = np.asarray(flat, dtype=np.int64).reshape(-1)
        n = self.n
        return np.stack([f // (n * n), (f // n) % n, f % n], axis=1)

    def flat_of_points(self, P_base: Array) -> Array:
        """Flat leaf index of each point, -1 where the point lies outside the cube (or is
        not finite): `ijk_of_points`, `inside` and `flat_of_ijk` in one compiled pass."""
        P = np.ascontiguousarray(np.asarray(P_base, dtype=float).reshape(-1, 3))
        return leaf_indices(P, self.origin, float(self.leaf), self.n)

    def codes_of_flat(self, flat: Array) -> Array:
        return self.codes_of_ijk(self.ijk_of_flat(flat))

    def flat_of_codes(self, codes: Array) -> Array:
        """Flat leaf index of leaf-level codes."""
        return self.flat_of_ijk(morton_decode(codes))

    def octal(self, code: int, level: int | None = None) -> str:
        """The code as Gargantini's octal string, one digit per level from the root."""
        level = self.depth if level is None else level
        if level == 0:
            return ""
        return format(int(code), "o").zfill(level)

    def to_json(self) -> dict:
        return {"size": self.size, "depth": self.depth, "centre": list(self.centre)}


@dataclass
class LinearOctree:
    """Sparse occupancy values per cell, keyed by Morton code, one dict per level.

    Only values > 0 are stored. Every stored node's value is the max of its stored children
    (kept up to date by `set`). Use `value` for point queries with the nearest-ancestor rule
    and `to_dense` for the planners' grid view.
    """

    grid: OctreeGrid
    _levels: list[dict[int, float]] = field(init=False, repr=False)
    _n_children: list[dict[int, int]] = field(init=False, repr=False)
    #: Dense views per level, kept until the next change: a planning query reads the grid
    #: half a dozen times (terminals, search costs, squeeze rule, the net's free cells), and
    #: building it walks every stored node (~1.4 ms at 62.5 mm leaves).
    _dense: dict[int, Array] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._levels = [{} for _ in range(self.grid.depth + 1)]
        self._n_children = [{} for _ in range(self.grid.depth + 1)]
        self._dense = {}

    # ---------------------------------------------------------------- inspection
    @property
    def depth(self) -> int:
        return self.grid.depth

    def stored(self, level: int | None = None) -> dict[int, float]:
        """A copy of the stored {code: value} of one level (default: leaves)."""
        level = self.depth if level is None else level
        return dict(self._levels[level])

    def n_stored(self) -> int:
        return sum(len(d) for d in self._levels)

    def is_internal(self, code: int, level: int) -> bool:
        return self._n_children[level].get(int(code), 0) > 0

    # ---------------------------------------------------------------- updates
    def set(self, codes: Array, values: Array, level: int | None = None) -> None:
        """Set the value of cells at `level` (default leaves); 0 removes a cell.

        Setting a cell below a terminal ancestor first splits that ancestor (its children
        inherit its value), so the rest of its block keeps what it had. A cell set at a coarse
        level replaces any finer cells under it (it becomes terminal).
        """
        level = self.depth if level is None else level
        self._dense.clear()
        codes = np.asarray(codes, dtype=np.uint64).reshape(-1)
        values = np.broadcast_to(np.asarray(values, dtype=float), codes.shape)
        touched: set[int] = set()
        for c, v in zip(codes.tolist(), values.tolist(), strict=True):
            self._split_terminal_ancestors(c, level)
            self._drop_subtree(c, level)
            self._store(level, c, float(v))
            touched.add(c)
        self._refresh_ancestors(touched, level)

    def set_leaves(self, codes: Array, values: Array) -> None:
        self.set(codes, values, self.depth)

    def compact(self) -> int:
        """Merge every node whose 8 children are terminal with one equal value (Gargantini's
        "fully occupied parent"); returns how many nodes were merged away."""
        merged = 0
        self._dense.clear()
        for level in range(self.depth, 0, -1):
            parents: dict[int, list[int]] = {}
            for c in self._levels[level]:
                if not self.is_internal(c, level):
                    parents.setdefault(c >> 3, []).append(c)
            for p, kids in parents.items():
                if len(kids) != 8 or self._n_children[level - 1].get(p, 0) != 8:
                    continue
                vals = {self._levels[level][k] for k in kids}
                if len(vals) != 1:
                    continue
                for k in kids:
                    del self._levels[level][k]
                self._n_children[level - 1].pop(p, None)
                self._levels[level - 1][p] = vals.pop()
                merged += 8
        return merged

    def _store(self, level: int, code: int, value: float) -> None:
        d = self._levels[level]
        existed = code in d
        if value > 0.0:
            d[code] = value
            if not existed and level > 0:
                pc = self._n_children[level - 1]
                pc[code >> 3] = pc.get(code >> 3, 0) + 1
        elif existed:
            del d[code]
            if level > 0:
                pc = self._n_children[level - 1]
                left = pc.get(code >> 3, 0) - 1
                if left > 0:
                    pc[code >> 3] = left
                else:
                    pc.pop(code >> 3, None)

    def _split_terminal_ancestors(self, code: int, level: int) -> None:
        # Find the nearest stored terminal ancestor, push its value down to `level - 1`.
        for up in range(1, level + 1):
            a_level, a_code = level - up, code >> (3 * up)
            if a_code in self._levels[a_level]:
                if self.is_internal(a_code, a_level):
                    return
                value = self._levels[a_level][a_code]
                # Push down along the path: each node on the way becomes internal with its
                # 8 children carrying the old value.
                for lv in range(a_level, level):
                    node = code >> (3 * (level - lv))
                    for d in range(8):
                        child = (node << 3) | d
                        if child not in self._levels[lv + 1]:
                            self._store(lv + 1, child, value)
                return

    def _drop_subtree(self, code: int, level: int) -> None:
        if not self.is_internal(code, level):
            return
        frontier = [code]
        for lv in range(level + 1, self.depth + 1):
            nxt = []
            for p in frontier:
                for d in range(8):
                    c = (p << 3) | d
                    if c in self._levels[lv]:
                        if self.is_internal(c, lv):
                            nxt.append(c)
                        self._store(lv, c, 0.0)
            frontier = nxt
            if not frontier:
                break

    def _refresh_ancestors(self, codes: set[int], level: int) -> None:
        """Parent = max of stored children, level by level up to the root."""
        current = codes
        for lv in range(level, 0, -1):
            parents = {c >> 3 for c in current}
            child_d, parent_d = self._levels[lv], self._levels[lv - 1]
            for p in parents:
                vals = [child_d[(p << 3) | d] for d in range(8) if (p << 3) | d in child_d]
                if vals:
                    parent_d[p] = max(vals)
                else:
                    parent_d.pop(p, None)
            current = parents
        self._recount()

    def _recount(self) -> None:
        for lv in range(1, self.depth + 1):
            counts: dict[int, int] = {}
            for c in self._levels[lv]:
                counts[c >> 3] = counts.get(c >> 3, 0) + 1
            self._n_children[lv - 1] = counts

    # ---------------------------------------------------------------- queries
    def value(self, codes: Array, level: int | None = None) -> Array:
        """Values of cells at `level`, with the nearest-ancestor rule for missing cells."""
        level = self.depth if level is None else level
        codes = np.asarray(codes, dtype=np.uint64).reshape(-1)
        out = np.zeros(len(codes))
        for i, c in enumerate(codes.tolist()):
            out[i] = self._value_one(c, level)
        return out

    def _value_one(self, code: int, level: int) -> float:
        d = self._levels[level]
        if code in d:
            return d[code]
        for up in range(1, level + 1):
            a_level, a_code = level - up, code >> (3 * up)
            if a_code in self._levels[a_level]:
                if self.is_internal(a_code, a_level):
                    return 0.0
                return self._levels[a_level][a_code]
        return 0.0

    def value_at_points(self, P_base: Array, level: int | None = None) -> Array:
        ijk = self.grid.ijk_of_points(P_base)
        out = np.zeros(len(ijk))
        ok = self.grid.inside(ijk)
        out[ok] = self.value(self.grid.codes_of_ijk(ijk[ok], level), level)
        return out

    def to_dense(self, level: int | None = None) -> Array:
        """A dense (m, m, m) float32 array of the values at `level` (m = 2**level).

        Read-only: the same array is returned until the octree changes."""
        level = self.depth if level is None else level
        cached = self._dense.get(level)
        if cached is None:
            cached = self._dense[level] = self._build_dense(level)
            cached.setflags(write=False)
        return cached

    def _build_dense(self, level: int) -> Array:
        m = 1 << level
        out = np.zeros((m, m, m), dtype=np.float32)
        # Coarser terminal nodes fill their blocks; then finer levels (max-reduced) overwrite.
        for lv in range(0, self.depth + 1):
            d = self._levels[lv]
            if not d:
                continue
            codes = np.fromiter(d.keys(), dtype=np.uint64, count=len(d))
            vals = np.fromiter(d.values(), dtype=np.float64, count=len(d))
            if lv <= level:
                terminal = np.array([not self.is_internal(int(c), lv) for c in codes.tolist()],
                                    dtype=bool)
                if lv == level:
                    terminal[:] = True  # nodes at the asked level give their (max) value
                codes, vals = codes[terminal], vals[terminal]
                if not len(codes):
                    continue
                ijk = morton_decode(codes)
                s = 1 << (level - lv)
                for (i, j, k), v in zip(ijk.tolist(), vals.tolist(), strict=True):
                    out[i * s:(i + 1) * s, j * s:(j + 1) * s, k * s:(k + 1) * s] = v
        return out
