"""Cell-extension Voronoi: labels on hand-made grids, roads midway, incremental == rebuild."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.roadmap.sources import label_sources, relabel
from assistant.roadmap.voronoi import (
    INF,
    ROAD,
    ROAD_UNREACHABLE,
    build_voronoi,
    terminal_labels,
    update_voronoi,
)


def grid2d(rows: list[str]) -> np.ndarray:
    """ASCII map -> (n, m, 1) source grid: digits are source labels, '.' free."""
    a = np.array([[int(c) if c.isdigit() else 0 for c in r] for r in rows], dtype=np.int32)
    return a[:, :, None]


def show(label: np.ndarray) -> list[str]:
    ch = {ROAD: "-", ROAD_UNREACHABLE: "0"}
    return ["".join(ch.get(int(v), str(int(v))) for v in row) for row in label[:, :, 0]]


@pytest.mark.parametrize("width", [9, 10])
def test_road_runs_midway_between_two_walls(width):
    src = np.zeros((5, width, 1), np.int32)
    src[:, 0] = 1
    src[:, -1] = 2
    v = build_voronoi(src)
    road_cols = np.flatnonzero(np.all(v.label[:, :, 0] == ROAD, axis=0))
    assert len(road_cols) == 1 and not (v.label == ROAD).sum() - 5
    mid = (width - 1) / 2
    assert abs(road_cols[0] - mid) <= 0.5
    # every other free cell belongs to the nearer wall
    lab = v.label[0, :, 0]
    assert np.all(lab[1:road_cols[0]] == 1) and np.all(lab[road_cols[0] + 1:-1] == 2)
    assert v.dist[0, 1, 0] == 1 and v.dist[0, road_cols[0], 0] == min(road_cols[0],
                                                                    width - 1 - road_cols[0])


def test_three_obstacles_in_a_room_hand_checked():
    rows = ["444444444",
            "4.......4",
            "4.1...2.4",
            "4.......4",
            "4.......4",
            "4...3...4",
            "444444444"]
    v = build_voronoi(grid2d(rows))
    # (1,1): its distance-0 neighbours are wall 4 and obstacle 1 -> road.
    # (1,4): only wall cells at distance 0 -> wall's region.
    # (2,3): sees only obstacle 1 below it, but its same-distance neighbour (1,4) carries
    #        the larger label 4 -> the even-gap rule makes it the road.
    # (2,4): all its distance-1 neighbours are roads except (1,4) -> region 4.
    assert show(v.label) == [
        "444444444",
        "4---4---4",
        "4-1-4-2-4",
        "4-------4",
        "444-3-444",
        "444-3-444",
        "444444444"]
    assert v.dist[2, 4, 0] == 2 and v.dist[4, 1, 0] == 1 and v.dist[4, 2, 0] == 2


def test_a_single_source_in_a_room_is_ringed_by_road():
    rows = ["1111111",
            "1.....1",
            "1.....1",
            "1..2..1",
            "1.....1",
            "1.....1",
            "1111111"]
    v = build_voronoi(grid2d(rows))
    assert show(v.label) == [
        "1111111",
        "1-----1",
        "1-222-1",
        "1-222-1",
        "1-222-1",
        "1-----1",
        "1111111"]


def test_unreachable_road_cells_are_zero_and_unreached_cells_stay_unlabelled():
    src = np.zeros((5, 7, 1), np.int32)
    src[:, 0] = 1
    src[:, 6] = 2
    reach = np.ones(src.shape, bool)
    reach[2, 3, 0] = False
    v = build_voronoi(src, reach)
    assert v.label[2, 3, 0] == ROAD_UNREACHABLE
    assert np.all(v.label[[0, 1, 3, 4], 3, 0] == ROAD)
    # a free pocket sealed off by sources is never reached
    src2 = np.ones((5, 5, 1), np.int32)
    src2[2, 2, 0] = 0
    src2[0, 0, 0] = 0
    v2 = build_voronoi(src2)
    assert v2.label[2, 2, 0] == 1 and v2.dist[2, 2, 0] == 1
    sealed = np.zeros((5, 5, 5), np.int32)
    sealed[1:4, 1:4, 1:4] = 1
    sealed[2, 2, 2] = 0
    sealed[0] = 0
    v3 = build_voronoi(np.where(sealed > 0, 0, 0) + (sealed > 0) * 1)
    assert v3.dist[2, 2, 2] == 1  # reached from its walls
    only_free = build_voronoi(np.zeros((3, 3, 3), np.int32))
    assert np.all(only_free.dist == INF)


def test_3d_road_is_the_mid_plane_between_two_blocks():
    src = np.zeros((8, 6, 6), np.int32)
    src[0] = 1
    src[7] = 2
    v = build_voronoi(src)
    roads = np.argwhere(v.label == ROAD)
    assert set(roads[:, 0].tolist()) == {3}  # even gap: the smaller label's side
    assert len(roads) == 36


def test_start_and_goal_sources_get_roads_around_them():
    src = np.zeros((11, 11, 1), np.int32)
    src[0, :] = src[-1, :] = src[:, 0] = src[:, -1] = 1
    src[5, 3] = 2  # start
    src[5, 7] = 3  # goal
    v = build_voronoi(src)
    lab = v.label[:, :, 0]
    # the start's region is closed off by roads, which touch the goal's region
    region = np.argwhere(lab == 2)
    assert len(region) > 1
    ring = {(i + di, j + dj) for i, j in region for di in (-1, 0, 1) for dj in (-1, 0, 1)}
    ring -= {tuple(x) for x in region}
    assert all(lab[i, j] in (ROAD, 2) for i, j in ring)
    assert lab[5, 5] == ROAD


def _random_case(rng: np.random.Generator):
    if rng.random() < 0.5:
        shape = (int(rng.integers(4, 22)), int(rng.integers(4, 22)), 1)
    else:
        shape = tuple(int(s) for s in rng.integers(3, 12, size=3))
    src = np.zeros(shape, np.int32)
    n_labels = int(rng.integers(1, 7))
    m = rng.random(shape) < rng.uniform(0.01, 0.25)
    src[m] = rng.integers(1, n_labels + 1, size=int(m.sum()))
    reach = rng.random(shape) < 0.9
    return src, reach, n_labels


@pytest.mark.parametrize("seed", range(60))
def test_incremental_update_equals_full_rebuild(seed):
    rng = np.random.default_rng(seed)
    src, reach, n_labels = _random_case(rng)
    v = build_voronoi(src, reach)
    for _ in range(3):  # a few successive updates
        new = v.source.copy()
        for _ in range(int(rng.integers(1, 5))):
            i = tuple(int(rng.integers(0, s)) for s in new.shape)
            new[i] = int(rng.integers(0, n_labels + 3))  # add, relabel or remove a source
        upd = update_voronoi(v, new, d_min=int(rng.integers(0, 7)))  # planner: 3 and 5
        full = build_voronoi(new, reach)
        assert upd.vmap.same_as(full)
        assert np.array_equal(upd.changed, (full.dist != v.dist) | (full.tent != v.tent)
                              | (full.label != v.label))
        v = upd.vmap


def _terminal_case(seed: int) -> int:
    """Four queries' terminals on one random map; how many needed more than one round."""
    from assistant.roadmap.sources import SourceLabels

    rng = np.random.default_rng(seed)
    src, reach, n_labels = _random_case(rng)
    if seed % 2:  # nine cells in ten sources, as in the planner's grids
        dense = rng.random(src.shape) < 0.9
        src[dense & (src == 0)] = rng.integers(1, n_labels + 1, int((dense & (src == 0)).sum()))
    base = build_voronoi(src, reach)
    labels = SourceLabels(src, {k: f"r{k}" for k in range(1, n_labels + 1)})
    grown = 0
    for _ in range(4):
        sc = int(rng.integers(0, src.size))
        gc = sc if rng.random() < 0.2 else int(rng.integers(0, src.size))
        cells, labs = labels.terminals(sc, gc)
        d_min = int(rng.integers(0, 7))
        new, _, _ = labels.with_terminals(sc, gc)
        upd = update_voronoi(base, new, d_min=d_min)
        got = terminal_labels(base, cells, labs, d_min=d_min)
        assert np.array_equal(got, upd.vmap.label)
        assert np.array_equal(got, build_voronoi(new, reach).label)
        grown += upd.rounds > 1
    return grown


