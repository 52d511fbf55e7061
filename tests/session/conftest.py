"""Session fixtures: sessions on the thesis sample cell, with and without its content."""

from __future__ import annotations

from pathlib import Path

import pytest

from assistant.session import Session

SAMPLES = Path(__file__).resolve().parents[2] / "sample_cells"


@pytest.fixture
def empty_session(tmp_path) -> Session:
    """Robot, link and hidden O3 of the thesis cell; no objects, no mission; autosaved."""
    return Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                               with_mission=False)


@pytest.fixture
def o1_dxf() -> bytes:
    return (SAMPLES / "thesis_rv2aj" / "dxf" / "O1.dxf").read_bytes()
