"""Angles from the transforms module are well conditioned where arccos is not: near 0 and pi
one rounding of a dot product becomes ~1.5e-8 rad through arccos; atan2(|a x b|, a . b) keeps
the angle to a few units in the last place (the reason `angle_between` and
`rotation_angle` use it; results then agree across processors)."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.transforms import angle_between, rot_z, rotation_angle

#: atan2 of exactly rounded |a x b| and a . b: relative error a few ulp (~1e-15); 1e-12
#: leaves room for any libm, while arccos's 1.5e-8 absolute error at 1e-9 rad is 15x the angle.
REL = 1e-12


@pytest.mark.parametrize("t", [1e-12, 1e-9, 1e-6, 0.3, np.pi / 2, np.pi - 1e-7])
def test_angle_between_is_exact_near_parallel_and_antiparallel(t):
    a = np.array([1.0, 0.0, 0.0])
    b = 2.5 * np.array([np.cos(t), np.sin(t), 0.0])  # any length
    want = t if t < 1.0 else np.pi - np.arctan2(np.sin(t), -np.cos(t))
    assert angle_between(a, b) == pytest.approx(want, rel=REL)


@pytest.mark.parametrize("t", [1e-9, 0.3, np.pi - 1e-7])
def test_angle_between_plane_vectors(t):
    a, b = np.array([2.0, 0.0]), np.array([np.cos(t), np.sin(t)])
    assert angle_between(a, b) == pytest.approx(t, rel=REL)


@pytest.mark.parametrize("t", [1e-10, 1e-7, 0.5, 3.0])
def test_rotation_angle_of_a_small_and_a_large_turn(t):
    assert rotation_angle(rot_z(t)) == pytest.approx(t, rel=REL)
