"""The compiled fitter control flow (`fit_search`) against the Python formulation it replaced
(`fit_reference`), fit for fit: the same primitives, deviations and tangency errors up to
last-bit differences of the compiled arithmetic (see `_same`), the same corner count - on
synthetic paths (lines, arcs, bends, corners, noise, with every tolerance the planner uses)
and on elastic nets of real planning queries."""

from __future__ import annotations

import numpy as np
import pytest
from fit_reference import fit_primitives_reference

from assistant.trajectory.primitives import FitParams, PrimitiveFit, fit_primitives

# Both fitters evaluate the same formulas, but numba compiles them for the host CPU (FMA
# contraction, vector width, libm) and the reference calls the kernels one by one: results
# may differ in the last bits on another processor. 1e-9 (m, rad) is far above that (the
# worst-conditioned quantity, the centre of an r_max = 1 m arc through nodes ~10 mm apart,
# amplifies a 1e-16 relative difference to ~1e-12 m) and far below anything a fit changes:
# the node tolerances are 1-2 mm.
_GEOM = 1e-9


def _layout(fit: PrimitiveFit) -> list[tuple[type, int, int]]:
    return [(type(p), p.first_node, p.last_node) for p in fit.primitives]


def _same(a: PrimitiveFit, b: PrimitiveFit, tolerance: float) -> None:
    """The compiled fit `a` is the reference fit `b`: the same primitives covering the same
    nodes, with the same geometry, deviations and tangency errors up to `_GEOM`.

    The one legitimate difference: growth asks whether a node lies within `tolerance` of a
    candidate (and which arc guess is closest), so a node lying within a few ULPs of that
    bound may be decided differently by the two evaluations, moving one boundary and what
    follows it. Then the fits must agree up to that primitive, each must still hold every
    node within the tolerance, and the primitive counts may differ by at most one (a
    shifted boundary leaves the greedy growth at most one primitive better or worse)."""
    la, lb = _layout(a), _layout(b)
    if la != lb:
        k = next((i for i, (x, y) in enumerate(zip(la, lb, strict=False)) if x != y),
                 min(len(la), len(lb)))
        _same_primitives(a.primitives[:k], b.primitives[:k])
        assert abs(len(la) - len(lb)) <= 1, (la, lb)
        for fit in (a, b):
            assert fit.max_deviation <= tolerance + _GEOM
            assert fit.primitives[0].first_node == 0
            assert fit.primitives[-1].last_node == len(fit.node_deviation) - 1
            for p, q in zip(fit.primitives[:-1], fit.primitives[1:], strict=False):
                assert p.last_node == q.first_node  # contiguous, every node covered
        return
    _same_primitives(a.primitives, b.primitives)
    np.testing.assert_allclose(a.node_deviation, b.node_deviation, rtol=0, atol=_GEOM)
    assert [e is None for e in a.tangency_error] == [e is None for e in b.tangency_error]
    np.testing.assert_allclose([e for e in a.tangency_error if e is not None],
                               [e for e in b.tangency_error if e is not None],
                               rtol=0, atol=_GEOM)
    assert a.tangency_breaks == b.tangency_breaks


def _same_primitives(ps: list, qs: list) -> None:
    assert len(ps) == len(qs)
    for p, q in zip(ps, qs, strict=True):
        assert type(p) is type(q)
        assert (p.first_node, p.last_node) == (q.first_node, q.last_node)
        for f in ("start", "end", "via", "centre", "normal", "radius", "sweep"):
            if hasattr(p, f):
                np.testing.assert_allclose(getattr(p, f), getattr(q, f), rtol=0,
                                           atol=_GEOM, err_msg=f)


def _path(rng: np.random.Generator, pieces: int, noise: float) -> np.ndarray:
    """Lines and arcs joined end to end (tangent or at corners), ~10 mm node spacing."""
    p, d = np.zeros(3), np.array([1.0, 0.0, 0.0])
    out = [p]
    for _ in range(pieces):
        if rng.random() < 0.5:
            n = int(rng.integers(3, 25))
            for _ in range(n):
                p = p + 0.01 * d
                out.append(p)
        else:
            axis = rng.normal(size=3)
            axis -= (axis @ d) * d
            axis /= np.linalg.norm(axis)
            radius = rng.uniform(0.02, 0.3)
            sweep = rng.uniform(0.3, 2.5)
            centre = p + radius * np.cross(axis, d)
            r0 = p - centre
            for a in np.linspace(0.0, sweep, max(3, int(radius * sweep / 0.01)))[1:]:
                q = centre + np.cos(a) * r0 + np.sin(a) * np.cross(axis, r0)
                out.append(q)
            p = out[-1]
            d = np.cos(sweep) * np.cross(axis, r0) / radius - np.sin(sweep) * r0 / radius
        if rng.random() < 0.3:  # a corner
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
    P = np.array(out)
    return P + rng.normal(scale=noise, size=P.shape)


@pytest.mark.parametrize("seed", range(40))
def test_compiled_fit_equals_the_python_fitter_on_synthetic_paths(seed):
    rng = np.random.default_rng(seed)
    nodes = _path(rng, int(rng.integers(1, 7)), [0.0, 0.0003, 0.001, 0.003][seed % 4])
    for tol in (0.002, 0.002 / 2.5, 0.001):
        params = FitParams(tolerance=tol)
        _same(fit_primitives(nodes, params), fit_primitives_reference(nodes, params), tol)


def test_compiled_fit_equals_the_python_fitter_on_short_and_degenerate_paths():
    for nodes in (np.array([[0.0, 0, 0], [0.1, 0, 0]]),
                  np.array([[0.0, 0, 0], [0.0, 0, 0], [0.0, 0, 0]]),  # no length at all
                  np.array([[0.0, 0, 0], [0.05, 0.05, 0], [0.1, 0, 0]]),
                  np.zeros((1, 3)) + np.linspace(0, 0.2, 30)[:, None] * [1, 1, 0]):
        _same(fit_primitives(nodes), fit_primitives_reference(nodes, FitParams()),
              FitParams().tolerance)


def test_compiled_fit_equals_the_python_fitter_on_planned_nets(thesis_nets):
    assert len(thesis_nets) >= 2
    for nodes in thesis_nets:
        for tol in (0.002, 0.0008, 0.001):
            params = FitParams(tolerance=tol)
            _same(fit_primitives(nodes, params), fit_primitives_reference(nodes, params), tol)


@pytest.fixture(scope="module")
def thesis_nets() -> list[np.ndarray]:
    """The elastic nets of the thesis mission's transfers (final smoothing)."""
    import assistant.planning.mission_planner as mp_module
    from assistant.planning.scenario import load_scenario
    from tests.planning.planning_fixtures import make_planner

    sc = load_scenario()
    planner = make_planner(sc.cell.robot(), sc.known_obstacles())
    nets: list[np.ndarray] = []
    run = mp_module.run_elastic_net

    def recording(*args, **kwargs):
        res = run(*args, **kwargs)
        nets.append(np.array(res.particles.points))
        return res

    mp_module.run_elastic_net = recording
    try:
        plan = planner.plan_mission(sc.mission, sc.cell.T_world_base, np.zeros(5))
    finally:
        mp_module.run_elastic_net = run
    assert plan.ok
    return nets
