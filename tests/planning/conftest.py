"""The thesis scenario and its RV-2AJ, loaded once per test module (every planning test that
plans the thesis mission starts from them)."""

from __future__ import annotations

import pytest

from assistant.planning import load_scenario


@pytest.fixture(scope="module")
def scenario():
    return load_scenario()


@pytest.fixture(scope="module")
def robot(scenario):
    return scenario.cell.robot()
