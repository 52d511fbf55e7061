"""The thesis scenario from an empty page, through the real `cellteach serve`, as an operator
would do it (`thesis_page`): the work table, the cell-layout DXF (O1, O2 where drawn, start P1
and goal P10 labelled), P7/P8 by pointer dwell (synthetic camera), the seam, the world, the
plan, the run - the simulated robot halts at the hidden O3 and the operator presses Collision!
each time, the mission is re-planned - and the MELFA program downloaded, in at most 20 actions.
The download must equal, byte for byte, what `cellteach run` makes of the sample's scripted
session (sample_cells/thesis_rv2aj/session.yaml: the same actions, headless)."""

from __future__ import annotations

import io
import json
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from thesis_page import LONG_MS, run_thesis_scenario
from web_ui import UI

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "sample_cells" / "thesis_rv2aj"
SCRIPT = SAMPLE / "session.yaml"

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.timeout(1200)]


@pytest.fixture
def cellteach_serve(tmp_path: Path):
    """`cellteach serve` on the empty thesis cell (robot, link, hidden O3 only)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "assistant", "serve", "--cell", "thesis_rv2aj", "--empty",
         "--session", str(tmp_path / "served-session"), "--port", "0"],
        cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    url = None
    assert proc.stderr is not None
    for line in proc.stderr:
        m = re.search(r"at (http://127\.0\.0\.1:\d+)", line)
        if m:
            url = m.group(1)
            break
    if url is None:
        proc.kill()
        pytest.fail("cellteach serve did not start: " + proc.stderr.read())
    yield url
    proc.terminate()
    proc.wait(10)


def run_reference(out: Path) -> subprocess.CompletedProcess:
    """The headless scripted session. Run after the page, not alongside it: the planner has
    wall-clock budgets, so two plans competing for two cores could end differently."""
    return subprocess.run([sys.executable, "-m", "assistant", "run", str(SCRIPT), "--out",
                           str(out)], cwd=ROOT, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, timeout=LONG_MS / 1000)


def documents(folder: Path) -> dict:
    """What the operator made: the cell, the taught locations and the mission."""
    doc = json.loads((folder / "session.json").read_text())
    cell = json.loads((folder / "cell" / "cell.json").read_text())
    return {"cell": cell["objects"], "locations": doc["locations"], "mission": doc["mission"]}


def test_thesis_scenario_in_the_browser_equals_the_script(cellteach_serve, open_ui, tmp_path):
    ref_out = tmp_path / "reference"
    ui: UI = open_ui(cellteach_serve)
    effort = run_thesis_scenario(ui, SAMPLE)
    # Issue 34's target: the scenario in at most 20 operator actions (by kind in the log).
    assert effort.total <= 20, effort.log
    assert effort.actions["key"] == 3  # Collision! pressed at each of the three halts
    assert not ui.errors(), ui.errors()  # the execution ended with a verified plan
    assert effort.download is not None
    name, data = effort.download
    assert name.endswith(".zip")
    (tmp_path / name).write_bytes(data)
    # The headless twin: the same actions through `cellteach run`.
    ref = run_reference(ref_out)
    assert ref.returncode == 0, ref.stderr
    # The page counts the moves as report.json does (one source for every count).
    report = json.loads((ref_out / "report.json").read_text())
    assert effort.moves_shown == sum(report["primitives"].values())
    # The predicted cycle time: the same total in the export panel (said to be a
    # prediction), report.json (the sum of its per-move times) and the program's header.
    total = report["predicted_cycle_time_s"]
    ui.wait_text(f"Predicted cycle time {total:.1f} s.")
    ui.wait_text("not measured on a controller")
    per_move = report["cycle_time"]["moves"]
    assert sum(m["seconds"] for m in per_move) == pytest.approx(total, abs=1e-3 * len(per_move))
    header = (ref_out / "MISSION.MB4").read_text("ascii")
    assert f"predicted cycle time {total:.1f} s" in header
    # Same cell, locations and mission (autosaved by the server after every action) ...
    assert documents(tmp_path / "served-session") == documents(ref_out / "session")
    # ... and the same program, byte for byte.
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        got = {n: z.read(n) for n in z.namelist()}
    expected = {p.name: p.read_bytes() for p in ref_out.iterdir()
                if p.suffix.upper() in (".MB4", ".POS")}
    assert sorted(got) == sorted(expected)
    for fname, content in expected.items():
        assert got[fname] == content, f"{fname} differs from the scripted session's"
