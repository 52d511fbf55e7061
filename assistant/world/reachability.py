"""Reachability look-up table: which joint positions put the TCP into which octree leaf (§8.5.2-3).

Joint space is discretised with a per-joint step delta_i = d_step / r_i, r_i the largest
distance of the TCP from joint i's axis over the joint ranges (so one step moves the TCP at
most d_step; thesis eq. 46). Forward kinematics runs once over the grid, vectorised, and each
joint position is binned into the leaf holding its TCP; a leaf is reachable if it holds one.

Measured radii instead of the thesis' sums: Table 8 sums link lengths (0.712 m for J1 includes
a 0.13 m "link 1" that is vertical and cannot move the TCP away from the J1 axis). We take
r_i = max |dp_TCP/dq_i| (the TCP's distance from the axis) over the joint space, found by
sampling + hill climbing, which gives the steps the definition asks for. A joint whose r_i is
~0 (the TCP on the J6 axis of a 5-axis arm) does not move the TCP: it is fixed at 0 (or the
range limit nearest 0) and skipped, so the grid does not multiply by its values.

Structure exploited: if joint 1 turns the whole arm about the base z axis (true for the RV-2AJ
and most industrial arms; checked numerically), TCP(q1, rest) = Rz(q1) TCP(0, rest). FK then
runs once over the (J2..Jn) grid (for the RV-2AJ the planar (r, z) of the J2 x J3 x J5 grid)
and each J1 value is a 2-D rotation of those points. Otherwise the full grid goes through the
robot's batch FK in chunks.

Storage is CSR-like: `positions` (flat joint-grid ids, int32) grouped by leaf, `leaves` (the
reachable leaves' flat grid ids, ascending) and `offsets`. Within a leaf the positions are in
*diversity order*: sorted along the joint grid (J1 slowest ... Jn fastest) and then permuted by
bit-reversal of the rank (van der Corput), so every prefix of a leaf's list is spread evenly
over the whole list. Consumers that cap the positions per cell (the A* search: too many make
it slow, too few make it fail) take the first valid ones and get a spread for free.

The table depends only on the robot and the parameters: it is cached as .npz under
`$CELLTEACH_CACHE` (default ``~/.cache/cellteach``), keyed by a hash of both, written
atomically (a cancelled or failed build leaves no file behind).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.world.joint_samples import (
    BYTES_PER_GRID_POINT,
    SampledTable,
    build_samples,
    check_grid_budget,
    samples_key,
)
from assistant.world.leaf_store import JointStore
from assistant.world.octree import OctreeGrid

Array = np.ndarray

#: 2: TCP positions from the RV-2AJ's compiled closed form (`rv2aj_fk_batch`); its sin/cos may
#: differ from numpy's in the last bit, which can bin a position on a leaf boundary into the
#: neighbouring leaf, so tables cached by 1 are not reused.
FORMAT_VERSION = 2
#: Thesis d_step: half a 62.5 mm leaf (Table 8 / §8.5.2).
THESIS_D_STEP = 0.03125


def cache_dir(override: str | os.PathLike | None = None) -> Path:
    """Where cached tables live: the argument, else $CELLTEACH_CACHE, else ~/.cache/cellteach."""
    if override is not None:
        return Path(override)
    env = os.environ.get("CELLTEACH_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "cellteach"


@dataclass(frozen=True)
class ReachabilityConfig:
    """Discretisation parameters of the table."""

    #: Largest TCP displacement (m) for one step of any joint. Thesis: 31.25 mm.
    d_step: float = THESIS_D_STEP
    #: r_i per joint (m); None measures them from the robot (see `joint_reach_radii`).
    radii: tuple[float, ...] | None = None
    #: Joints with r_i below this (m/rad) do not move the TCP and are fixed.
    skip_below: float = 1e-4
    #: Configurations per FK chunk on the generic path.
    chunk: int = 1 << 18
    #: "grid" (the thesis' full joint grid), "samples" (a fixed budget of joint samples,
    #: `joint_samples`) or "auto": the grid while it fits `grid_points` and the memory budget.
    store: str = "auto"
    #: Most joint-grid points "auto" accepts (the RV-2AJ's thesis grid has ~10 M).
    grid_points: int = 40_000_000
    #: Joint samples of the sampled store (before the top-up of thin leaves).
    samples: int = 1 << 21
    #: Samples added (per world build, not cached) in the box the taught postures span,
    #: widened by `focus_margin` rad (`SampledTable.focused`).
    focus_samples: int = 1 << 20
    focus_margin: float = 0.8
    #: Memory the store may take while it is built (MB); a request beyond it is refused
    #: with a message naming this setting.
    memory_mb: int = 1536

    def to_json(self) -> dict:
        return {"d_step": self.d_step, "radii": None if self.radii is None else list(self.radii),
                "skip_below": self.skip_below}


@dataclass
class ReachabilityTable(JointStore):
    """Joint positions per reachable leaf on the full joint grid (see the module docstring for
    the layout). `lower`, `step`, `counts` define the grid."""

    kind = "grid"

    # ---------------------------------------------------------------- joint grid
    @property
    def grid_size(self) -> int:
        """Number of points of the joint grid (reachable or not)."""
        return int(np.prod(self.counts.astype(np.int64)))

    @property
    def id_space(self) -> int:
        return self.grid_size

    def joint_index(self, ids: Array) -> Array:
        """(n, dof) per-joint grid indices of flat joint-grid ids (C order, J1 slowest)."""
        return np.stack(np.unravel_index(np.asarray(ids, dtype=np.int64),
                                         tuple(int(c) for c in self.counts)), axis=1)

    def joints(self, ids: Array) -> Array:
        """(n, dof) joint values (rad) of flat joint-grid ids."""
        return self.lower + self.joint_index(ids) * self.step

    def flat_id(self, joint_index: Array) -> Array:
        ji = np.asarray(joint_index, dtype=np.int64).reshape(-1, self.dof)
        return np.ravel_multi_index(tuple(ji.T), tuple(int(c) for c in self.counts))

    def ids_in_box(self, q: Array, half_steps: float) -> Array:
        """Flat ids of the grid points within `half_steps` steps of q in every varying joint
        (fixed joints are ignored)."""
        ranges = []
        for i in range(self.dof):
            if self.counts[i] == 1:
                ranges.append(np.array([0]))
                continue
            x = (float(q[i]) - self.lower[i]) / self.step[i]
            lo = max(0, int(np.ceil(x - half_steps - 1e-9)))
            hi = min(int(self.counts[i]) - 1, int(np.floor(x + half_steps + 1e-9)))
            if hi < lo:
                return np.zeros(0, dtype=np.int64)
            ranges.append(np.arange(lo, hi + 1))
        mesh = np.stack(np.meshgrid(*ranges, indexing="ij"), axis=-1).reshape(-1, self.dof)
        return self.flat_id(mesh)

    # ---------------------------------------------------------------- chain prefixes
    def prefix_space(self, n_joints: int) -> int:
        return int(np.prod(self.counts[:n_joints].astype(np.int64)))

    def prefixes(self, ids: Array, n_joints: int) -> Array:
        """Flat ids of the grid over the first `n_joints` joints (C order: a division)."""
        return np.asarray(ids, dtype=np.int64) // int(np.prod(self.counts[n_joints:]))

    def prefix_configs(self, n_joints: int, prefixes: Array, rest: Array) -> Array:
        counts = tuple(int(c) for c in self.counts[:n_joints])
        idx = (np.stack(np.unravel_index(prefixes, counts), axis=1) if n_joints
               else np.zeros((1, 0)))
        Q = np.tile(rest, (len(prefixes), 1))
        Q[:, :n_joints] = self.lower[:n_joints] + idx * self.step[:n_joints]
        return Q


# -------------------------------------------------------------------- radii
def joint_reach_radii(robot: Robot, *, samples: int = 20_000, seed: int = 0) -> Array:
    """r_i = max over the joint ranges of the TCP's distance from joint i's axis (m).

    For a revolute joint that distance is |dp_TCP/dq_i|, taken by central differences on
    random configurations, then refined by a few rounds of vectorised hill climbing from the
    best samples (random sampling alone lands ~1 % low for the stretched-arm maxima).
    """
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits.lower, robot.limits.upper
    dof = robot.dof

    def speeds(Q: Array) -> Array:
        h = 1e-5
        out = np.empty((len(Q), dof))
        for i in range(dof):
            Qp, Qm = Q.copy(), Q.copy()
            Qp[:, i] += h
            Qm[:, i] -= h
            d = robot.batch_fk(Qp).positions - robot.batch_fk(Qm).positions
            out[:, i] = np.linalg.norm(d, axis=1) / (2 * h)
        return out

    Q = rng.uniform(lo, hi, size=(samples, dof))
    S = speeds(Q)
    radii = S.max(axis=0)
    span = hi - lo
    for i in range(dof):
        top = np.argsort(S[:, i])[-32:]
        C, best = Q[top].copy(), S[top, i].copy()
        sigma = 0.1 * span
        for rnd in range(40):
            P = np.clip(C + rng.normal(size=C.shape) * sigma, lo, hi)
            v = speeds(P)[:, i]
            better = v > best
            C[better], best[better] = P[better], v[better]
            if rnd % 10 == 9:
                sigma = sigma / 3.0
        radii[i] = max(radii[i], float(best.max()))
    return radii


def _turns_about_base_z(robot: Robot, rng: np.random.Generator) -> bool:
    """Does joint 1 rotate every TCP position about the base z axis by exactly q1?"""
    lo, hi = robot.limits.lower, robot.limits.upper
    Q = rng.uniform(lo, hi, size=(64, robot.dof))
    Q0 = Q.copy()
    Q0[:, 0] = 0.0
    p = robot.batch_fk(Q).positions
    p0 = robot.batch_fk(Q0).positions
    c, s = np.cos(Q[:, 0]), np.sin(Q[:, 0])
    rot = np.stack([c * p0[:, 0] - s * p0[:, 1], s * p0[:, 0] + c * p0[:, 1], p0[:, 2]], axis=1)
    return bool(np.allclose(p, rot, atol=1e-9))


# -------------------------------------------------------------------- build
def table_key(robot: Robot, grid: OctreeGrid, config: ReachabilityConfig) -> str:
    payload = json.dumps({"format": FORMAT_VERSION, "robot": robot.description_hash(),
                          "grid": grid.to_json(), "reach": config.to_json()}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def joint_grid(robot: Robot, radii: Array, config: ReachabilityConfig,
               ) -> tuple[Array, Array, Array]:
    """(lower, step, counts) per joint. Both range ends are grid values, so the real step is
    range / (counts - 1) <= d_step / r_i."""
    lo, hi = robot.limits.lower.astype(float), robot.limits.upper.astype(float)
    lower, step = lo.copy(), np.zeros(robot.dof)
    counts = np.ones(robot.dof, dtype=np.int64)
    for i in range(robot.dof):
        if radii[i] < config.skip_below:
            lower[i] = float(np.clip(0.0, lo[i], hi[i]))
            continue
        delta = config.d_step / radii[i]
        n = int(np.ceil((hi[i] - lo[i]) / delta - 1e-9)) + 1
        counts[i] = max(n, 2)
        step[i] = (hi[i] - lo[i]) / (counts[i] - 1)
    return lower, step, counts


def build_table(robot: Robot, grid: OctreeGrid, config: ReachabilityConfig | None = None,
                progress: Progress | None = None) -> ReachabilityTable:
    """Compute the table (no cache). Raises `Cancelled` through `progress`."""
    config = config or ReachabilityConfig()
    progress = progress or Progress("reachability table")
    t0 = time.perf_counter()
    progress.update(0.0, "joint steps")
    radii = (np.asarray(config.radii, dtype=float) if config.radii is not None
             else joint_reach_radii(robot))
    lower, step, counts = joint_grid(robot, radii, config)
    total = int(np.prod(counts.astype(float)))
    check_grid_budget(total, config.memory_mb)
    leaf_of = np.empty(total, dtype=np.int32)
    rng = np.random.default_rng(1)
    if counts[0] > 1 and _turns_about_base_z(robot, rng):
        _bin_by_rotation(robot, grid, lower, step, counts, leaf_of, progress.sub(0.05, 0.6))
    else:
        _bin_generic(robot, grid, lower, step, counts, leaf_of, config.chunk,
                     progress.sub(0.05, 0.6))
    progress.update(0.6, "grouping joint positions per leaf")
    ids = np.flatnonzero(leaf_of >= 0).astype(np.int32)
    leaf_of = leaf_of[ids]
    order = np.argsort(leaf_of, kind="stable")
    leaf_sorted = leaf_of[order]
    ids = ids[order]
    del leaf_of, order
    progress.update(0.75, "diversity order")
    starts = np.flatnonzero(np.r_[True, leaf_sorted[1:] != leaf_sorted[:-1]])
    leaves = leaf_sorted[starts].astype(np.int64)
    offsets = np.r_[starts, len(ids)].astype(np.int64)
    del leaf_sorted
    ids = _diversity_order(ids, offsets)
    progress.update(1.0, f"{len(ids)} joint positions in {len(leaves)} leaves", force=True)
    return ReachabilityTable(
        key=table_key(robot, grid, config), grid=grid, radii=radii, lower=lower, step=step,
        counts=counts, leaves=leaves, offsets=offsets, positions=ids,
        build_seconds=time.perf_counter() - t0)


def _bin_by_rotation(robot: Robot, grid: OctreeGrid, lower: Array, step: Array, counts: Array,
                     leaf_of: Array, progress: Progress) -> None:
    """FK once over the (J2..Jn) grid at q1 = 0, then rotate by each J1 value."""
    rest = tuple(int(c) for c in counts[1:])
    m = int(np.prod(rest))
    p0 = np.empty((m, 3))
    chunk = 1 << 17
    for s in range(0, m, chunk):
        idx = np.stack(np.unravel_index(np.arange(s, min(m, s + chunk)), rest), axis=1)
        Q = np.zeros((len(idx), robot.dof))
        Q[:, 0] = 0.0
        Q[:, 1:] = lower[1:] + idx * step[1:]
        p0[s:s + len(idx)] = robot.batch_fk(Q).positions
    o = grid.origin
    inv = 1.0 / grid.leaf
    n = grid.n
    # Per-axis leaf coordinates of the rotation-invariant parts.
    x0, y0 = p0[:, 0], p0[:, 1]
    kz = np.floor((p0[:, 2] - o[2]) * inv).astype(np.int64)
    zbad = (kz < 0) | (kz >= n)
    base_z = np.clip(kz, 0, n - 1)
    n1 = int(counts[0])
    block = max(1, (1 << 19) // max(m, 1))
    for a in range(0, n1, block):
        q1 = lower[0] + np.arange(a, min(n1, a + block)) * step[0]
        c, s = np.cos(q1)[:, None], np.sin(q1)[:, None]
        ix = np.floor((c * x0 - s * y0 - o[0]) * inv).astype(np.int64)
        iy = np.floor((s * x0 + c * y0 - o[1]) * inv).astype(np.int64)
        bad = (ix < 0) | (ix >= n) | (iy < 0) | (iy >= n) | zbad
        flat = (ix * n + iy) * n + base_z
        flat[bad] = -1
        leaf_of[a * m:(a + len(q1)) * m] = flat.reshape(-1)
        progress.update((a + len(q1)) / n1, "binning TCP positions")


def _bin_generic(robot: Robot, grid: OctreeGrid, lower: Array, step: Array, counts: Array,
                 leaf_of: Array, chunk: int, progress: Progress) -> None:
    shape = tuple(int(c) for c in counts)
    total = len(leaf_of)
    for s in range(0, total, chunk):
        idx = np.stack(np.unravel_index(np.arange(s, min(total, s + chunk)), shape), axis=1)
        Q = lower + idx * step
        leaf_of[s:s + len(idx)] = grid.flat_of_points(robot.batch_fk(Q).positions)
        progress.update(min(total, s + chunk) / total, "binning TCP positions")


def _bit_reverse(v: Array, width: Array) -> Array:
    """Reverse the low `width` bits of each v (widths may differ per element, <= 32)."""
    x = v.astype(np.uint64)
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF),
                        (16, 0x0000FFFF)):
        s, m = np.uint64(shift), np.uint64(mask)
        x = ((x >> s) & m) | ((x & m) << s)
    return x >> (np.uint64(32) - width.astype(np.uint64))


def _diversity_order(ids: Array, offsets: Array) -> Array:
    """Permute each leaf's (grid-sorted) ids into van der Corput order of their ranks."""
    counts = np.diff(offsets)
    slot = np.repeat(np.arange(len(counts), dtype=np.uint32), counts)
    rank = np.arange(len(ids), dtype=np.uint32)
    rank -= offsets[:-1].astype(np.uint32)[slot]
    width = np.ceil(np.log2(np.maximum(counts, 1))).astype(np.uint32)[slot]
    key = _bit_reverse(rank, width)
    del rank
    key[width == 0] = 0
    del width
    key |= slot.astype(np.uint64) << np.uint64(32)
    del slot
    return ids[np.argsort(key)]


