"""The only view of the world a planner gets (as in OMPL): is a configuration valid, is a motion.

FCL against the cell (`collision.CollisionChecker`), the octree world model, a test double and
the OMPL benchmark all speak this protocol, so planners never touch geometry.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

Array = np.ndarray


class ValidityChecker(Protocol):
    def is_valid(self, q: Array) -> bool:
        """Inside joint limits and free of collision."""

    def is_valid_batch(self, Q: Array) -> Array:
        """`is_valid` for each row of Q, shape (N,) bool."""

    def first_invalid_fraction(self, q0: Array, q1: Array) -> float | None:
        """Fraction in [0, 1] of the straight joint-space motion q0 -> q1 where it first
        becomes invalid, or None when the whole motion is valid."""
