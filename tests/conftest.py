"""Shared fixtures. Browser tests live in tests/web and have their own conftest."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from assistant.robots.model import Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
from assistant.warmup.steps import warm_up


@pytest.fixture(scope="session", autouse=True)
def _compiled_kernels() -> None:
    """Compile (or load) the numba kernels once before any test. On a clean checkout the
    first call would otherwise compile inside whatever test comes first - for the link
    tests inside an emulator's request handler, where the seconds it takes look like a
    lost link. The second worker of the parallel run warms up last step first: on a cold
    cache the two compile different kernels and load each other's (half the wait)."""
    warm_up(reverse=os.environ.get("PYTEST_XDIST_WORKER") == "gw1")


@pytest.fixture(scope="session")
def rv2aj() -> RV2AJ:
    """The RV-2AJ with a 100 mm straight gripper, as in the sample cells."""
    return RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


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
