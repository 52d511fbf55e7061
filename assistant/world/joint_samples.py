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
* the per-joint `step` is the grid's resolution d_step / r_i (one step moves the TCP at most
  d_step): edge checks and the posture box of an indication use it as with the grid.

Ids are row numbers of `samples` (float32: 2^-24 relative, < 1 um at the TCP). There are no
shared joint prefixes, so the chain validator checks each position level by level on its own.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.world.leaf_store import JointStore, WorldBudgetError, save_npz
from assistant.world.octree import OctreeGrid

Array = np.ndarray

FORMAT_VERSION = 1
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

    samples: Array | None = None  # (S, dof) float32 joint values; ids are its rows

    kind = "samples"

    @property
    def id_space(self) -> int:
        assert self.samples is not None
        return len(self.samples)

    def joints(self, ids: Array) -> Array:
        assert self.samples is not None
        return self.samples[np.asarray(ids, dtype=np.int64)].astype(float)

    def ids_in_box(self, q: Array, half_steps: float) -> Array:
        """Ids within `half_steps` steps of q in every varying joint (a scan: ~10 ms for 2 M)."""
        assert self.samples is not None
        varying = self.counts > 1
        half = (half_steps * self.step[varying] + 1e-9).astype(np.float32)
        qv = np.asarray(q, dtype=np.float32)[varying]
        inside = np.ones(len(self.samples), dtype=bool)
        for k, j in enumerate(np.flatnonzero(varying)):
            inside &= np.abs(self.samples[:, j] - qv[k]) <= half[k]
        return np.flatnonzero(inside)

    def prefix_space(self, n_joints: int) -> int:
        return self.id_space

    def prefixes(self, ids: Array, n_joints: int) -> Array:
        return np.asarray(ids, dtype=np.int64)

    def prefix_configs(self, n_joints: int, prefixes: Array, rest: Array) -> Array:
        return self.joints(prefixes)

    def focused(self, robot: Robot, anchors: Array, n: int, margin: float) -> SampledTable:
        """A copy with `n` more Sobol samples in the box the anchor postures span, widened by
        `margin` (rad) and clipped to the limits: the working range of the taught postures
        gets ~10x the density of the whole range (and the rest of the range stays)."""
        assert self.samples is not None
        A = np.atleast_2d(np.asarray(anchors, dtype=float))
        lo = np.maximum(A.min(axis=0) - margin, robot.limits.lower)
        hi = np.minimum(A.max(axis=0) + margin, robot.limits.upper)
        varying = self.counts > 1
        m = max(1, int(np.ceil(np.log2(max(n, 2)))))
        U = qmc.Sobol(d=self.dof, scramble=True, seed=1).random_base2(m)[:n]
        X = (lo + U * (hi - lo)).astype(np.float32)
        X[:, ~varying] = self.lower[~varying]
        leaf = _bin(robot, self.grid, X, None)
        keep = np.flatnonzero(leaf >= 0)
        ids = np.r_[self.positions.astype(np.int64), len(self.samples) + keep]
        lf = np.r_[self.leaf_of_positions(), leaf[keep]]
        order = np.argsort(lf, kind="stable")
        ids, lf = ids[order].astype(np.int32), lf[order]
        starts = np.flatnonzero(np.r_[True, lf[1:] != lf[:-1]])
        return SampledTable(self.key, self.grid, self.radii, self.lower, self.step,
                            self.counts, lf[starts].astype(np.int64),
                            np.r_[starts, len(ids)].astype(np.int64), ids,
                            self.build_seconds, samples=np.concatenate([self.samples, X]))

    def toward(self, anchors: Array, weights: Array) -> SampledTable:
        """A copy whose leaves list their positions nearest-first to the nearest anchor
        posture (arm-radius weighted joint distance).

        Why: the search connects positions of neighbouring leaves, and uniform samples of a
        6-axis arm's +-360 deg limits hold ~100 IK branches and turns per TCP position: K
        diverse positions per leaf rarely include two neighbours close in joint space. The
        positions nearest to the taught postures form coherent fields (the same branch and
        turn in neighbouring leaves), so the first K valid ones connect."""
        assert self.samples is not None
        A = np.atleast_2d(np.asarray(anchors, dtype=np.float32))
        w = np.asarray(weights, dtype=np.float32)
        P = self.samples[self.positions]
        d = np.full(len(P), np.inf, dtype=np.float32)
        for a in A:
            d = np.minimum(d, np.einsum("ij,ij->i", (P - a) * w, (P - a) * w))
        slot = np.repeat(np.arange(len(self.leaves)), np.diff(self.offsets))
        order = np.lexsort((d, slot))
        return SampledTable(self.key, self.grid, self.radii, self.lower, self.step,
                            self.counts, self.leaves, self.offsets, self.positions[order],
                            self.build_seconds, samples=self.samples)

    def nbytes(self) -> int:
        assert self.samples is not None
        return super().nbytes() + int(self.samples.nbytes)

    def save(self, path) -> None:
        save_npz(path, key=np.array(self.key), grid=np.array(json.dumps(self.grid.to_json())),
                 radii=self.radii, lower=self.lower, step=self.step, counts=self.counts,
                 leaves=self.leaves, offsets=self.offsets, positions=self.positions,
                 samples=self.samples, build_seconds=np.array(self.build_seconds))

    @staticmethod
    def load(path) -> SampledTable:
        with np.load(path) as z:
            g = json.loads(str(z["grid"]))
            return SampledTable(
                key=str(z["key"]), grid=OctreeGrid(g["size"], g["depth"], tuple(g["centre"])),
                radii=z["radii"], lower=z["lower"], step=z["step"], counts=z["counts"],
                leaves=z["leaves"], offsets=z["offsets"], positions=z["positions"],
                samples=z["samples"], build_seconds=float(z["build_seconds"]))


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