@pytest.mark.parametrize("seed", range(60))
def test_terminal_labels_are_the_updated_maps(seed):
    """A query's start and goal put on the map (`terminal_labels`: the first update round
    on its own box, the whole update when that round's ring changes) give the labels of
    the full update and of a rebuild; sparse and dense (the planner's) sources, start and
    goal in one cell or on a source cell, every reset radius the planner might use."""
    _terminal_case(seed)


def test_terminal_labels_cover_rounds_that_grow():
    """The cases above include first rounds whose ring changed (the fallback's path)."""
    assert sum(_terminal_case(s) for s in range(60)) > 0


def test_update_is_local_for_a_new_obstacle_cell():
    src = np.zeros((32, 32, 32), np.int32)
    src[0], src[-1] = 1, 2
    src[:, 0], src[:, -1] = 3, 4
    v = build_voronoi(src)
    # a bump on wall 2 (same region): distances change in the cone of cells now nearer to
    # the bump (Chebyshev), and with them where fronts meet; the update follows that cone
    # and stays well short of the whole grid
    new = src.copy()
    new[30, 10, 16] = 2
    upd = update_voronoi(v, new, d_min=3)
    assert not upd.rebuilt
    assert upd.region_cells < 0.4 * new.size
    assert upd.vmap.same_as(build_voronoi(new))
    # a separate obstacle claims the cone of cells nearer to it than to the walls (Chebyshev
    # distance): the region grows as far as that, still equal to a rebuild
    new2 = src.copy()
    new2[28, 28, 16] = 5
    upd2 = update_voronoi(v, new2, d_min=3)
    assert not upd2.rebuilt and upd2.region_cells < 0.4 * new.size
    assert upd2.vmap.same_as(build_voronoi(new2))


