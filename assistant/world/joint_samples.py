"""The joint-position store for any arm: a fixed budget of joint samples binned per octree leaf.

The thesis' full joint grid (`reachability`) has prod_i(range_i r_i / d_step) points: ~10 M
for the 5-axis RV-2AJ, 10^15 for a UR5 at its own +-360 deg limits. This store keeps the
grid's contract (joint positions grouped by the leaf of their TCP, each leaf's list spread in
every prefix; `leaf_store`) with memory linear in a budget:

* a scrambled Sobol sequence of `samples` points over the joint limits (low-discrepancy: its
  prefixes cover the box evenly, so a leaf's positions in sequence order are spread);
* a top-up of thin leaves: positions of leaves holding fewer than `THIN` are perturbed by a
  few joint steps and the children that land in thin or still-empty leaves are kept (the
  reach boundary and tight corners get positions the uniform sequence gives rarely);
* every sample is snapped to the thesis' joint grid (step d_step / r_i: one step moves the
  TCP at most d_step) and stored as its per-joint grid indices (int32). Joint values decode
  exactly as the grid's, and samples that share their first joints share a prefix: the chain
  validator checks the shoulder once per J1 value, the upper arm once per (J1, J2) pair
  (~300x fewer narrow-phase calls on a UR5 than checking every sample at every level).

Ids are row numbers of `index`.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field

import numpy as np

from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.world.leaf_store import JointStore, WorldBudgetError
from assistant.world.octree import OctreeGrid

Array = np.ndarray

FORMAT_VERSION = 2
#: Leaves with fewer positions than this are topped up.
THIN = 48
#: Bytes per sampled position while the store is built and used: joint values (4 per joint),
#: id, inverse map, leaf, sort keys, validity state and per-level caches.
BYTES_PER_SAMPLE = 48
#: Bytes per joint-grid point at the peak of a grid build (leaf per point, ids, sort order,
#: diversity keys, the inverse map).
BYTES_PER_GRID_POINT = 40


@dataclass
class SampledTable(JointStore):
    """Joint positions per reachable leaf from a fixed sample budget (module docstring)."""

    index: Array | None = None  # (S, dof) int32 per-joint grid indices; ids are its rows
    #: (joint, ids sorted by its grid index, those indices): `prepare_box_queries`.
    _by_joint: tuple[int, Array, Array] | None = field(default=None, repr=False)

    kind = "samples"
    extra_arrays = ("index",)

    @property
    def id_space(self) -> int:
        assert self.index is not None
        return len(self.index)

    def joints(self, ids: Array) -> Array:
        assert self.index is not None
        return self.lower + self.index[np.asarray(ids, dtype=np.int64)] * self.step

    def prepare_box_queries(self) -> None:
        """Sort the ids by the joint with the most grid values once (`ids_in_box`)."""
        assert self.index is not None
        if self._by_joint is None:
            varying = np.flatnonzero(self.counts > 1)
            j = int(varying[np.argmax(self.counts[varying])]) if len(varying) else 0
            order = np.argsort(self.index[:, j], kind="stable")
            self._by_joint = (j, order, self.index[order, j])

    def ids_in_box(self, q: Array, half_steps: float) -> Array:
        """Ids within `half_steps` steps of q in every varying joint, ascending: the ids in
        that range of the most selective joint (a binary search in its sorted order), then
        the other joints (a scan of every id cost 0.15-0.3 s a collision indication on a
        UR with 2-4 M samples, the bulk of a re-plan)."""
        assert self.index is not None
        self.prepare_box_queries()
        assert self._by_joint is not None
        j0, order, col = self._by_joint
        tol = half_steps + 1e-9
        x0 = (float(q[j0]) - self.lower[j0]) / self.step[j0] if self.counts[j0] > 1 else 0.0
        lo = int(np.searchsorted(col, np.floor(x0 - tol), side="left"))
        hi = int(np.searchsorted(col, np.ceil(x0 + tol), side="right"))
        cand = np.sort(order[lo:hi])
        inside = np.ones(len(cand), dtype=bool)
        for j in np.flatnonzero(self.counts > 1):
            x = (float(q[j]) - self.lower[j]) / self.step[j]
            inside &= np.abs(self.index[cand, j] - x) <= tol
        return cand[inside]

    def prefix_space(self, n_joints: int) -> int:
        space = int(np.prod(self.counts[:n_joints].astype(float)))
        return space if space < 2**62 else self.id_space

    def prefixes(self, ids: Array, n_joints: int) -> Array:
        """The grid id over the first joints (C order); the id itself where that space
        would not fit an int64 (no sharing there)."""
        assert self.index is not None
        ids = np.asarray(ids, dtype=np.int64)
        if int(np.prod(self.counts[:n_joints].astype(float))) >= 2**62:
            return ids
        key = np.zeros(len(ids), dtype=np.int64)
        for j in range(n_joints):
            key = key * int(self.counts[j]) + self.index[ids, j]
        return key

    def prefix_configs(self, n_joints: int, prefixes: Array, rest: Array) -> Array:
        if int(np.prod(self.counts[:n_joints].astype(float))) >= 2**62:
            return self.joints(prefixes)
        Q = np.tile(rest, (len(prefixes), 1))
        key = np.asarray(prefixes, dtype=np.int64).copy()
        for j in range(n_joints - 1, -1, -1):
            Q[:, j] = self.lower[j] + (key % int(self.counts[j])) * self.step[j]
            key //= int(self.counts[j])
        return Q

    def focused(self, robot: Robot, anchors: Array, n: int, margin: float) -> SampledTable:
        """A copy with `n` more Sobol samples in the box the anchor postures span, widened by
        `margin` (rad) and clipped to the limits: the working range of the taught postures
        gets ~10x the density of the whole range (and the rest of the range stays)."""
        assert self.index is not None
        A = np.atleast_2d(np.asarray(anchors, dtype=float))
        lo = np.maximum(A.min(axis=0) - margin, robot.limits.lower)
        hi = np.minimum(A.max(axis=0) + margin, robot.limits.upper)
        m = max(1, int(np.ceil(np.log2(max(n, 2)))))
        U = _sobol(self.dof, m, seed=1)[:n]
        X = self.snap(lo + U * (hi - lo))
        # float32 FK (~4x quicker on a URDF arm): a TCP within ~1 um of a leaf face may be
        # binned into the neighbour, which the positions' checks do not care about
        leaf = _bin(robot, self.grid, self, X, None, dtype=np.float32)
        keep = np.flatnonzero(leaf >= 0)
        ids = np.r_[self.positions.astype(np.int64), len(self.index) + keep]
        lf = np.r_[self.leaf_of_positions(), leaf[keep]]
        order = np.argsort(lf, kind="stable")
        ids, lf = ids[order].astype(np.int32), lf[order]
        starts = np.flatnonzero(np.r_[True, lf[1:] != lf[:-1]])
        return SampledTable(self.key, self.grid, self.radii, self.lower, self.step,
                            self.counts, lf[starts].astype(np.int64),
                            np.r_[starts, len(ids)].astype(np.int64), ids,
                            self.build_seconds, index=np.concatenate([self.index, X]))

    def snap(self, Q: Array) -> Array:
        """(n, dof) int32 grid indices of the nearest grid points (within the limits)."""
        varying = self.counts > 1
        x = np.zeros(np.shape(Q), dtype=np.float64)
        x[:, varying] = (np.asarray(Q)[:, varying] - self.lower[varying]) / self.step[varying]
        return np.clip(np.rint(x), 0, self.counts - 1).astype(np.int32)

    def toward(self, anchors: Array, weights: Array) -> SampledTable:
        """A copy whose leaves list their positions nearest-first to the nearest anchor
        posture (arm-radius weighted joint distance).

        Why: the search connects positions of neighbouring leaves, and uniform samples of a
        6-axis arm's +-360 deg limits hold ~100 IK branches and turns per TCP position: K
        diverse positions per leaf rarely include two neighbours close in joint space. The
        positions nearest to the taught postures form coherent fields (the same branch and
        turn in neighbouring leaves), so the first K valid ones connect."""
        assert self.index is not None
        A = np.atleast_2d(np.asarray(anchors, dtype=float))
        w = np.asarray(weights, dtype=float)
        d = np.full(self.n_positions, np.inf)
        # in the grid's own units (the index), each anchor moved into them once: the
        # distances without decoding every position's joints (~0.6 s for 3 M)
        ws = (w * self.step).astype(np.float32)
        Ai = ((A - self.lower) / np.where(self.step > 0, self.step, 1.0)).astype(np.float32)
        for s in range(0, self.n_positions, 1 << 18):
            X = self.index[self.positions[s:s + (1 << 18)]].astype(np.float32)
            for a in Ai:
                D = (X - a) * ws
                d[s:s + len(X)] = np.minimum(d[s:s + len(X)], np.einsum("ij,ij->i", D, D))
        # one sort: slot in the integer part, the distance squashed into [0, 0.5) below it
        # (the default sort is not stable but deterministic: the same table, the same order)
        slot = np.repeat(np.arange(len(self.leaves), dtype=np.float64), np.diff(self.offsets))
        order = np.argsort(slot + d / (2.0 * (1.0 + d)))
        return SampledTable(self.key, self.grid, self.radii, self.lower, self.step,
                            self.counts, self.leaves, self.offsets, self.positions[order],
                            self.build_seconds, index=self.index)

    def nbytes(self) -> int:
        assert self.index is not None
        return super().nbytes() + int(self.index.nbytes)


def samples_key(robot: Robot, grid: OctreeGrid, config) -> str:
    payload = json.dumps({"format": FORMAT_VERSION, "store": "samples",
                          "robot": robot.description_hash(), "grid": grid.to_json(),
                          "reach": config.to_json(), "samples": int(config.samples)},
                         sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def check_sample_budget(n: int, dof: int, memory_mb: float) -> None:
    """Refuse (clearly, before allocating) a sample budget beyond the memory budget."""
    need = n * (BYTES_PER_SAMPLE + 4 * dof) * 1.25  # + the top-up
    if need > memory_mb * 2**20:
        raise WorldBudgetError(
            f"{n:,} joint samples need about {need / 2**20:,.0f} MB, more than the world "
            f"model's memory budget of {memory_mb:,.0f} MB: lower the joint samples or raise "
            "the memory budget (world settings 'joint_samples' / 'memory_mb')")


def check_grid_budget(total: int, memory_mb: float) -> None:
    need = total * BYTES_PER_GRID_POINT
    if total >= 2**31 or need > memory_mb * 2**20:
        raise WorldBudgetError(
            f"the full joint grid has {total:,} points (about {need / 2**20:,.0f} MB), more "
            f"than the world model's memory budget of {memory_mb:,.0f} MB: use the sampled "
            "store (world setting 'store: samples' or 'auto'), a coarser resolution, or raise "
            "'memory_mb'")


def _bin(robot: Robot, grid: OctreeGrid, store: SampledTable, index: Array,
         progress: Progress | None, chunk: int = 1 << 17, dtype: type = np.float64) -> Array:
    """Flat leaf of the TCP of each row of grid indices (-1 outside the octree)."""
    out = np.empty(len(index), dtype=np.int64)
    for s in range(0, len(index), chunk):
        Q = store.lower + index[s:s + chunk] * store.step
        P = robot.batch_fk(Q, dtype=dtype).positions if dtype is not np.float64 \
            else robot.batch_fk(Q).positions
        out[s:s + chunk] = grid.flat_of_points(np.asarray(P, dtype=np.float64))
        if progress is not None:
            progress.update(min(len(index), s + chunk) / len(index), "binning TCP positions")
    return out


def build_samples(robot: Robot, grid: OctreeGrid, config, radii: Array,
                  progress: Progress | None = None) -> SampledTable:
    """Sample, snap, top up, group per leaf. Raises `Cancelled` through `progress`,
    `WorldBudgetError` before allocating beyond the memory budget."""
    progress = progress or Progress("joint samples")
    t0 = time.perf_counter()
    dof = robot.dof
    n = int(config.samples)
    check_sample_budget(n, dof, config.memory_mb)
    lo = robot.limits.lower.astype(float)
    hi = robot.limits.upper.astype(float)
    radii = np.asarray(radii, dtype=float)
    varying = radii >= config.skip_below
    counts = np.ones(dof, dtype=np.int64)
    step = np.zeros(dof)
    lower = np.where(varying, lo, np.clip(0.0, lo, hi))
    for i in np.flatnonzero(varying):  # the thesis grid: both range ends are grid values
        counts[i] = max(2, int(np.ceil((hi[i] - lo[i]) / (config.d_step / radii[i]) - 1e-9)) + 1)
        step[i] = (hi[i] - lo[i]) / (counts[i] - 1)
    store = SampledTable(samples_key(robot, grid, config), grid, radii, lower, step, counts,
                         np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.int32),
                         index=np.zeros((0, dof), np.int32))
    m = max(1, int(np.ceil(np.log2(max(n, 2)))))
    index = store.snap(lo + _sobol(dof, m, seed=0)[:n] * (hi - lo))
    leaf = _bin(robot, grid, store, index, progress.sub(0.0, 0.7))
    index, leaf = _top_up(robot, grid, store, index, leaf, n // 4, progress.sub(0.7, 0.95))
    progress.update(0.95, "grouping joint positions per leaf")
    ids = np.flatnonzero(leaf >= 0)
    order = np.argsort(leaf[ids], kind="stable")  # sequence order within a leaf
    ids = ids[order].astype(np.int32)
    leaf_sorted = leaf[ids]
    starts = np.flatnonzero(np.r_[True, leaf_sorted[1:] != leaf_sorted[:-1]])
    progress.update(1.0, f"{len(ids)} joint positions in {len(starts)} leaves", force=True)
    store.leaves = leaf_sorted[starts].astype(np.int64)
    store.offsets = np.r_[starts, len(ids)].astype(np.int64)
    store.positions, store.index = ids, index
    store.build_seconds = time.perf_counter() - t0
    return store


def _top_up(robot: Robot, grid: OctreeGrid, store: SampledTable, index: Array, leaf: Array,
            budget: int, progress: Progress, rounds: int = 3) -> tuple[Array, Array]:
    """Perturbed children of thin leaves' positions (a few grid steps), kept where they land
    in a thin or empty leaf (see the module docstring); at most `budget` new positions."""
    rng = np.random.default_rng(7)
    added = 0
    varying = store.counts > 1
    for r in range(rounds):
        progress.update(r / rounds, "topping up thin leaves")
        inside = leaf >= 0
        count = np.bincount(leaf[inside], minlength=grid.n_cells)
        parents = np.flatnonzero(inside & (count[np.maximum(leaf, 0)] < THIN))
        if not len(parents) or added >= budget:
            break
        per = max(1, min(8, (budget - added) // len(parents)))
        P = np.repeat(index[parents], per, axis=0).astype(np.int64)
        P[:, varying] += np.rint(rng.normal(size=(len(P), int(varying.sum()))) * 2.0
                                 ).astype(np.int64)
        P = np.clip(P, 0, store.counts - 1).astype(np.int32)
        lf = _bin(robot, grid, store, P, None)
        ok = lf >= 0
        ok[ok] = count[lf[ok]] < THIN
        keep = np.flatnonzero(ok)[: budget - added]
        if not len(keep):
            break
        index = np.concatenate([index, P[keep]])
        leaf = np.concatenate([leaf, lf[keep]])
        added += len(keep)
    progress.update(1.0, "topping up thin leaves")
    return index, leaf


def _sobol(dof: int, m: int, seed: int) -> Array:
    """2^m scrambled Sobol points in [0, 1)^dof. scipy.stats is imported here, not with the
    module: its import (0.4-1.4 s) stays off the session's start."""
    from scipy.stats import qmc

    return qmc.Sobol(d=dof, scramble=True, seed=seed).random_base2(m)
