"""Fixtures for the link tests: a fast arm, obstacles on a known sweep, emulators on port 0."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from assistant.collision import Obstacle
from assistant.robot_model import CollisionShape, ShapeKind, Tool
from assistant.rv2aj import RV2AJ, RV2AJConfig
from assistant.transforms import make_T

#: The RV-2AJ with a gripper and ten times its datasheet speeds: motions in tests take
#: tens of milliseconds while every code path (timing, streaming, collisions) stays real.
FAST_SPEEDS = tuple(10.0 * v for v in (180.0, 90.0, 135.0, 180.0, 210.0))

#: An exploration sweep: the stretched arm turns about J1 from -45 to +60 degrees.
Q_A = np.radians([-45.0, 45.0, 45.0, 30.0, 0.0])
Q_B = np.radians([60.0, 45.0, 45.0, 30.0, 0.0])
HOME = np.radians([0.0, 10.0, 60.0, 20.0, 0.0])


@pytest.fixture(scope="session")
def fast_robot() -> RV2AJ:
    return RV2AJ(RV2AJConfig(speeds_deg_s=FAST_SPEEDS, tool=Tool.straight(0.1)))


def box_on_sweep(robot: RV2AJ, qa: np.ndarray, qb: np.ndarray, frac: float,
                 size: float = 0.06, name: str = "hidden") -> Obstacle:
    """A box centred on the TCP at `frac` of the straight joint motion qa -> qb."""
    q = qa + frac * (qb - qa)
    return Obstacle(name, make_T(p=robot.fk(q)[:3, 3]),
                    (CollisionShape(ShapeKind.BOX, (size, size, size)),))


def sweep(qa: np.ndarray, qb: np.ndarray, n: int = 5) -> np.ndarray:
    return qa + np.linspace(0.0, 1.0, n)[:, None] * (qb - qa)


@pytest.fixture
def closing() -> Iterator[Callable]:
    """Register things with close() (emulators, links); all are closed at teardown."""
    items: list = []

    def add(obj):
        items.append(obj)
        return obj

    yield add
    for obj in reversed(items):
        with contextlib.suppress(Exception):  # teardown must close the rest
            obj.close()
