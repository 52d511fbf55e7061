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


class MarginValidity(ValidityChecker, Protocol):
    """A checker that can also certify small moves without an exact check (optional).

    `is_valid_batch_margin(Q, certified)` answers like `is_valid_batch` and gives each valid
    row a margin: a move to q' with `travel(q, q') < margin` stays free of collision, so a
    caller may pass such rows as `certified` next time and only the cheap tests run.
    """

    def is_valid_batch_margin(self, Q: Array, certified: Array | None = None,
                              ) -> tuple[Array, Array]:
        """(valid (N,) bool, margin (N,) metres; NaN for invalid or certified rows)."""

    def travel(self, Q0: Array, Q1: Array) -> Array:
        """Upper bound on how far any point of the arm moves between rows of Q0 and Q1."""
