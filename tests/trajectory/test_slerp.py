"""Orientation interpolation of LINEAR/CIRCULAR moves: the same rotations as scipy's Slerp."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from assistant.trajectory.cartesian_follow import slerp_rotations


def test_slerp_rotations_equal_scipy_slerp() -> None:
    rng = np.random.default_rng(7)
    u = np.r_[-0.1, np.linspace(0.0, 1.0, 17), 1.2]  # fractions outside [0, 1] are clipped
    pairs = [tuple(Rotation.random(2, random_state=int(s)).as_matrix())
             for s in rng.integers(0, 2**31, 100)]
    R = Rotation.random(random_state=1)
    pairs += [(R.as_matrix(), R.as_matrix()),  # no turn
              (R.as_matrix(), (R * Rotation.from_rotvec([1e-9, 0.0, 0.0])).as_matrix()),
              (R.as_matrix(), (R * Rotation.from_rotvec([0.0, 3.1, 0.0])).as_matrix())]
    for R0, R1 in pairs:
        ref = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([R0, R1])))(np.clip(u, 0, 1))
        assert np.allclose(slerp_rotations(R0, R1, u), ref.as_matrix(), atol=1e-12)
