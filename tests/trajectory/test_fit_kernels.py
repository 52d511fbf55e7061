"""The compiled fitter geometry against the numpy formulation it replaced, case for case.

The reference below is the fitter's former numpy code (kept here only as the reference):
on noisy lines, arcs and bends, with and without an incoming tangent, both kernels must
find the same primitives (or none) to 1e-9 m.
"""

from __future__ import annotations

import numpy as np
import pytest

from assistant.trajectory.fit_kernels import (
    _gram,
    _max_or_nan,
    _rotate_radius,
    arc_deviation,
    arc_distances,
    fit_arc,
    fit_line,
    line_deviation,
    line_distances,
    put_on_arc,
    sym2_major,
    sym3_eigvec,
)
from assistant.trajectory.primitives import FitParams

TOL = FitParams().tolerance


# --------------------------------------------------------------------- numpy reference
def _unit(v):
    n = float(np.sqrt(v @ v))
    return v / n if n > 1e-15 else v * 0.0


def _ref_line_dist(a, b, P):
    d = b - a
    L2 = float(d @ d)
    X = P - a
    s = np.clip(X @ d / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(X))
    return np.linalg.norm(X - s[:, None] * d, axis=1)


def _ref_arc_dist(start, end, centre, radius, normal, sweep, P):
    X = P - centre
    h = X @ normal
    V = X - h[:, None] * normal
    rho = np.linalg.norm(V, axis=1)
    r0 = start - centre
    phi = np.mod(np.arctan2(V @ np.cross(normal, r0), V @ r0), 2.0 * np.pi)
    d_arc = np.sqrt(h ** 2 + (rho - radius) ** 2)
    d_end = np.minimum(np.linalg.norm(P - start, axis=1), np.linalg.norm(P - end, axis=1))
    return np.where(phi <= sweep + 1e-12, d_arc, d_end)


def _ref_cone(d, axis, angle):
    c = float(np.clip(d @ axis, -1.0, 1.0))
    if c >= np.cos(angle):
        return d
    perp = _unit(d - c * axis)
    return axis if not perp.any() else np.cos(angle) * axis + np.sin(angle) * perp


def _ref_line(O, t0, pts, p):
    X = pts - O
    Vt = np.linalg.svd(X, full_matrices=False)[2]
    d_ls = Vt[0] * np.sign(Vt[0] @ X.sum(axis=0) or 1.0)
    dirs = [t0, _ref_cone(d_ls, t0, p.tangent_slack)] if t0 is not None else [d_ls, _unit(X[-1])]
    for d in dirs:
        proj = X @ d
        if proj[-1] <= 0.0 or np.any(np.diff(proj) < -p.tolerance):
            continue
        end = O + proj[-1] * d
        if _ref_line_dist(O, end, pts).max() <= p.tolerance:
            return end
    return None


def _ref_circle(a, b, c):
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    nn = float(n @ n)
    if nn < 1e-18 * max(1e-30, float(ab @ ab) * float(ac @ ac)):
        return None
    centre = a + (np.cross(n, ab) * float(ac @ ac) + np.cross(ac, n) * float(ab @ ab)) / (2 * nn)
    return centre, n / np.sqrt(nn)


