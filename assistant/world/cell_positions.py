"""The joint positions each leaf offers the search: the first K valid ones in diversity order.

The table holds ~5 M positions for the RV-2AJ (median ~900 per leaf); the A* connects every
position of a cell to every position of its neighbours, so it wants a few, well spread ones
(thesis §8.5.6: too many make the search slow, too few make it fail). Checking all 5 M
against CAD would take a minute, so validity is resolved lazily per leaf: walk the leaf's
list in diversity order (`reachability` module), check a batch, keep the first K valid, and
check more (doubling batches) only for leaves that still have fewer than K. Leaves whose
whole list is checked without a valid position are blocked; leaves still short after the
round budget are reported as unresolved (and treated as blocked if they have none).

Per position a state byte (unknown / valid / invalid by CAD / invalid by an indication) is
kept, so an operator indication can invalidate positions and the affected leaves refill.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.progress import Progress
from assistant.world.chain_levels import ChainValidator
from assistant.world.leaf_store import JointStore

Array = np.ndarray

UNKNOWN, VALID, INVALID_CAD, INVALID_INDICATED = 0, 1, 2, 3


@dataclass(frozen=True)
class SelectionConfig:
    """How many positions a cell keeps for the search and how hard to look for them."""

    #: K: positions kept per leaf (ours; the thesis only says "at least a few per cell").
    per_cell: int = 12
    #: Positions checked per leaf in the first round; doubles each round.
    first_batch: int = 16
    #: Rounds before a leaf counts as unresolved (16 * (2^6 - 1) = 1008 positions checked;
    #: the sampled store uses `sampled_rounds`: its leaves hold ~100 positions, nearest to
    #: the taught postures first, and a leaf below a table would check all of them).
    #: On the thesis cell every leaf left unresolved has no valid position in its first
    #: thousand, spread evenly over its list; treating it as blocked loses nothing there.
    max_rounds: int = 6
    sampled_rounds: int = 2


@dataclass(frozen=True)
class FillReport:
    leaves: int
    checked: int
    exhausted_blocked: int
    unresolved: int


class CellPositions:
    """Per-position validity state and the selected positions per leaf."""

    def __init__(self, table: JointStore, validator: ChainValidator,
                 config: SelectionConfig | None = None):
        self.table = table
        self.validator = validator
        self.config = config or SelectionConfig()
        n_leaves = len(table.leaves)
        self.state = np.zeros(table.n_positions, dtype=np.int8)
        self.examined = np.zeros(n_leaves, dtype=np.int64)  # prefix length checked per leaf
        self.selected = np.zeros(table.n_positions, dtype=bool)
        self.n_selected = np.zeros(n_leaves, dtype=np.int64)
        self.checked_total = 0
        # `selected_joints` of the current selection (every query asks; it only changes
        # when the selection does): dropped wherever `selected` is written.
        self._csr: tuple[Array, Array, Array] | None = None
        # `has_valid`'s grid of the current selection, dropped with `_csr`.
        self._has_valid: Array | None = None

    # ---------------------------------------------------------------- filling
    def fill(self, slots: Array, progress: Progress | None = None) -> FillReport:
        """Make each leaf slot hold K valid positions if its list has them (see module doc)."""
        t = self.table
        cfg = self.config
        slots = np.unique(np.asarray(slots, dtype=np.int64))
        if progress is not None:
            progress.update(0.0, "valid joint positions")
        counts = np.diff(t.offsets)
        checked = 0
        batch = cfg.first_batch
        rounds = cfg.sampled_rounds if t.kind == "samples" else cfg.max_rounds
        for rnd in range(rounds):
            self._reselect(slots)
            need = slots[(self.n_selected[slots] < cfg.per_cell)
                         & (self.examined[slots] < counts[slots])]
            if not len(need):
                break
            take = np.minimum(batch, counts[need] - self.examined[need])
            start = t.offsets[need] + self.examined[need]
            p = np.repeat(start - np.r_[0, np.cumsum(take)[:-1]], take) + np.arange(take.sum())
            todo = p[self.state[p] == UNKNOWN]
            if len(todo):
                sub = (progress.sub(rnd / rounds, (rnd + 1) / rounds)
                       if progress is not None else None)
                ok = self.validator.validate(t.positions[todo], sub)
                self.state[todo] = np.where(ok, VALID, INVALID_CAD)
                checked += len(todo)
            self.examined[need] += take
            batch *= 2
        self._reselect(slots)
        self.checked_total += checked
        exhausted = (self.examined[slots] >= counts[slots]) & (self.n_selected[slots] == 0)
        unresolved = (self.examined[slots] < counts[slots]) & (self.n_selected[slots] == 0)
        return FillReport(len(slots), checked, int(exhausted.sum()), int(unresolved.sum()))

    def _reselect(self, slots: Array) -> None:
        """Selected = the first K valid positions of the examined prefix of each slot."""
        t = self.table
        if not len(slots):
            return
        lens = self.examined[slots]
        starts = t.offsets[slots]
        p = np.repeat(starts - np.r_[0, np.cumsum(lens)[:-1]], lens) + np.arange(lens.sum())
        owner = np.repeat(np.arange(len(slots)), lens)
        ok = self.state[p] == VALID
        # rank of each valid position within its slot
        csum = np.cumsum(ok)
        before = np.r_[0, csum][np.r_[0, np.cumsum(lens)][:-1]]
        rank = csum - before[owner] - 1
        keep = ok & (rank < self.config.per_cell)
        # The old selection lies inside the examined prefix (it only grows): clear, then set.
        self._csr = self._has_valid = None
        self.selected[p] = False
        self.selected[p[keep]] = True
        self.n_selected[slots] = np.bincount(owner[keep], minlength=len(slots))

    # ---------------------------------------------------------------- updates
    def invalidate(self, position_index: Array) -> Array:
        """Mark positions (indices into table.positions) invalid by an indication; returns the
        affected leaf slots (refill them with `fill`)."""
        pi = np.asarray(position_index, dtype=np.int64)
        if not len(pi):
            return pi
        self.state[pi] = INVALID_INDICATED
        self._csr = self._has_valid = None
        self.selected[pi] = False  # consistent at once, even if the refill is cancelled
        slots = self.slots_of(pi)
        self._reselect(slots)
        return slots

    def reset(self, position_index: Array) -> Array:
        """Positions an indication invalidated become unknown again (the indication was
        forgotten); returns their leaf slots (refill them with `fill`)."""
        pi = np.asarray(position_index, dtype=np.int64)
        pi = pi[self.state[pi] == INVALID_INDICATED]
        if not len(pi):
            return np.zeros(0, dtype=np.int64)
        self.state[pi] = UNKNOWN
        self._csr = self._has_valid = None
        return self.slots_of(pi)

    def slots_of(self, position_index: Array) -> Array:
        """The leaf slots (unique) holding some positions (indices into table.positions)."""
        pi = np.asarray(position_index, dtype=np.int64)
        return np.unique(np.searchsorted(self.table.offsets, pi, side="right") - 1)

    # ---------------------------------------------------------------- views
    def has_valid(self) -> Array:
        """Dense bool grid: the leaf offers at least one valid joint position (a copy of
        the grid remembered until the selection changes: a planning query asks four times,
        and building it cost more than copying)."""
        if self._has_valid is None:
            m = np.zeros(self.table.grid.n_cells, dtype=bool)
            m[self.table.leaves[self.n_selected > 0]] = True
            self._has_valid = m.reshape(self.table.grid.shape)
        return self._has_valid.copy()

    def selected_csr(self) -> tuple[Array, Array, Array]:
        """(cells, offsets, joint-grid ids): the selected positions of every leaf that has some,
        grouped by flat cell id (ascending), in diversity order within a cell."""
        p = np.flatnonzero(self.selected)
        slot = np.searchsorted(self.table.offsets, p, side="right") - 1
        cells, first = np.unique(slot, return_index=True)
        offsets = np.r_[first, len(p)].astype(np.int64)
        return self.table.leaves[cells], offsets, self.table.positions[p]

    def selected_joints(self) -> tuple[Array, Array, Array]:
        """`selected_csr` with joint values (rad) instead of ids: (cells, offsets, Q).

        Remembered until the selection changes: decoding the ids costs ~2 ms of every
        planning query, a copy of the result ~0.1 ms (copies, so a caller may write to them;
        read-only arrays would also be new argument types for the compiled kernels)."""
        cells, offsets, Q = self.decode()
        return cells.copy(), offsets.copy(), Q.copy()

    def decode(self) -> tuple[Array, Array, Array]:
        """The remembered (cells, offsets, Q) of `selected_joints`, decoded now if the
        selection changed (not copies: do not write to them). The roadmap calls it when it
        builds or updates, so the first query after does not pay the decoding."""
        if self._csr is None:
            cells, offsets, ids = self.selected_csr()
            self._csr = (cells, offsets, self.table.joints(ids))
        return self._csr
