"""The compiled kernels (numba) against the numpy formulation they replaced, row for row,
and the exact segment distances that keep far pairs from FCL against references.

The broad phase must flag exactly the pairs whose covering spheres reach a box or each other
(the exact checks only see those) and give the same gap (the smoother's certificates rest on
it); the DH batch must give the single-configuration chain's frames.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from contact_bisect import bisect_to_contact
from numba import njit
from scipy.spatial.transform import Rotation

from assistant.collision.broad_phase import (
    _segment_segment_distance,
    prune_round_pairs,
    sphere_broad_phase,
)
from assistant.collision.checker import CollisionChecker
from assistant.collision.clearance_scan import _row_sphere_bounds
from assistant.collision.fcl_shapes import fcl_transform
from assistant.collision.prune_numpy import segment_box_distances
from assistant.collision.reports import Obstacle
from assistant.collision.segment_box import segment_box_distance_one
from assistant.robots.dh import batch_chain_frames, chain_frames, flange_frame
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T


def _box(name: str, centre, size, rpy=(0.0, 0.0, 0.0)) -> Obstacle:
    R = Rotation.from_euler("xyz", rpy).as_matrix()
    return Obstacle(name, make_T(R, centre),
                    (CollisionShape(ShapeKind.BOX, tuple(size)),))


def _reference(chk: CollisionChecker, frames: np.ndarray, scale: float = 1.0):
    """The broad phase as numpy array expressions (the code before the kernel), with the
    spheres' radii times `scale`."""
    r_sph = chk._sph_r * scale
    F = frames[:, chk._sph_link]
    C = (F[..., :3, :3] @ chk._sph_local[:, :, None])[..., 0] + F[..., :3, 3]
    n, s = C.shape[:2]
    R, E, P = len(chk._rshapes), len(chk._env_lo), len(chk._self_pairs)
    env_c = np.zeros((n, R, E), dtype=bool)
    self_c = np.zeros((n, P), dtype=bool)
    gap = np.full(n, np.inf)
    if E:
        d = C[:, :, None, :] - np.clip(C[:, :, None, :], chk._env_lo, chk._env_hi)
        dist2 = (d * d).sum(-1)
        near = dist2 <= r_sph[None, :, None] ** 2
        moving = chk._sph_link != 0
        near[:, ~moving] = False
        for sph in range(s):
            env_c[:, chk._sph_shape[sph]] |= near[:, sph]
        gap = np.minimum(gap, (np.sqrt(dist2[:, moving]) - r_sph[moving, None]).min(
            axis=(1, 2), initial=np.inf))
    if P:
        diff = C[:, chk._sp_a] - C[:, chk._sp_b]
        d2 = (diff * diff).sum(-1)
        rr = r_sph[chk._sp_a] + r_sph[chk._sp_b]
        near = d2 <= rr ** 2
        for j, pair in enumerate(chk._sp_pair):
            self_c[:, pair] |= near[:, j]
        gap = np.minimum(gap, (np.sqrt(d2) - rr).min(axis=1))
    return env_c, self_c, gap


@pytest.fixture(scope="module")
def crowded(rv2aj) -> CollisionChecker:
    return CollisionChecker(rv2aj, [
        _box("O1", [0.30, 0.10, 0.10], [0.10, 0.10, 0.20]),
        _box("O2", [-0.10, 0.30, 0.25], [0.15, 0.10, 0.10], rpy=(0.3, 0.0, 0.7)),
        _box("O3", [0.05, -0.32, 0.40], [0.08, 0.30, 0.05]),
        _box("table", [0.0, 0.0, -0.011], [1.5, 1.5, 0.02]),
    ])