# -------------------------------------------------------------------- cache
def grid_points(robot: Robot, radii: Array, config: ReachabilityConfig) -> int:
    """Points of the full joint grid the parameters ask for (a float product: may be huge)."""
    return int(np.prod(joint_grid(robot, radii, config)[2].astype(float)))


def store_kind(robot: Robot, radii: Array, config: ReachabilityConfig) -> str:
    """"grid" or "samples": `config.store`, or for "auto" the grid while it has at most
    `grid_points` points and fits the memory budget."""
    if config.store in ("grid", "samples"):
        return config.store
    if config.store != "auto":
        raise ValueError(f"unknown joint-position store {config.store!r}: "
                         "use 'auto', 'grid' or 'samples'")
    total = grid_points(robot, radii, config)
    fits = total * BYTES_PER_GRID_POINT <= config.memory_mb * 2**20
    return "grid" if total <= config.grid_points and fits else "samples"


def store_path(robot: Robot, grid: OctreeGrid, config: ReachabilityConfig,
               cache: str | os.PathLike | None, kind: str) -> Path:
    key = table_key(robot, grid, config) if kind == "grid" else samples_key(robot, grid, config)
    return cache_dir(cache) / ("reachability" if kind == "grid" else "joint_samples") / \
        f"{key}.npz"


