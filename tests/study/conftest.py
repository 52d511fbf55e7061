"""Fixtures of the placement-study tests: the thesis cell's study problem, built once."""

from __future__ import annotations

import pytest

from assistant.session import Session
from assistant.study import StudyProblem


@pytest.fixture(scope="session")
def thesis_session() -> Session:
    s = Session.from_sample("thesis_rv2aj", None)
    yield s
    s.close()


@pytest.fixture(scope="session")
def thesis_problem(thesis_session: Session) -> StudyProblem:
    """The thesis cell (RV-2AJ at the origin, O1/O2, P1 -> SEAM (P7 to P8) -> P10) as a study."""
    return thesis_session.study_problem()