def test_broad_phase_matches_the_numpy_formulation(crowded, rv2aj):
    rng = np.random.default_rng(11)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(2000, 5))
    frames = rv2aj.batch_link_poses(Q)
    env_c, self_c, gap = crowded._candidates(frames, with_gap=True)
    ref_env, ref_self, ref_gap = _reference(crowded, frames)
    # Flags of d^2 <= r^2, computed by the kernel and numpy each in its own order (~1e-16 m
    # apart): compared where the reference is clear of the threshold - the same flag with
    # the radii 1e-9 relative smaller and larger - nearly everywhere.
    env_lo, self_lo, _ = _reference(crowded, frames, 1.0 - 1e-9)
    env_hi, self_hi, _ = _reference(crowded, frames, 1.0 + 1e-9)
    env_clear, self_clear = env_lo == env_hi, self_lo == self_hi
    assert env_clear.mean() > 0.99 and self_clear.mean() > 0.99
    assert np.array_equal(env_c[env_clear], ref_env[env_clear])
    assert np.array_equal(self_c[self_clear], ref_self[self_clear])
    np.testing.assert_allclose(gap, ref_gap, rtol=0, atol=1e-12)
    # Both outcomes occur, for obstacles and for self pairs, or the comparison proves little.
    assert 0.05 < env_c.any(axis=(1, 2)).mean() < 0.95
    assert self_c.any()
    assert (gap > 0).any() and (gap <= 0).any()


def test_broad_phase_without_obstacles_or_self_pairs(rv2aj):
    frames = rv2aj.batch_link_poses(np.zeros((3, 5)))
    free = CollisionChecker(rv2aj, [], self_collision=False)
    env_c, self_c, gap = free._candidates(frames, with_gap=True)
    assert env_c.shape == (3, len(free._rshapes), 0) and self_c.shape == (3, 0)
    assert np.all(gap == np.inf)  # nothing to measure: every move is certified
    # Called directly with a sphere that reaches a box: flagged, gap negative.
    env_c, _, gap = sphere_broad_phase(
        np.ascontiguousarray(np.broadcast_to(np.eye(4), (1, 2, 4, 4))),
        np.array([1]), np.zeros((1, 3)), np.array([0.1]), np.array([0]),
        np.array([[0.05, -1.0, -1.0]]), np.array([[1.0, 1.0, 1.0]]),
        np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), 1, 0)
    assert env_c[0, 0, 0] and gap[0] == pytest.approx(0.05 - 0.1)


def _reference_bounds(chk: CollisionChecker, frames: np.ndarray, scale: float = 1.0,
                      ) -> np.ndarray:
    """The clearance report's sphere bounds as numpy array expressions (the code before
    the kernel): per (configuration, shape, obstacle) the smallest sphere-to-box gap of the
    shape's spheres (radii times `scale`), -inf where a sphere reaches the box or the shape
    has none."""
    F = frames[:, chk._sph_link]
    C = (F[..., :3, :3] @ chk._sph_local[:, :, None])[..., 0] + F[..., :3, 3]
    d = C[:, :, None, :] - np.clip(C[:, :, None, :], chk._env_lo, chk._env_hi)
    gap = np.sqrt((d * d).sum(-1)) - scale * chk._sph_r[None, :, None]
    out = np.full((len(frames), len(chk._rshapes), len(chk._env_lo)), -np.inf)
    for shape in np.unique(chk._sph_shape):
        bound = gap[:, chk._sph_shape == shape].min(axis=1)
        out[:, shape] = np.where(bound > 0.0, bound, -np.inf)
    return out


@njit(cache=False)
def _rows_sphere_bounds(frames, mov_of, has, sph_link, sph_local, sph_r, sph_shape, env_lo,
                        env_hi):
    out = np.empty((frames.shape[0], has.shape[0], env_lo.shape[0]))
    c = np.empty(3)
    for k in range(frames.shape[0]):
        _row_sphere_bounds(frames, k, mov_of, has, sph_link, sph_local, sph_r, sph_shape,
                           env_lo, env_hi, out[k], c)
    return out


