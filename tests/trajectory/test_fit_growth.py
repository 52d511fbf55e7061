"""The primitive fitter's growth, look-ahead and junction refinement (`fit_growth`) on
synthetic paths (lines, arcs, bends, corners, noise, with every tolerance the planner uses),
short and degenerate ones, and the elastic nets of real planning queries: what every fit
must be - every node covered once and within the tolerance, tangent where it must be - and
what the look-ahead buys over plain growth."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.trajectory.fit_growth import fit_primitives
from assistant.trajectory.primitives import FitParams, PrimitiveFit, PrimitiveKind

# A deviation is the distance of a node to its primitive, computed from fitted geometry
# whose worst-conditioned quantity (the centre of an r_max = 1 m arc through nodes ~10 mm
# apart) amplifies rounding to ~1e-12 m: 1e-9 m is far above that and far below the 1-2 mm
# tolerances.
_GEOM = 1e-9


def _valid(fit: PrimitiveFit, n: int, params: FitParams) -> None:
    """Every node covered, in order, once, by joined primitives; each node within the
    tolerance of its primitive; every joint that must be tangent within the tangent slack,
    but for the corners the fit counts as breaks.

    The last primitive is snapped onto the goal, moving its end by up to the tolerance: its
    nodes may then lie up to twice the tolerance off, and its joint may bend by what that
    move turns over its length."""
    prims = fit.primitives
    assert prims[0].first_node == 0 and prims[-1].last_node == n - 1
    for p, q in zip(prims[:-1], prims[1:], strict=False):
        assert p.last_node == q.first_node  # contiguous
        assert p.last_node > p.first_node
        np.testing.assert_allclose(p.end, q.start, rtol=0, atol=_GEOM)  # joined
    last = prims[-1]
    tol = params.tolerance
    assert fit.node_deviation[:last.first_node + 1].max() <= tol + _GEOM
    assert fit.node_deviation.max() <= 2.0 * tol + _GEOM
    assert len(fit.tangency_error) == len(prims) - 1
    over = 0
    for p, q, err in zip(prims[:-1], prims[1:], fit.tangency_error, strict=True):
        assert (err is None) == (p.kind == PrimitiveKind.LINE == q.kind)
        if err is None:
            continue
        bound = params.tangent_slack + 1e-9  # atan2 form: rounding ~1e-16 rad
        if q is last:
            bound += 2.0 * tol / max(q.length, tol)
        over += err > bound
    assert over <= fit.tangency_breaks


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
def test_fits_of_synthetic_paths_cover_every_node_within_the_tolerance(seed):
    rng = np.random.default_rng(seed)
    nodes = _path(rng, int(rng.integers(1, 7)), [0.0, 0.0003, 0.001, 0.003][seed % 4])
    for tol in (0.002, 0.002 / 2.5, 0.001):
        params = FitParams(tolerance=tol)
        _valid(fit_primitives(nodes, params), len(nodes), params)


def test_noiseless_pieces_are_found_as_drawn():
    """A line, a tangent arc and a line again, without noise: three primitives, the arc
    with its drawn radius (the look-ahead keeps the first line from overshooting into it)."""
    line1 = np.outer(np.arange(0, 11) * 0.01, [1.0, 0.0, 0.0])
    a = np.linspace(0.0, np.pi / 2, 17)[1:]
    arc = np.stack([0.1 + 0.1 * np.sin(a), 0.1 - 0.1 * np.cos(a), np.zeros_like(a)], 1)
    line2 = arc[-1] + np.outer(np.arange(1, 11) * 0.01, [0.0, 1.0, 0.0])
    nodes = np.vstack([line1, arc, line2])
    params = FitParams(tolerance=0.0005)
    fit = fit_primitives(nodes, params)
    _valid(fit, len(nodes), params)
    assert [p.kind for p in fit.primitives] == [PrimitiveKind.LINE, PrimitiveKind.ARC,
                                                PrimitiveKind.LINE]
    assert fit.primitives[1].radius == pytest.approx(0.1, abs=params.tolerance)
    assert fit.tangency_breaks == 0


def test_short_and_degenerate_paths():
    params = FitParams()
    for nodes in (np.array([[0.0, 0, 0], [0.1, 0, 0]]),
                  np.array([[0.0, 0, 0], [0.0, 0, 0], [0.0, 0, 0]]),  # no length at all
                  np.array([[0.0, 0, 0], [0.05, 0.05, 0], [0.1, 0, 0]]),
                  np.zeros((1, 3)) + np.linspace(0, 0.2, 30)[:, None] * [1, 1, 0]):
        _valid(fit_primitives(nodes, params), len(nodes), params)
    with pytest.raises(ValueError, match="two nodes"):
        fit_primitives(np.zeros((1, 3)), params)


def test_fits_of_planned_nets(thesis_nets):
    assert len(thesis_nets) >= 2
    for nodes in thesis_nets:
        for tol in (0.002, 0.0008, 0.001):
            params = FitParams(tolerance=tol)
            _valid(fit_primitives(nodes, params), len(nodes), params)


@pytest.fixture(scope="module")
def thesis_nets() -> list[np.ndarray]:
    """The elastic nets of the thesis mission's transfers (final smoothing)."""
    from dataclasses import replace

    import assistant.planning.mission_planner as mp_module
    from assistant.planning.scenario import load_scenario
    from tests.planning.planning_fixtures import FAST, make_planner

    sc = load_scenario()
    # the transfers as smoothed paths: with the joint-move forms a final plan answers most
    # thesis transfers without a net (one certified joint move or two)
    planner = make_planner(sc.cell.robot(), sc.known_obstacles(),
                           config=replace(FAST, transfer_joint_moves=False))
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
