"""No operator action waits on a compile: with an empty cache, kernels run their fallbacks
while one background process compiles them, each switching to compiled code as it lands;
with a complete cache they load from it at once."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np

from assistant.collision.broad_phase import (
    _sphere_broad_phase_numpy,
    prune_round_pairs,
    sphere_broad_phase,
)
from assistant.collision.prune_numpy import prune_round_pairs_numpy
from assistant.kernels import lazy
from assistant.robots.dh import (
    _chain_frames_kernel,
    _chain_row_numpy,
    chain_frames_numpy,
    chain_row,
)
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
from assistant.robots.rv2aj_fk_batch import tcp_poses, tcp_poses_numpy

_TOY = textwrap.dedent('''
    import numpy as np
    from assistant.kernels.lazy import kernel

    CALLS = []

    def _twice_numpy(x):
        CALLS.append("fallback")
        return 2.0 * x

    @kernel(fallback=_twice_numpy)
    def twice(x):
        out = np.empty_like(x)
        for i in range(x.shape[0]):
            out[i] = 2.0 * x[i]
        return out

    @kernel
    def total(x):
        s = 0.0
        for v in twice(x):
            s += v
        return s

    def steps():
        twice(np.ones(3))
        yield
        total(np.ones(3))
        yield
''')

_PROBE = textwrap.dedent('''
    import json, sys, time
    from assistant.kernels import lazy
    import toy_kernels as t
    started = lazy.start(steps="toy_kernels:steps")
    pending = lazy.pending_names()
    x = t.twice(np.ones(2)) if False else None
    import numpy as np
    first = t.twice(np.arange(3.0)).tolist(), t.total(np.arange(3.0))
    calls_while_pending = list(t.CALLS)
    done = lazy.wait(240)
    after = t.twice(np.arange(3.0)).tolist(), t.total(np.arange(3.0))
    print(json.dumps(dict(started=started, pending=pending, first=first,
                          calls_while_pending=calls_while_pending, done=done, after=after,
                          still_pending=lazy.pending_names(),
                          hits=sum(t.twice.stats.cache_hits.values()),
                          compiled=[bool(t.twice.signatures), bool(t.total.signatures)],
                          marker=lazy.cache_complete())))
''')


def _probe(tmp_path, env):
    (tmp_path / "toy_kernels.py").write_text(_TOY)
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                         text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_an_empty_cache_runs_fallbacks_then_switches_to_compiled_code(tmp_path):
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["CELLTEACH_CACHE"] = str(tmp_path / "cache")
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    cold = _probe(tmp_path, env)
    assert cold["started"] is True
    assert {"toy_kernels.twice", "toy_kernels.total"} <= set(cold["pending"])
    # while pending: the same answers, computed by the fallback (total's own Python calls
    # the pending twice, which runs its numpy fallback too)
    assert cold["first"] == [[0.0, 2.0, 4.0], 6.0]
    assert cold["calls_while_pending"] == ["fallback", "fallback"]
    assert cold["done"] is True and cold["still_pending"] == []
    assert cold["after"] == [[0.0, 2.0, 4.0], 6.0]
    assert cold["compiled"] == [True, True]
    assert cold["marker"] is True
    # the next process finds the cache complete: no compile process, kernels load from disk
    warm = _probe(tmp_path, env)
    assert warm["started"] is False and warm["pending"] == []
    assert warm["calls_while_pending"] == []
    assert warm["hits"] >= 1
    assert warm["after"] == [[0.0, 2.0, 4.0], 6.0]


def test_a_failed_compile_process_leaves_kernels_compiling_on_call(tmp_path, monkeypatch):
    """If the background process dies, nothing stays on the slow path for ever."""
    monkeypatch.setenv("CELLTEACH_WARM_STEPS", "no_such_module:steps")
    monkeypatch.setattr(lazy, "cache_complete", lambda: False)
    try:
        assert lazy.start(steps="no_such_module:steps") is True
        assert lazy.wait(120)
        assert lazy.pending_names() == []
    finally:
        lazy.set_pending(False)
        lazy._process = None


def test_chain_frames_fallback_agrees_with_the_kernel(rng):
    robot = RV2AJ(RV2AJConfig())
    F = robot.chain.fixed_stack
    Q = rng.uniform(-3.0, 3.0, size=(50, F.shape[0]))
    # 1e-12: six 4x4 products of unit-size entries, each rounding ~1e-16 relative; the two
    # forms sum the same products in another order
    np.testing.assert_allclose(chain_frames_numpy(Q, F), _chain_frames_kernel(Q, F),
                               rtol=0, atol=1e-12)
    out_a, out_b = np.empty((F.shape[0] + 1, 4, 4)), np.empty((F.shape[0] + 1, 4, 4))
    T_a, T_b = np.empty((4, 4)), np.empty((4, 4))
    _chain_row_numpy(Q[0], F, out_a, T_a)
    chain_row.py_func(Q[0], F, out_b, T_b)
    np.testing.assert_allclose(out_a, out_b, rtol=0, atol=1e-12)
    np.testing.assert_allclose(T_a, T_b, rtol=0, atol=1e-12)
    # a wrong angle is seen
    assert not np.allclose(chain_frames_numpy(Q + 1e-6, F), _chain_frames_kernel(Q, F),
                           rtol=0, atol=1e-12)


def test_tcp_poses_fallback_agrees_with_the_kernel(rng):
    from assistant.robots.model import Tool

    for tool in (None, Tool.straight(0.1)):  # without and with a TCP offset
        robot = RV2AJ(RV2AJConfig(tool=tool)) if tool else RV2AJ(RV2AJConfig())
        consts = robot.tcp_kernel_constants
        Q = rng.uniform(robot.limits.lower, robot.limits.upper, size=(200, robot.dof))
        pos_a, rot_a = tcp_poses_numpy(Q, *consts)
        pos_b, rot_b = tcp_poses(Q, *consts)
        # 1e-12 m / 1e-12: a dozen products and sums of sub-metre terms, each rounding
        # ~1e-16; the compiled loop may fuse them (FMA) where numpy does not
        np.testing.assert_allclose(pos_a, pos_b, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rot_a, rot_b, rtol=0, atol=1e-12)
        # a wrong wrist angle is seen
        Q2 = Q.copy()
        Q2[:, 4] += 1e-6
        assert not np.allclose(tcp_poses_numpy(Q2, *consts)[1], rot_b, rtol=0, atol=1e-12)


def test_shape_poses_fallback_agrees_with_the_kernel(rng):
    from assistant.collision.shape_poses import shape_poses, shape_poses_numpy

    frames = rng.normal(size=(30, 6, 4, 4))
    shape_link = rng.integers(0, 6, size=9)
    shape_T = rng.normal(size=(9, 4, 4))
    R_a, t_a = shape_poses_numpy(frames, shape_link, shape_T)
    R_b, t_b = shape_poses(frames, shape_link, shape_T)
    # 1e-12: four products of O(1) entries summed; the orders may differ in the last bit
    np.testing.assert_allclose(R_a, R_b, rtol=0, atol=1e-12)
    np.testing.assert_allclose(t_a, t_b, rtol=0, atol=1e-12)
    # a wrong link is seen
    R_c, _ = shape_poses_numpy(frames, (shape_link + 1) % 6, shape_T)
    assert not np.allclose(R_c, R_b, rtol=0, atol=1e-12)


def test_broad_phase_fallback_agrees_with_the_kernel(rng):
    N, L, S, E = 40, 6, 12, 5
    frames = np.tile(np.eye(4), (N, L, 1, 1))
    frames[:, :, :3, 3] = rng.uniform(-0.3, 0.3, size=(N, L, 3))
    sph_link = rng.integers(0, L, size=S)
    sph_local = rng.uniform(-0.05, 0.05, size=(S, 3))
    sph_r = rng.uniform(0.02, 0.08, size=S)
    sph_shape = rng.integers(0, 4, size=S)
    lo = rng.uniform(-0.3, 0.2, size=(E, 3))
    hi = lo + rng.uniform(0.02, 0.2, size=(E, 3))
    sp_a = rng.integers(0, S, size=10)
    sp_b = rng.integers(0, S, size=10)
    sp_pair = rng.integers(0, 3, size=10)
    args = (frames, sph_link, sph_local, sph_r, sph_shape, lo, hi, sp_a, sp_b, sp_pair, 4, 3)
    env_a, self_a, gap_a = _sphere_broad_phase_numpy(*args)
    env_b, self_b, gap_b = sphere_broad_phase(*args)
    assert env_a.any() and self_a.any() and (~env_a).any()
    # Flags are decided by d^2 <= r^2, computed by each in its own order (~1e-16 m apart):
    # compared where the reference is clear of the threshold - the same flag with every
    # radius 1e-9 relative (>= 2e-11 m) smaller and larger, so rounding cannot flip it.
    env_lo, self_lo, _ = _sphere_broad_phase_numpy(*_scaled(args, 3, 1.0 - 1e-9))
    env_hi, self_hi, _ = _sphere_broad_phase_numpy(*_scaled(args, 3, 1.0 + 1e-9))
    env_clear, self_clear = env_lo == env_hi, self_lo == self_hi
    assert env_clear.mean() > 0.99 and self_clear.mean() > 0.99  # nearly all are compared
    np.testing.assert_array_equal(env_a[env_clear], env_b[env_clear])
    np.testing.assert_array_equal(self_a[self_clear], self_b[self_clear])
    np.testing.assert_allclose(gap_a, gap_b, rtol=0, atol=1e-12)  # metres


def _scaled(args: tuple, i: int, factor: float) -> tuple:
    """`args` with its `i`-th (an array of radii or a distance) times `factor`."""
    return (*args[:i], args[i] * factor, *args[i + 1:])


def test_round_pair_pruning_fallback_agrees_with_the_kernel(rng):
    from scipy.spatial.transform import Rotation

    N, L, S, E, P = 60, 5, 8, 6, 12
    frames = np.tile(np.eye(4), (N, L, 1, 1))
    frames[:, :, :3, :3] = Rotation.random(N * L, random_state=1).as_matrix().reshape(N, L, 3, 3)
    frames[:, :, :3, 3] = rng.uniform(-0.4, 0.4, size=(N, L, 3))
    shape_link = rng.integers(0, L, size=S)
    seg_a = rng.uniform(-0.1, 0.1, size=(S, 3))
    seg_b = seg_a + rng.uniform(-0.2, 0.2, size=(S, 3))
    seg_b[0] = seg_a[0]  # a sphere: a segment of length zero
    seg_r = rng.uniform(0.01, 0.05, size=S)
    seg_r[1] = np.nan  # a mesh: never pruned
    seg_a[1] = seg_b[1] = np.nan
    box_R = Rotation.random(E, random_state=2).as_matrix()
    box_c = rng.uniform(-0.4, 0.4, size=(E, 3))
    box_h = rng.uniform(0.02, 0.2, size=(E, 3))
    pair_a, pair_b = rng.integers(0, S, size=P), rng.integers(0, S, size=P)
    rows = np.arange(0, N, 2)  # every other row: the rest must stay untouched
    env, self_ = rng.random((N, S, E)) < 0.8, rng.random((N, P)) < 0.8
    args = (shape_link, seg_a, seg_b, seg_r, box_R, box_c, box_h, pair_a, pair_b, 0.02)
    env_a, self_a, env_b, self_b = env.copy(), self_.copy(), env.copy(), self_.copy()
    prune_round_pairs_numpy(frames, rows, env_a, self_a, *args)
    prune_round_pairs(frames, rows, env_b, self_b, *args)
    # Flags are decided by bound > apart, each bound summed in its own order (~1e-16 m
    # apart): compared where the reference is clear of the threshold - the same flag with
    # `apart` 1e-9 m smaller and larger, so rounding cannot flip it.
    env_lo, self_lo, env_hi, self_hi = env.copy(), self_.copy(), env.copy(), self_.copy()
    prune_round_pairs_numpy(frames, rows, env_lo, self_lo, *_scaled(args, 9, 1.0 - 5e-8))
    prune_round_pairs_numpy(frames, rows, env_hi, self_hi, *_scaled(args, 9, 1.0 + 5e-8))
    env_clear, self_clear = env_lo == env_hi, self_lo == self_hi
    assert env_clear.mean() > 0.99 and self_clear.mean() > 0.99  # nearly all are compared
    np.testing.assert_array_equal(env_a[env_clear], env_b[env_clear])
    np.testing.assert_array_equal(self_a[self_clear], self_b[self_clear])
    assert (env_a != env).any() and (self_a != self_).any()  # it prunes
    assert (env_a[1::2] == env[1::2]).all() and env_a[:, 1].sum() == env[:, 1].sum()
    # a looser threshold prunes less: the comparison sees the difference
    env_c = env.copy()
    prune_round_pairs_numpy(frames, rows, env_c, self_.copy(), *args[:-1], 0.05)
    assert (env_c != env_a).any()


def test_pending_clearance_gives_the_compiled_answer(rng):
    """The clearance scan's numpy fallback bounds every pair instead of visiting samples in
    bound order; the clearance it leads to is the kernel's."""
    from assistant.collision.checker import CollisionChecker
    from assistant.collision.clearance_numpy import pruned_clearance_numpy
    from assistant.collision.reports import Obstacle
    from assistant.robots.model import CollisionShape, ShapeKind, Tool
    from assistant.transforms import make_T

    robot = RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    shapes = [CollisionShape(ShapeKind.BOX, (0.08, 0.1, 0.06)),  # exact: segment to box
              CollisionShape(ShapeKind.CYLINDER, (0.04, 0.12)),  # FCL measures these
              CollisionShape(ShapeKind.SPHERE, (0.05,))]
    def cell(kinds):
        return CollisionChecker(robot, [
            Obstacle(f"b{i}", make_T(p=rng.uniform([0.2, -0.35, 0.05], [0.45, 0.35, 0.45])),
                     (shapes[k],)) for i, k in enumerate(kinds)])

    # mixed (the exact boxes often decide), and round obstacles only (FCL decides)
    checkers = [cell([0, 1, 2, 0, 1, 2]), cell([1, 2, 1, 2])]
    lo, hi = robot.limits.lower, robot.limits.upper
    calls = []

    def spy(*args):
        out = pruned_clearance_numpy(*args)
        calls.append(len(out[1]))
        return out

    clearance_scan = __import__("assistant.collision.clearance_scan", fromlist=["x"])
    kernel_disp = clearance_scan.pruned_clearance
    for i in range(12):
        checker = checkers[i % 2]
        path = [rng.uniform(lo, hi) * 0.6 for _ in range(3)]
        compiled = checker.min_clearance_along(path)
        lazy.set_pending(True)
        kernel_disp._cellteach_fallback = spy
        try:
            pending = checker.min_clearance_along(path)
        finally:
            kernel_disp._cellteach_fallback = pruned_clearance_numpy
            lazy.set_pending(False)
        # 1e-9 m: the same FCL calls on the same poses, or the same segment-to-box distance
        # summed in another order (~1e-16 relative per term)
        assert abs(compiled - pending) <= 1e-9, (compiled, pending)
    assert calls and max(calls) > 0  # FCL was asked for some pairs (cylinders, spheres)