def _sphere_bounds(chk: CollisionChecker, frames: np.ndarray) -> np.ndarray:
    """The clearance pass's per-sample sphere bounds (`clearance_scan`) for every shape."""
    n_shapes = len(chk._rshapes)
    has = np.isin(np.arange(n_shapes), chk._sph_shape)
    return _rows_sphere_bounds(np.ascontiguousarray(frames, dtype=float),
                               np.arange(n_shapes), has, chk._sph_link, chk._sph_local,
                               chk._sph_r, chk._sph_shape, chk._env_lo, chk._env_hi)


def test_clearance_bounds_match_the_numpy_formulation(crowded, rv2aj):
    rng = np.random.default_rng(12)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(1500, 5))
    frames = rv2aj.batch_link_poses(Q)
    got = _sphere_bounds(crowded, frames)
    ref = _reference_bounds(crowded, frames)
    # -inf marks a sphere reaching its box (a bound <= 0), decided on gaps computed by the
    # kernel and by numpy: compared where the radii 1e-9 relative either way decide alike
    clear = (np.isinf(_reference_bounds(crowded, frames, 1.0 - 1e-9))
             == np.isinf(_reference_bounds(crowded, frames, 1.0 + 1e-9)))
    assert clear.mean() > 0.99
    assert np.array_equal(np.isinf(got)[clear], np.isinf(ref)[clear])
    fin = np.isfinite(ref) & clear
    np.testing.assert_allclose(got[fin], ref[fin], rtol=0, atol=1e-12)
    # Bounds and "none known" both occur, shapes without spheres have none.
    assert 0.05 < np.isfinite(got).mean() < 0.95
    assert np.all(np.isneginf(got[:, ~np.isin(np.arange(len(crowded._rshapes)),
                                              crowded._sph_shape)]))
    # Bounds hold: never above FCL's distance (a sample of finite rows).
    for k, r, e in np.argwhere(np.isfinite(got))[::997]:
        rs = crowded._rshapes[r]
        rs.obj.setTransform(fcl_transform(frames[k][rs.link] @ rs.shape.T_link_shape))
        d, _ = crowded._pair_distance(rs.obj, crowded._env[e].obj)
        assert got[k, r, e] <= d + 1e-9


def test_clearance_bounds_direct_call():
    """One sphere of shape 0 on link 1, shape 1 without spheres: a gap, then an overlap."""
    frames = np.ascontiguousarray(np.broadcast_to(np.eye(4), (2, 2, 4, 4)).copy())
    frames[1, 1, 0, 3] = 0.9  # the second configuration moves the sphere into the box
    out = _rows_sphere_bounds(frames, np.array([0, 1]), np.array([True, False]),
                              np.array([1]), np.zeros((1, 3)), np.array([0.1]),
                              np.array([0]), np.array([[0.5, -1.0, -1.0]]),
                              np.array([[1.0, 1.0, 1.0]]))
    assert out.shape == (2, 2, 1)
    assert out[0, 0, 0] == pytest.approx(0.5 - 0.1)
    assert np.isneginf(out[1, 0, 0]) and np.all(np.isneginf(out[:, 1]))


