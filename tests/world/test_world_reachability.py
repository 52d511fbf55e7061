"""Reachability table: steps, binning (FK lands in the leaf), reach limits, diversity order,
disk cache (hit, key, env override) and cancellation."""

from __future__ import annotations

import numpy as np
import pytest

import assistant.world.reachability as reach_mod
from assistant.progress import Cancelled, Progress
from assistant.world.octree import OctreeGrid
from assistant.world.reachability import (
    ReachabilityConfig,
    build_table,
    cache_dir,
    joint_grid,
    joint_reach_radii,
    load_or_build,
)

SHOULDER = np.array([0.0, 0.0, 0.3])
COARSE = ReachabilityConfig(d_step=0.0625)


@pytest.fixture(scope="module")
def coarse_grid() -> OctreeGrid:
    return OctreeGrid.for_leaf(2.0, 0.125)


@pytest.fixture(scope="module")
def coarse_table(rv2aj, coarse_grid):
    return build_table(rv2aj, coarse_grid, COARSE)


@pytest.fixture(scope="module")
def thesis_table(rv2aj):
    """The thesis resolution: 2 m cube, 62.5 mm leaves, d_step = 31.25 mm."""
    return build_table(rv2aj, OctreeGrid.for_leaf(2.0, 0.0625), ReachabilityConfig())


def test_radii_are_the_tcp_distances_from_each_axis(rv2aj):
    r = joint_reach_radii(rv2aj)
    # J1, J2: stretched arm 0.25 + 0.16 + 0.072 + 0.1; J3: 0.332; J5: 0.172; J6: TCP on axis
    assert r[:4] == pytest.approx([0.582, 0.582, 0.332, 0.172], abs=2e-3)
    assert r[4] < 1e-6


def test_steps_against_thesis_table_8(rv2aj):
    radii = joint_reach_radii(rv2aj)
    lower, step, counts = joint_grid(rv2aj, radii, ReachabilityConfig())
    nominal = np.degrees(0.03125 / radii[:4])
    # J2, J3, J5: delta_i = d_step / r_i as in Table 8
    assert nominal[1:] == pytest.approx([3.08, 5.40, 10.42], abs=0.03)
    # ranges are split evenly with both ends on the grid: never coarser than nominal
    assert np.all(np.degrees(step[:4]) <= nominal + 1e-9)
    assert np.degrees(step[:4]) == pytest.approx([3.06, 3.05, 5.35, 10.0], abs=0.01)
    # J1: Table 8 used 0.712 m (sum of link lengths, incl. a vertical 0.13 m) -> 2.51 deg;
    # the TCP is at most 0.582 m from the J1 axis, so a 3.08 deg step already moves it 31 mm
    assert nominal[0] == pytest.approx(3.08, abs=0.03)
    # J6 does not move a TCP on its axis: fixed, not multiplied into the grid
    assert counts[4] == 1 and step[4] == 0.0
    assert counts[:4].tolist() == [99, 60, 44, 19]


def test_every_binned_position_has_its_tcp_in_its_leaf(rv2aj, coarse_table, thesis_table, rng):
    for table in (coarse_table, thesis_table):
        idx = rng.choice(table.n_positions, size=min(20000, table.n_positions), replace=False)
        leaf = table.leaf_of_positions()[idx]
        q = table.joints(table.positions[idx])
        assert table.grid.flat_of_points(rv2aj.batch_fk(q).positions).tolist() == leaf.tolist()
        assert rv2aj.limits.contains_batch(q).all()
    # the thesis table in numbers (figures in the issue note)
    assert thesis_table.n_positions > 4_000_000
    assert 3000 < len(thesis_table.leaves) < 5000