def is_cached(robot: Robot, grid: OctreeGrid, config: ReachabilityConfig,
              cache: str | os.PathLike | None = None) -> bool:
    kinds = ("grid", "samples") if config.store == "auto" else (config.store,)
    return any(store_path(robot, grid, config, cache, k).exists() for k in kinds)


def cached_store(robot: Robot, grid: OctreeGrid, config: ReachabilityConfig,
                 cache: str | os.PathLike | None = None) -> JointStore | None:
    """The store from the disk cache, if one for these parameters is there and readable."""
    kinds = ("grid", "samples") if config.store == "auto" else (config.store,)
    for kind in kinds:
        path = store_path(robot, grid, config, cache, kind)
        if not path.exists():
            continue
        try:
            store = (ReachabilityTable.load(path) if kind == "grid"
                     else SampledTable.load(path))
        except (OSError, ValueError, KeyError):
            continue  # unreadable or stale: rebuilt and overwritten
        if path.stem == store.key:
            return store
    return None


def load_or_build(robot: Robot, grid: OctreeGrid, config: ReachabilityConfig | None = None,
                  progress: Progress | None = None, *,
                  cache: str | os.PathLike | None = None, use_cache: bool = True,
                  ) -> JointStore:
    """The joint-position store from the disk cache if present, else built (then cached):
    the full grid or the sampled store (`store_kind`)."""
    config = config or ReachabilityConfig()
    if use_cache:
        store = cached_store(robot, grid, config, cache)
        if store is not None:
            return store
    given = config
    progress = progress or Progress("joint positions")
    progress.update(0.0, "joint steps")
    radii = (np.asarray(config.radii, dtype=float) if config.radii is not None
             else joint_reach_radii(robot))
    kind = store_kind(robot, radii, config)
    config = replace(config, radii=tuple(float(r) for r in radii)) if config.radii is None \
        else config
    store: JointStore
    if kind == "grid":
        store = build_table(robot, grid, config, progress)
    else:
        store = build_samples(robot, grid, config, radii, progress.sub(0.05, 1.0))
    # cached under the key of the parameters as given (radii measured or not)
    store.key = store_path(robot, grid, given, cache, kind).stem
    if use_cache:
        store.save(store_path(robot, grid, given, cache, kind))
    return store