def test_regions_are_per_object_and_shadows_join_their_obstacle():
    shape = (12, 12, 1)
    occupied = np.zeros(shape, bool)
    ids = np.zeros(shape, np.int32)
    occupied[2:4, 2:4] = True
    ids[2:4, 2:4] = 1
    occupied[4:6, 2:4] = True  # touches object 1 but is object 2: still its own region
    ids[4:6, 2:4] = 2
    reachable = np.ones(shape, bool)
    reachable[:, 10:] = False
    has_valid = np.ones(shape, bool)
    has_valid[2:4, 4] = False  # a shadow next to object 1
    labels = label_sources(occupied, ids, ["A", "B"], reachable, has_valid)
    src = labels.source[:, :, 0]
    names = labels.names
    assert names[int(src[2, 2])] == "A" and names[int(src[4, 2])] == "B"
    assert src[2, 4] == src[2, 2]  # the shadow belongs to A
    assert names[int(src[0, 11])] == "unreachable"
    assert (src[:, 0] > 0).all() and names[int(src[6, 0])] == "border"
    # relabelling after a new observed blob keeps every existing label in place
    occupied2 = occupied.copy()
    occupied2[8, 6] = True
    ids2 = ids.copy()
    ids2[8, 6] = -1
    again = relabel(labels, occupied2, ids2, ["A", "B"], reachable, has_valid)
    keep = labels.source > 0
    assert np.array_equal(again.source[keep], labels.source[keep])
    assert again.source[8, 6, 0] == labels.next_label
    assert again.names[int(again.source[8, 6, 0])].startswith("observed")