def _bin(robot: Robot, grid: OctreeGrid, Q: Array, progress: Progress | None,
         chunk: int = 1 << 17) -> Array:
    out = np.empty(len(Q), dtype=np.int64)
    for s in range(0, len(Q), chunk):
        out[s:s + chunk] = grid.flat_of_points(
            robot.batch_fk(Q[s:s + chunk].astype(float)).positions)
        if progress is not None:
            progress.update(min(len(Q), s + chunk) / len(Q), "binning TCP positions")
    return out


def build_samples(robot: Robot, grid: OctreeGrid, config, radii: Array,
                  progress: Progress | None = None) -> SampledTable:
    """Sample, top up, group per leaf. Raises `Cancelled` through `progress`,
    `WorldBudgetError` before allocating beyond the memory budget."""
    progress = progress or Progress("joint samples")
    t0 = time.perf_counter()
    dof = robot.dof
    n = int(config.samples)
    check_sample_budget(n, dof, config.memory_mb)
    lo = robot.limits.lower.astype(float)
    hi = robot.limits.upper.astype(float)
    varying = radii >= config.skip_below
    step = np.where(varying, config.d_step / np.maximum(radii, 1e-12), 0.0)
    lower = np.where(varying, lo, np.clip(0.0, lo, hi))
    counts = np.where(varying, 2, 1).astype(np.int64)
    m = max(1, int(np.ceil(np.log2(max(n, 2)))))
    U = qmc.Sobol(d=dof, scramble=True, seed=0).random_base2(m)[:n]
    Q = (lo + U * (hi - lo)).astype(np.float32)
    del U
    Q[:, ~varying] = lower[~varying]
    leaf = _bin(robot, grid, Q, progress.sub(0.0, 0.7))
    Q, leaf = _top_up(robot, grid, Q, leaf, step, lo, hi, n // 4, progress.sub(0.7, 0.95))
    progress.update(0.95, "grouping joint positions per leaf")
    ids = np.flatnonzero(leaf >= 0)
    order = np.argsort(leaf[ids], kind="stable")  # sequence order within a leaf
    ids = ids[order].astype(np.int32)
    leaf_sorted = leaf[ids]
    starts = np.flatnonzero(np.r_[True, leaf_sorted[1:] != leaf_sorted[:-1]])
    leaves = leaf_sorted[starts].astype(np.int64)
    offsets = np.r_[starts, len(ids)].astype(np.int64)
    progress.update(1.0, f"{len(ids)} joint positions in {len(leaves)} leaves", force=True)
    return SampledTable(
        key=samples_key(robot, grid, config), grid=grid, radii=np.asarray(radii, dtype=float),
        lower=lower, step=step, counts=counts, leaves=leaves, offsets=offsets, positions=ids,
        samples=Q, build_seconds=time.perf_counter() - t0)


def _top_up(robot: Robot, grid: OctreeGrid, Q: Array, leaf: Array, step: Array, lo: Array,
            hi: Array, budget: int, progress: Progress, rounds: int = 3,
            ) -> tuple[Array, Array]:
    """Perturbed children of thin leaves' positions, kept where they land in a thin or empty
    leaf (see the module docstring); at most `budget` new positions."""
    rng = np.random.default_rng(7)
    added = 0
    for r in range(rounds):
        progress.update(r / rounds, "topping up thin leaves")
        inside = leaf >= 0
        count = np.bincount(leaf[inside], minlength=grid.n_cells)
        thin_parent = inside & (count[np.maximum(leaf, 0)] < THIN)
        parents = np.flatnonzero(thin_parent)
        if not len(parents) or added >= budget:
            break
        per = max(1, min(8, (budget - added) // len(parents)))
        P = np.repeat(Q[parents].astype(float), per, axis=0)
        P += rng.normal(size=P.shape) * (2.0 * step)
        P = np.clip(P, lo, hi)
        lf = _bin(robot, grid, P, None)
        ok = lf >= 0
        ok[ok] = count[lf[ok]] < THIN
        keep = np.flatnonzero(ok)[: budget - added]
        if not len(keep):
            break
        Q = np.concatenate([Q, P[keep].astype(np.float32)])
        leaf = np.concatenate([leaf, lf[keep]])
        added += len(keep)
    progress.update(1.0, "topping up thin leaves")
    return Q, leaf
