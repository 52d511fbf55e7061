"""`CollisionChecker`: the exact checker (`exact_checker.ExactChecker`, python-fcl) with the
fast conservative model in front of it (`fast_checker.FastChecker`, built on first use).

The two share the exact checker's code: the fast model is an `ExactChecker` of the capsule
robot, and this class is the one that knows both (so neither imports the other).
"""

from __future__ import annotations

from assistant.collision.exact_checker import ExactChecker
from assistant.collision.fast_checker import FastChecker
from assistant.collision.fast_model import fast_robot


class CollisionChecker(ExactChecker):
    """The checker every planner, the world model and the session use (`ExactChecker`)."""

    @property
    def fast(self) -> ExactChecker | None:
        """The fast conservative model of this checker's robot and obstacles
        (`fast_checker.FastChecker`), built on first use; None for a robot it cannot pose."""
        if not self._use_fast:
            return None
        if self._fast_model is False:
            robot = fast_robot(self.robot)
            self._fast_model = None if robot is None else FastChecker(self, robot)
        return self._fast_model  # type: ignore[return-value]