def _ref_candidates(O, t0, X):
    out = []
    if t0 is None:
        Vt = np.linalg.svd(X, full_matrices=False)[2]
        n = Vt[2] if Vt.shape[0] > 2 else _unit(np.cross(X[0], X[-1]))
        if np.linalg.norm(n) < 0.5:
            return out
        e1 = _unit(X[-1] - (X[-1] @ n) * n)
        e2 = np.cross(n, e1)
        xy = np.stack([X @ e1, X @ e2], axis=1)
        c2 = np.linalg.lstsq(2.0 * xy, (xy ** 2).sum(axis=1), rcond=None)[0]
        out.append((O + c2[0] * e1 + c2[1] * e2, n))
        circle = _ref_circle(O, O + X[len(X) // 2], O + X[-1])
        if circle is not None:
            out.append(circle)
        return out
    b1 = _unit(np.cross(t0, [1.0, 0.0, 0.0] if abs(t0[0]) < 0.9 else [0.0, 1.0, 0.0]))
    b2 = np.cross(t0, b1)
    Y = np.stack([X @ b1, X @ b2], axis=1)
    Vt = np.linalg.svd(Y, full_matrices=False)[2]
    for mc in (Vt[0], _unit(Y[-1]) if np.linalg.norm(Y[-1]) > 1e-12 else None):
        if mc is None:
            continue
        m = mc[0] * b1 + mc[1] * b2
        r2 = (X ** 2).sum(axis=1)
        denom = float((r2 ** 2).sum())
        kappa = float(2.0 * ((X @ m) * r2).sum() / denom) if denom > 0 else 0.0
        if abs(kappa) < 1e-9:
            continue
        out.append((O + m / kappa, _unit(np.cross(t0, m / kappa))))
        xl, rl = float(X[-1] @ m), float(X[-1] @ X[-1])
        if abs(xl) > 1e-12:
            k2 = 2.0 * xl / rl
            out.append((O + m / k2, _unit(np.cross(t0, m / k2))))
    return out


def _ref_arc_from(O, centre, normal, pts, t0, p):
    r0 = O - centre
    radius = float(np.linalg.norm(r0))
    X = pts - centre
    V = np.vstack([r0, X - (X @ normal)[:, None] * normal])
    phi = np.cumsum(np.arctan2(np.cross(V[:-1], V[1:]) @ normal,
                               np.einsum("ij,ij->i", V[:-1], V[1:])))
    if phi[-1] < 0.0:
        normal, phi = -normal, -phi
    if t0 is not None and _unit(np.cross(normal, r0)) @ t0 < np.cos(p.tangent_slack) - 1e-12:
        return None
    if (np.any(np.diff(phi) < -p.tolerance / radius) or phi[-1] > p.max_sweep
            or phi[-1] <= 0.0):
        return None
    sweep = float(phi[-1])
    rot = np.cos(sweep) * r0 + np.sin(sweep) * np.cross(normal, r0)
    end = centre + rot
    dev = float(_ref_arc_dist(O, end, centre, radius, normal, sweep, pts).max())
    return None if dev > p.tolerance else (centre, normal, end, radius, sweep, dev)


def _ref_arc(O, t0, pts, p, first_feasible):
    X = pts - O
    if len(X) < 2 or np.linalg.norm(X[-1]) < 1e-9:
        return None
    if first_feasible:
        cands = _ref_candidates(O, t0, X)
    else:
        kinds = (t0, None) if t0 is not None else (None,)
        cands = [g for t in kinds for g in _ref_candidates(O, t, X)]
    best = None
    for C, N in cands:
        R0 = O - C
        r2 = float(R0 @ R0)
        with np.errstate(invalid="ignore", divide="ignore"):
            N = N - (N @ R0 / r2) * R0
            N = N / np.sqrt(N @ N)
            Xc = pts - C
            h = Xc @ N
            rho = np.linalg.norm(Xc - h[:, None] * N, axis=1)
            dev2 = (h * h + (rho - np.sqrt(r2)) ** 2).max()
        if not (p.r_min ** 2 <= r2 <= p.r_max ** 2 and np.isfinite(C).all()
                and dev2 <= p.tolerance ** 2):
            continue
        arc = _ref_arc_from(O, C, N, pts, t0, p)
        if arc is None:
            continue
        if first_feasible:
            return arc
        if best is None or arc[-1] < best[-1]:
            best = arc
    return best


# --------------------------------------------------------------------- cases
def _cases(seed: int, n: int):
    """(O, t0 or None, nodes): noisy straight runs, arcs and bends, 2-24 nodes; some step
    back along the way by a few tolerances (a zigzag the fit must refuse)."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        m = int(rng.integers(2, 25))
        O = rng.uniform(-0.5, 0.5, 3)
        kind = rng.integers(3)
        u = np.arange(1, m + 1) * 0.02
        if m > 4 and rng.random() < 0.3:
            k = int(rng.integers(1, m - 2))
            u[k] = u[k - 1] - rng.uniform(1.5, 4.0) * TOL
        if kind == 0:  # line
            d = _unit(rng.normal(size=3))
            pts = O + u[:, None] * d
            t0 = d if rng.random() < 0.5 else None
        else:  # arc (kind 2: an arc with a kink of 8 deg in its tangent)
            r = rng.uniform(0.03, 0.6)
            n_ = _unit(rng.normal(size=3))
            e1 = _unit(np.cross(n_, rng.normal(size=3)))
            a = u / r
            e2 = np.cross(n_, e1)
            pts = O + r * (np.cos(a)[:, None] - 1.0) * e1 + r * np.sin(a)[:, None] * e2
            t0 = np.cross(n_, e1)
            if kind == 2:
                c, s = np.cos(0.14), np.sin(0.14)
                t0 = _unit(c * t0 + s * n_)
            if rng.random() < 0.4:
                t0 = None
        pts = pts + rng.normal(scale=rng.choice([0.0, 0.0005, 0.002]), size=pts.shape)
        yield O, t0, np.ascontiguousarray(pts)


def _t(t0):
    return np.zeros(3) if t0 is None else np.ascontiguousarray(t0, dtype=float)


@pytest.mark.parametrize("seed", [1, 2])
def test_line_fit_equals_numpy_reference(seed: int) -> None:
    p = FitParams()
    found = 0
    for O, t0, pts in _cases(seed, 300):
        ok, end = fit_line(O, _t(t0), t0 is not None, pts, p.tolerance, p.tangent_slack)
        ref = _ref_line(O, t0, pts, p)
        assert ok == (ref is not None)
        if ok:
            found += 1
            assert np.allclose(end, ref, atol=1e-9)
    assert 50 < found < 250  # both outcomes are exercised


@pytest.mark.parametrize("first_feasible", [True, False])
@pytest.mark.parametrize("seed", [3, 4])
def test_arc_fit_equals_numpy_reference(seed: int, first_feasible: bool) -> None:
    p = FitParams(r_max=0.5)
    found = 0
    for O, t0, pts in _cases(seed, 300):
        ok, r = fit_arc(O, _t(t0), t0 is not None, pts, p.tolerance, p.tangent_slack, p.r_min,
                        p.r_max, p.max_sweep, first_feasible)
        ref = _ref_arc(O, t0, pts, p, first_feasible)
        assert ok == (ref is not None)
        if ok:
            found += 1
            centre, normal, end, radius, sweep, dev = ref
            assert np.allclose(r[0:3], centre, atol=1e-9)
            assert np.allclose(r[3:6], normal, atol=1e-9)
            assert np.allclose(r[9:12], end, atol=1e-9)
            assert r[12] == pytest.approx(radius, abs=1e-9)
            assert r[13] == pytest.approx(sweep, abs=1e-9)
            assert r[14] == pytest.approx(dev, abs=1e-12)
    assert 50 < found < 250


def test_distances_equal_numpy_reference() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        P = rng.uniform(-1, 1, (int(rng.integers(1, 30)), 3))
        a, b = rng.uniform(-1, 1, (2, 3))
        assert np.allclose(line_distances(a, b, P), _ref_line_dist(a, b, P), atol=1e-12)
        centre = rng.uniform(-1, 1, 3)
        normal = _unit(rng.normal(size=3))
        r0 = _unit(np.cross(normal, rng.normal(size=3))) * rng.uniform(0.01, 1.0)
        sweep = rng.uniform(0.1, 6.0)
        start = centre + r0
        end = centre + np.cos(sweep) * r0 + np.sin(sweep) * np.cross(normal, r0)
        radius = float(np.linalg.norm(r0))
        assert np.allclose(arc_distances(start, end, centre, radius, normal, sweep, P),
                           _ref_arc_dist(start, end, centre, radius, normal, sweep, P),
                           atol=1e-12)


def test_deviations_and_arc_points_equal_their_array_forms_to_the_bit() -> None:
    """The fitter's allocation-free forms: `line_deviation`/`arc_deviation` are the largest
    distance (NaN if any distance is NaN, as `_max_or_nan`), `put_on_arc` is
    centre + `_rotate_radius` - the same bits, so the fitted primitives cannot change."""
    rng = np.random.default_rng(9)
    for t in range(300):
        P = rng.uniform(-1, 1, (int(rng.integers(1, 30)), 3))
        if t % 10 == 0:
            P[int(rng.integers(len(P)))] = np.nan
        a, b, centre = rng.uniform(-1, 1, (3, 3))
        normal = _unit(rng.normal(size=3))
        r0 = _unit(np.cross(normal, rng.normal(size=3))) * rng.uniform(0.01, 1.0)
        sweep = rng.uniform(0.1, 6.0)
        radius = float(np.linalg.norm(r0))
        for got, want in ((line_deviation(a, b, P), _max_or_nan(line_distances(a, b, P))),
                          (arc_deviation(centre + r0, b, centre, radius, normal, sweep, P),
                           _max_or_nan(arc_distances(centre + r0, b, centre, radius, normal,
                                                     sweep, P)))):
            # 1e-15 m: distances below ~3 m from the same few products (FMA may contract
            # them differently in the two compiled forms); NaN exactly where either has one
            assert np.isnan(got) == np.isnan(want)
            assert np.isnan(got) or abs(got - want) <= 1e-15 * max(1.0, abs(want))
        assert np.isnan(line_deviation(a, b, P)) == (t % 10 == 0)
        out = np.full(7, -1.0)
        put_on_arc(centre, r0, normal, sweep, out, 2)
        # 1e-15 m: centre + a Rodrigues rotation of r0 (|.| < 2 m), a few ULPs
        np.testing.assert_allclose(out[2:5], centre + _rotate_radius(r0, normal, sweep),
                                   rtol=0, atol=1e-15)
        assert (out[[0, 1, 5, 6]] == -1.0).all()


def test_gram_eigenvectors_equal_the_singular_vectors() -> None:
    """The fits' principal direction, plane normal and 2-D major axis come from the Gram
    matrix (Jacobi, closed form) instead of an SVD of the nodes: the same directions (up to
    sign) on node sets like the fitter's, straight, bent and scattered."""
    rng = np.random.default_rng(11)
    for t in range(600):
        m = int(rng.integers(3, 25))
        u = np.arange(1, m + 1) * 0.04
        if t % 3 == 0:  # a noisy straight run
            X = np.outer(u, _unit(rng.normal(size=3)))
        elif t % 3 == 1:  # an arc of radius 3-60 cm
            r = rng.uniform(0.03, 0.6)
            e1 = _unit(rng.normal(size=3))
            n = _unit(np.cross(e1, rng.normal(size=3)))
            a = u / r
            X = r * (np.cos(a)[:, None] - 1.0) * e1 + r * np.sin(a)[:, None] * np.cross(n, e1)
        else:
            X = rng.normal(size=(m, 3))
        X = X + rng.normal(scale=rng.choice([0.0, 1e-4, 2e-3]), size=X.shape)
        s, Vt = np.linalg.svd(X, full_matrices=False)[1:]
        M = _gram(X)
        assert np.allclose(M, X.T @ X, rtol=1e-12, atol=1e-15)
        if s[0] - s[1] > 1e-6 * s[0]:
            v = sym3_eigvec(M, True)
            assert min(np.linalg.norm(v - Vt[0]), np.linalg.norm(v + Vt[0])) < 1e-9
        if s[1] - s[2] > 1e-3 * s[0]:
            v = sym3_eigvec(M, False)
            assert min(np.linalg.norm(v - Vt[2]), np.linalg.norm(v + Vt[2])) < 1e-9
        Y = X[:, :2]
        sy, Vy = np.linalg.svd(Y, full_matrices=False)[1:]
        if sy[0] - sy[1] > 1e-6 * sy[0]:
            v = np.array(sym2_major(Y[:, 0] @ Y[:, 0], Y[:, 0] @ Y[:, 1], Y[:, 1] @ Y[:, 1]))
            assert min(np.linalg.norm(v - Vy[0]), np.linalg.norm(v + Vy[0])) < 1e-9
    # exact cases: a diagonal matrix, and repeated eigenvalues with a unique extreme one
    assert np.allclose(np.abs(sym3_eigvec(np.diag([1.0, 3.0, 2.0]), True)), [0, 1, 0])
    assert np.allclose(np.abs(sym3_eigvec(np.diag([1.0, 3.0, 2.0]), False)), [1, 0, 0])
    assert np.allclose(np.abs(sym3_eigvec(np.diag([5.0, 1.0, 1.0]), True)), [1, 0, 0])
