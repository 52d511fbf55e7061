"""Shared values for the link tests: a fast arm's speeds, postures, obstacles on a sweep."""

from __future__ import annotations

import numpy as np

from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.robots.rv2aj import RV2AJ
from assistant.transforms import make_T

#: The RV-2AJ with a gripper and ten times its datasheet speeds: motions in tests take
#: tens of milliseconds while every code path (timing, streaming, collisions) stays real.
FAST_SPEEDS = tuple(10.0 * v for v in (180.0, 90.0, 135.0, 180.0, 210.0))

#: An exploration sweep: the stretched arm turns about J1 from -45 to +60 degrees.
Q_A = np.radians([-45.0, 45.0, 45.0, 30.0, 0.0])
Q_B = np.radians([60.0, 45.0, 45.0, 30.0, 0.0])
HOME = np.radians([0.0, 10.0, 60.0, 20.0, 0.0])


def box_on_sweep(robot: RV2AJ, qa: np.ndarray, qb: np.ndarray, frac: float,
                 size: float = 0.06, name: str = "hidden") -> Obstacle:
    """A box centred on the TCP at `frac` of the straight joint motion qa -> qb."""
    q = qa + frac * (qb - qa)
    return Obstacle(name, make_T(p=robot.fk(q)[:3, 3]),
                    (CollisionShape(ShapeKind.BOX, (size, size, size)),))


def sweep(qa: np.ndarray, qb: np.ndarray, n: int = 5) -> np.ndarray:
    return qa + np.linspace(0.0, 1.0, n)[:, None] * (qb - qa)