def test_pending_checks_give_the_compiled_answers(rng):
    """The collision checks a first run makes before its kernels are compiled (numpy
    fallbacks, kernels' own Python) answer as the compiled ones do."""
    from assistant.collision.checker import CollisionChecker
    from assistant.collision.reports import Obstacle
    from assistant.robots.model import CollisionShape, ShapeKind, Tool
    from assistant.transforms import make_T

    robot = RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    blocks = [Obstacle(f"b{i}", make_T(p=rng.uniform([0.15, -0.3, 0.0], [0.45, 0.3, 0.4])),
                       (CollisionShape(ShapeKind.BOX, tuple(rng.uniform(0.04, 0.15, 3))),))
              for i in range(4)]
    checker = CollisionChecker(robot, blocks)
    lo, hi = robot.limits.lower, robot.limits.upper
    Q = rng.uniform(lo, hi, size=(300, robot.dof))
    Q[::7] = rng.uniform(lo - 0.3, hi + 0.3, size=Q[::7].shape)  # some outside the limits
    path = np.linspace(Q[0], Q[1], 40)

    def answers():
        return (checker.is_valid_batch(Q), checker.is_valid_batch_margin(Q)[0],
                checker.is_valid_samples(Q), _first_bad(checker.check_path(list(path))))

    compiled = answers()
    lazy.set_pending(True)
    try:
        pending = answers()
    finally:
        lazy.set_pending(False)
    assert 0 < compiled[0].sum() < len(Q)  # both free and colliding rows
    for a, b in zip(compiled[:3], pending[:3], strict=True):
        np.testing.assert_array_equal(a, b)  # validity is exact: FCL decides both
    assert compiled[3] == pending[3]


def _first_bad(found):
    """check_path's first invalid segment and the fraction along it (None: all valid)."""
    return None if found is None else (found[0], found[1].first_invalid_fraction)
