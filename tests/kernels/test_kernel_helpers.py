"""Small compiled helpers against the numpy/Python expressions they stand in for."""

from __future__ import annotations

import numpy as np
from numba import njit

from assistant.kernels.helpers import axis_angle3_into, wrap_pi


@njit(cache=False)
def _wrap_all(a: np.ndarray) -> np.ndarray:
    out = np.empty_like(a)
    for i in range(a.shape[0]):
        out[i] = wrap_pi(a[i])
    return out


@njit(cache=False)
def _modulo_all(a: np.ndarray) -> np.ndarray:
    out = np.empty_like(a)
    for i in range(a.shape[0]):
        out[i] = (a[i] + np.pi) % (2.0 * np.pi) - np.pi
    return out


def test_wrap_pi_is_the_modulo_to_the_bit():
    """The fast path (a + pi already in [0, 2 pi)) and the modulo give the same bits, at
    the interval's ends, for zeros of either sign, far values, infinities and NaN."""
    rng = np.random.default_rng(2)
    edges = [np.pi, -np.pi, np.nextafter(np.pi, 0), np.nextafter(-np.pi, 0), 3 * np.pi,
             np.nextafter(np.pi, 4), -3 * np.pi, 0.0, -0.0, 1e-300, -1e-300, 1e300,
             np.inf, -np.inf, np.nan]
    a = np.concatenate([rng.uniform(-4, 4, 200_000), rng.uniform(-1e4, 1e4, 20_000),
                        edges])
    got, want = _wrap_all(a), _modulo_all(a)
    # Exact on any machine: only additions, subtractions and a float modulo (fmod is exact),
    # each correctly rounded in IEEE arithmetic - no product an FMA could contract.
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    # numpy's own float modulo agrees (the Python semantics both follow)
    with np.errstate(invalid="ignore"):
        ref = (a + np.pi) % (2.0 * np.pi) - np.pi
    assert np.array_equal(got.view(np.int64), ref.view(np.int64))


def _rodrigues(axis: np.ndarray, norm: float, angle: float) -> np.ndarray:
    """I + sin K + (1 - cos) K K in Python floats, the products summed left to right."""
    if norm < 1e-15:
        return np.eye(3)
    k0, k1, k2 = (float(v) / norm for v in axis)
    K = [[0.0, -k2, k1], [k2, 0.0, -k0], [-k1, k0, 0.0]]
    s, t = float(np.sin(angle)), 1.0 - float(np.cos(angle))
    return np.array([[((1.0 if r == c else 0.0) + s * K[r][c])
                      + t * (K[r][0] * K[0][c] + K[r][1] * K[1][c] + K[r][2] * K[2][c])
                      for c in range(3)] for r in range(3)])


def test_axis_angle3_is_rodrigues_within_rounding():
    """`axis_angle3_into` against the formula in Python
    floats: random axes (not unit), a zero axis and one below the identity's threshold."""
    rng = np.random.default_rng(3)
    K, KK, out = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for axis in [*rng.normal(size=(200, 3)), np.zeros(3), np.full(3, 1e-17)]:
        norm = float(np.linalg.norm(axis))
        angle = float(rng.uniform(-4, 4))
        want = _rodrigues(axis, norm, angle)
        axis_angle3_into(axis, norm, angle, K, KK, out)
        # 1e-15: entries |.| <= 3 from sums of 2-3 products; FMA contraction (or its absence)
        # changes each by at most a few ULPs of 1
        np.testing.assert_allclose(out, want, rtol=0, atol=1e-15)
