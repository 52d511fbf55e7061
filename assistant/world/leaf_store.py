"""What every joint-position store offers: joint positions grouped by the octree leaf of their TCP.

Two stores implement it: the thesis' full joint grid (`reachability.ReachabilityTable`, the
RV-2AJ: every grid point, exponential in the axes) and a fixed budget of low-discrepancy
samples (`joint_samples.SampledTable`, any 6- or 7-axis arm: memory linear in the budget).
Consumers (valid positions per leaf, the chain validator, indications, the roadmap) see ids:
opaque int ids of positions, `joints(ids)` decodes them, `positions` (int32) lists them grouped
by leaf in CSR form (`leaves` ascending flat leaf ids, `offsets`), each leaf's list in an order
whose every prefix is spread over the whole list.

`step` is the per-joint resolution (rad): one step of joint i moves the TCP at most d_step.
`counts[i] == 1` marks a joint the store does not vary (it cannot move the TCP).
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Self

import numpy as np

from assistant.world.octree import OctreeGrid

Array = np.ndarray


class WorldBudgetError(ValueError):
    """A world model request would exceed a configured budget (memory, samples)."""


@dataclass
class JointStore:
    """Leaf-grouped joint positions; subclasses say what an id is (see the module docstring)."""

    key: str
    grid: OctreeGrid
    radii: Array  # r_i (m) per joint
    lower: Array  # lowest value per joint (rad); the fixed value of a fixed joint
    step: Array  # resolution per joint (rad), 0 for fixed joints
    counts: Array  # grid values per joint; 1 for fixed joints
    leaves: Array  # (L,) int64 flat leaf ids, ascending
    offsets: Array  # (L + 1,) int64
    positions: Array  # (N,) int32 ids, grouped by leaf, diversity order
    build_seconds: float = 0.0
    _slot: Array | None = field(default=None, repr=False)
    _inverse: Array | None = field(default=None, repr=False)

    kind: ClassVar[str] = "store"

    @property
    def dof(self) -> int:
        return len(self.counts)

    @property
    def n_positions(self) -> int:
        return len(self.positions)

    @property
    def steps_deg(self) -> Array:
        """The thesis' Table 8 view: step per joint in degrees (0 for fixed joints)."""
        return np.degrees(self.step)

    @property
    def id_space(self) -> int:
        """Upper bound (exclusive) of the ids."""
        raise NotImplementedError

    def joints(self, ids: Array) -> Array:
        raise NotImplementedError

    def ids_in_box(self, q: Array, half_steps: float) -> Array:
        raise NotImplementedError

    def prefix_space(self, n_joints: int) -> int:
        """Number of distinct values `prefixes(ids, n_joints)` can take."""
        raise NotImplementedError

    def prefixes(self, ids: Array, n_joints: int) -> Array:
        """Per id, an id of its values in the first `n_joints` joints (shared prefixes let the
        chain validator check a link once for every position below it)."""
        raise NotImplementedError

    def prefix_configs(self, n_joints: int, prefixes: Array, rest: Array) -> Array:
        """Configurations (n, dof) with the prefixes' leading joints; the others any value
        (`rest` where the store has no value of its own)."""
        raise NotImplementedError

    def index_of_ids(self, ids: Array) -> Array:
        """Index into `positions` of ids, -1 where the id is not stored (its TCP is outside
        the octree). The inverse map (4 bytes per id) is built once."""
        if self._inverse is None:
            inv = np.full(self.id_space, -1, dtype=np.int32)
            inv[self.positions] = np.arange(self.n_positions, dtype=np.int32)
            self._inverse = inv
        return self._inverse[np.asarray(ids, dtype=np.int64)].astype(np.int64)

    # ---------------------------------------------------------------- leaves
    def slot_of_leaf(self, flat_leaves: Array) -> Array:
        """Index into `leaves` of flat leaf ids, -1 for unreachable leaves."""
        if self._slot is None:
            s = np.full(self.grid.n_cells, -1, dtype=np.int32)
            s[self.leaves] = np.arange(len(self.leaves), dtype=np.int32)
            self._slot = s
        return self._slot[np.asarray(flat_leaves, dtype=np.int64)]

    def positions_in(self, flat_leaf: int) -> Array:
        """Ids binned into one leaf (diversity order); empty if unreachable."""
        s = int(self.slot_of_leaf(np.array([flat_leaf]))[0])
        if s < 0:
            return self.positions[:0]
        return self.positions[self.offsets[s]:self.offsets[s + 1]]

    def counts_per_leaf(self) -> Array:
        return np.diff(self.offsets)

    def reachable(self) -> Array:
        """Dense bool grid: the leaf holds at least one joint position."""
        m = np.zeros(self.grid.n_cells, dtype=bool)
        m[self.leaves] = True
        return m.reshape(self.grid.shape)

    def leaf_of_positions(self) -> Array:
        """(N,) flat leaf id of every stored position (expanded from the CSR offsets)."""
        return np.repeat(self.leaves, np.diff(self.offsets))

    def nbytes(self) -> int:
        return int(self.leaves.nbytes + self.offsets.nbytes + self.positions.nbytes)

    # ---------------------------------------------------------------- persistence
    #: Arrays a subclass keeps beyond the common ones (saved and loaded by field name).
    extra_arrays: ClassVar[tuple[str, ...]] = ()

    def save(self, path: Path) -> None:
        save_npz(path, key=np.array(self.key), grid=np.array(json.dumps(self.grid.to_json())),
                 radii=self.radii, lower=self.lower, step=self.step, counts=self.counts,
                 leaves=self.leaves, offsets=self.offsets, positions=self.positions,
                 build_seconds=np.array(self.build_seconds),
                 **{name: getattr(self, name) for name in self.extra_arrays})

    @classmethod
    def load(cls, path: Path) -> Self:
        with np.load(path) as z:
            g = json.loads(str(z["grid"]))
            return cls(key=str(z["key"]),
                       grid=OctreeGrid(g["size"], g["depth"], tuple(g["centre"])),
                       radii=z["radii"], lower=z["lower"], step=z["step"], counts=z["counts"],
                       leaves=z["leaves"], offsets=z["offsets"], positions=z["positions"],
                       build_seconds=float(z["build_seconds"]),
                       **{name: z[name] for name in cls.extra_arrays})


def save_npz(path: Path, **arrays: Array) -> None:
    """Write atomically: a temporary file in the same folder, then a rename (a cancelled or
    failed write leaves no file behind)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".reach-", suffix=".npz.tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
