"""The score of a candidate: a cost, lower is better, in seconds-like units of the cycle.

    cost = cycle * (1 + clearance_weight * shortfall / required)

`cycle` is the predicted cycle time when a `cycle_time` callable is given (the program
issue's prediction, `cycle_time(robot, trajectory) -> s`), else the TCP path length in metres
(a stand-in that ranks the same way for similar speeds). The shortfall is how far the plan's
minimum clearance falls below what the study asks (0 when met): a placement that keeps it is
ranked by its cycle alone. The margin to the joint limits is a requirement (the screen refuses
a location without it), not a weight.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: cycle_time(robot, trajectory) -> seconds; must be a module-level function (it is pickled
#: to the worker processes).
CycleTime = Callable[[Any, Any], float]


@dataclass(frozen=True)
class Scoring:
    clearance_weight: float = 1.0
    cycle_time: CycleTime | None = None

    @property
    def unit(self) -> str:
        return "s" if self.cycle_time is not None else "m"

    def cycle(self, robot: Any, trajectory: Any, tcp_length: float) -> float:
        if self.cycle_time is not None and trajectory is not None:
            return float(self.cycle_time(robot, trajectory))
        return float(tcp_length)

    def cost(self, cycle: float, clearance: float | None, required_clearance: float) -> float:
        pen = 0.0
        if required_clearance > 0 and clearance is not None:
            pen = self.clearance_weight * max(0.0, required_clearance - clearance) / \
                required_clearance
        return float(cycle) * (1.0 + pen)