def _leaf_distance_range(grid: OctreeGrid, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest and farthest distance of each leaf box from the shoulder."""
    c = grid.centres_of_ijk(grid.ijk_of_flat(flat))
    h = grid.leaf / 2
    near = np.linalg.norm(np.maximum(np.abs(c - SHOULDER) - h, 0.0), axis=1)
    far = np.linalg.norm(np.abs(c - SHOULDER) + h, axis=1)
    return near, far


def test_nothing_beyond_reach_and_known_points_reachable(rv2aj, thesis_table):
    grid = thesis_table.grid
    near, _ = _leaf_distance_range(grid, thesis_table.leaves)
    assert near.max() <= 0.582 + 1e-6
    # every leaf entirely beyond 0.65 m from the shoulder is unreachable
    all_flat = np.arange(grid.n_cells)
    near_all, _ = _leaf_distance_range(grid, all_flat)
    assert not thesis_table.reachable().reshape(-1)[near_all > 0.65].any()
    # points well inside the reach, where IK finds a solution, lie in reachable leaves
    reach = thesis_table.reachable().reshape(-1)
    for p in ([0.35, 0.0, 0.35], [0.0, 0.4, 0.5], [-0.2, -0.25, 0.6], [0.3, 0.2, 0.1]):
        T = np.eye(4)
        T[:3, 3] = p
        assert rv2aj.ik(T, position_only=True).ok
        assert reach[grid.flat_of_points(np.array([p]))[0]]


def test_each_leaf_list_is_spread_evenly(coarse_table):
    t = coarse_table
    counts = t.counts_per_leaf()
    s = int(np.argmax(counts))
    ids = t.positions[t.offsets[s]:t.offsets[s + 1]]
    ranks = np.searchsorted(np.sort(ids), ids)  # rank in grid order
    n = len(ids)
    # van der Corput: the first 2^m positions split the grid-sorted list into gaps of at most
    # 2^(w - m) (w = bits of n), i.e. they sample it evenly from the very first ones
    w = int(np.ceil(np.log2(n)))
    for m in (1, 2, 3, 4):
        first = np.sort(ranks[: 2**m])
        assert np.all(np.diff(np.r_[first, n + first[0]]) <= 2 ** (w - m))
    # and the list is a permutation of the leaf's positions
    assert len(np.unique(ids)) == n


def test_cache_hit_returns_the_same_table_without_building(rv2aj, coarse_grid, tmp_path,
                                                           monkeypatch):
    first = load_or_build(rv2aj, coarse_grid, COARSE, cache=tmp_path)
    files = list((tmp_path / "reachability").glob("*.npz"))
    assert len(files) == 1 and files[0].stem == first.key

    def boom(*a, **k):
        raise AssertionError("the builder must not run on a cache hit")

    monkeypatch.setattr(reach_mod, "build_table", boom)
    second = load_or_build(rv2aj, coarse_grid, COARSE, cache=tmp_path)
    for name in ("radii", "lower", "step", "counts", "leaves", "offsets", "positions"):
        assert np.array_equal(getattr(first, name), getattr(second, name)), name
    assert second.grid == first.grid
    # other parameters or another tool: another key, so the builder is needed
    with pytest.raises(AssertionError, match="must not run"):
        load_or_build(rv2aj, coarse_grid, ReachabilityConfig(d_step=0.07), cache=tmp_path)
    with pytest.raises(AssertionError, match="must not run"):
        load_or_build(rv2aj.with_tool(np.eye(4)), coarse_grid, COARSE, cache=tmp_path)


def test_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("CELLTEACH_CACHE", str(tmp_path / "env"))
    assert cache_dir() == tmp_path / "env"
    assert cache_dir(tmp_path / "arg") == tmp_path / "arg"
    monkeypatch.delenv("CELLTEACH_CACHE")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "cellteach"


def test_cancelled_build_leaves_no_cache_file(rv2aj, coarse_grid, tmp_path):
    seen = []

    def cb(ev):
        seen.append(ev.fraction)
        if ev.fraction > 0.2:
            prog.cancel()

    prog = Progress("table", cb, min_interval_s=0.0)
    with pytest.raises(Cancelled):
        load_or_build(rv2aj, coarse_grid, ReachabilityConfig(d_step=0.05), prog, cache=tmp_path)
    assert seen and max(seen) < 1.0
    assert not any(p.is_file() for p in tmp_path.rglob("*"))


def test_failed_write_leaves_no_partial_file(rv2aj, coarse_grid, tmp_path, monkeypatch):
    def broken(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(reach_mod.np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        load_or_build(rv2aj, coarse_grid, COARSE, cache=tmp_path)
    assert not any(p.is_file() for p in tmp_path.rglob("*"))


def test_a_finer_octree_works(rv2aj, rng):
    fine = OctreeGrid.for_leaf(2.0, 0.03125)
    assert fine.shape == (64, 64, 64)
    table = build_table(rv2aj, fine, COARSE)
    idx = rng.choice(table.n_positions, 5000, replace=False)
    q = table.joints(table.positions[idx])
    P = rv2aj.batch_fk(q).positions
    differ = fine.flat_of_points(P) != table.leaf_of_positions()[idx]
    # The table bins its own FK (another evaluation order, compiled for this CPU); a TCP
    # may land within rounding of a leaf face and fall on either side, nowhere else.
    rel = (P - fine.origin) / fine.leaf
    to_face = np.abs(rel - np.round(rel)).min(axis=1) * fine.leaf
    assert differ.sum() <= 5 and np.all(to_face[differ] < 1e-9)  # metres
    # each leaf splits into 8; near the reach boundary some of the 8 are not reachable
    coarse = build_table(rv2aj, OctreeGrid.for_leaf(2.0, 0.0625), COARSE)
    assert 5 * len(coarse.leaves) < len(table.leaves) < 9 * len(coarse.leaves)