def test_batch_chain_frames_match_the_single_chain(rv2aj):
    rng = np.random.default_rng(5)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(50, 5))
    frames, flanges = batch_chain_frames(rv2aj.chain, Q)
    for q, f, fl in zip(Q, frames, flanges, strict=True):
        np.testing.assert_allclose(f, chain_frames(rv2aj.chain, q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(fl, flange_frame(rv2aj.chain, q), rtol=0, atol=1e-12)
    # Non-contiguous and integer input are taken as well (a column slice, a zero posture).
    wide = np.zeros((4, 10))
    wide[:, ::2] = Q[:4]
    np.testing.assert_allclose(batch_chain_frames(rv2aj.chain, wide[:, ::2])[0], frames[:4],
                               rtol=0, atol=0)
    zero = batch_chain_frames(rv2aj.chain, np.zeros((1, 5), dtype=int))[0][0]
    np.testing.assert_allclose(zero, chain_frames(rv2aj.chain, np.zeros(5)), atol=1e-12)


def test_segment_box_distance_scalar_matches_the_vectorised_one():
    rng = np.random.default_rng(3)
    a = rng.uniform(-0.3, 0.3, (3000, 3))
    b = a + rng.normal(0.0, 0.15, (3000, 3))
    b[:200, 0] = a[:200, 0]  # parallel to a face: no crossing on that axis
    b[200:300] = a[200:300]  # a point
    half = rng.uniform(0.01, 0.2, (3000, 3))
    ref = segment_box_distances(a, b, half)  # the numpy form (the kernel's fallback)
    got = np.array([segment_box_distance_one(x, y, h)
                    for x, y, h in zip(a, b, half, strict=True)])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    assert (ref == 0).any() and (ref > 0.05).any()


def test_segment_segment_distance_against_a_dense_search():
    rng = np.random.default_rng(4)
    s = np.linspace(0.0, 1.0, 401)
    for i in range(60):
        p1, q1, p2 = rng.uniform(-0.2, 0.2, (3, 3))
        q2 = p2 + rng.normal(0.0, 0.1, 3)
        if i % 10 == 0:
            q2 = p2 + 0.7 * (q1 - p1)  # parallel
        if i % 10 == 1:
            q2 = p2.copy()  # a point
        X = p1 + s[:, None] * (q1 - p1)
        Y = p2 + s[:, None] * (q2 - p2)
        dense = np.sqrt(((X[:, None] - Y[None]) ** 2).sum(-1)).min()
        got = _segment_segment_distance(p1, q1, p2, q2)
        # Never above any sampled pair (it is the minimum), and the grid gets within 1 mm.
        assert got <= dense + 1e-12
        assert got >= dense - 1e-3


def test_pruned_pairs_keep_fcls_answers(crowded, rv2aj):
    """Most sphere candidates are pruned, and the checks still equal brute-force FCL,
    also for postures that bring a link within millimetres of a box."""
    rng = np.random.default_rng(12)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(1500, 5))
    frames = rv2aj.batch_link_poses(Q)
    env_c, self_c, _ = crowded._candidates(frames)
    before = int(env_c.sum() + self_c.sum())
    rows = np.arange(len(Q))
    prune_round_pairs(frames, rows, env_c, self_c, crowded._shape_link, crowded._seg_a,
                      crowded._seg_b, crowded._seg_r, crowded._env_R, crowded._env_c,
                      crowded._env_h, crowded._pair_a, crowded._pair_b, crowded.PRUNE_APART)
    assert int(env_c.sum() + self_c.sum()) < 0.85 * before  # random postures: many touch
    fast = crowded.in_collision_batch(Q)
    naive = np.array([crowded.in_collision_naive(q) for q in Q])
    assert np.array_equal(fast, naive) and 0.05 < fast.mean() < 0.95
    # Postures near contact: bisect between a free and a colliding posture.
    near = bisect_to_contact(crowded, Q[~fast][:40], Q[fast][:40])
    assert np.array_equal(crowded.in_collision_batch(near),
                          np.array([crowded.in_collision_naive(q) for q in near]))


@pytest.mark.fresh_compile  # ~3.5 min: selected by .ci/run's generic-CPU pass only
def test_warm_up_compiles_every_kernel(tmp_path):
    """In a fresh process with an empty numba cache, nothing is compiled until `warm_up`,
    and after it every kernel is (so `cellteach serve` compiles them all up front)."""
    code = (
        "import json\n"
        "from assistant.warmup import steps as w\n"
        "before = [bool(k.signatures) for k in w.KERNELS]\n"
        "w.warm_up()\n"
        "print(json.dumps([before, [bool(k.signatures) for k in w.KERNELS]]))\n")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    env.pop("NUMBA_DISABLE_JIT", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=300, check=True)
    before, after = json.loads(out.stdout.strip().splitlines()[-1])
    assert not any(before)
    assert all(after)
