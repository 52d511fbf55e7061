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

from assistant.collision.broad_phase import _sphere_broad_phase_numpy, sphere_broad_phase
from assistant.kernels import lazy
from assistant.robots.dh import (
    _chain_frames_kernel,
    _chain_row_numpy,
    chain_frames_numpy,
    chain_row,
)
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig

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
    # flags are decided by d^2 <= r^2 on the same numbers: exact unless a distance lies
    # within rounding of a radius, which random data of this size never does
    np.testing.assert_array_equal(env_a, env_b)
    np.testing.assert_array_equal(self_a, self_b)
    np.testing.assert_allclose(gap_a, gap_b, rtol=0, atol=1e-12)  # metres


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
