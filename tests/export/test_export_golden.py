"""Golden files: the exact text each dialect writes for the thesis scenario and two drawings
(screen 9: lines and a free curve as a spline; frame 1: lines and arcs as LIN and CIRC).

They encode what a hand-written program looks like and were reviewed line by line before
they were committed. Regenerate after an intended change with

    CELLTEACH_UPDATE_GOLDEN=1 pytest tests/export/test_export_golden.py

and review the diff like code.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from assistant.export import get_dialect
from assistant.export.dialect import ProgramFile
from assistant.export.simulate import max_deviation, simulate

GOLDEN = Path(__file__).parent / "golden"
ALL = ("melfa", "krl", "rapid", "urscript")
UPDATE = os.environ.get("CELLTEACH_UPDATE_GOLDEN") == "1"


@pytest.fixture
def scenario_program(request, thesis_program, drawing_program, frame_program):
    return {"thesis": thesis_program, "drawing": drawing_program,
            "frame": frame_program}[request.param]


@pytest.mark.parametrize("scenario_program", ["thesis", "drawing", "frame"], indirect=True)
@pytest.mark.parametrize("dialect", ALL)
def test_written_program_matches_golden(rv2aj, scenario_program, dialect, request):
    scenario = request.node.callspec.params["scenario_program"]
    folder = GOLDEN / dialect / scenario
    files = get_dialect(dialect).write(scenario_program, rv2aj)
    if UPDATE:
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.iterdir():
            old.unlink()
        for f in files:
            (folder / f.name).write_text(f.text, encoding="ascii")
    expected = sorted(p.name for p in folder.iterdir()) if folder.exists() else []
    assert sorted(f.name for f in files) == expected, "run with CELLTEACH_UPDATE_GOLDEN=1"
    for f in files:
        assert f.text == (folder / f.name).read_text(encoding="ascii"), f.name


@pytest.mark.parametrize("scenario_program", ["thesis", "drawing", "frame"], indirect=True)
@pytest.mark.parametrize("dialect", ALL)
def test_golden_files_read_back_to_the_planned_path(rv2aj, scenario_program, dialect, request):
    """The committed text itself (not a fresh write) drives the planned TCP path."""
    scenario = request.node.callspec.params["scenario_program"]
    folder = GOLDEN / dialect / scenario
    d = get_dialect(dialect)
    files = [ProgramFile(p.name, p.read_text(encoding="ascii")) for p in sorted(folder.iterdir())]
    back = d.read(files, rv2aj)
    ref = simulate(d.lower(scenario_program), rv2aj, scenario_program.q_start, max_step=0.005)
    got = simulate(back, rv2aj, scenario_program.q_start, samples=ref.sample_counts())
    assert max_deviation(ref, got) < 2e-5
