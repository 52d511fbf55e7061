"""Fixtures for the link tests: a fast arm and a closer for emulators and links."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

import pytest
from link_fixtures import FAST_SPEEDS

from assistant.robots.model import Tool
from assistant.robots.rv2aj import RV2AJ, RV2AJConfig


@pytest.fixture(scope="session")
def fast_robot() -> RV2AJ:
    return RV2AJ(RV2AJConfig(speeds_deg_s=FAST_SPEEDS, tool=Tool.straight(0.1)))


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
