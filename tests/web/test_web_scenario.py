"""The thesis scenario from an empty page, through the real `cellteach serve`: import O1/O2,
place them by numbers, teach P1/P10 by numbers and P7/P8 by pointer dwell (synthetic camera),
add the seam, build the world, plan, execute - the simulated robot meets the hidden O3, the
collisions are recorded and the mission re-planned - export MELFA and download it. The
download must equal, byte for byte, what `cellteach run` makes of the sample's scripted
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
from web_ui import UI

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "sample_cells" / "thesis_rv2aj"
SCRIPT = SAMPLE / "session.yaml"
#: Planning and execution with eight collision indications take minutes on a loaded machine.
LONG_MS = 600_000

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
    ui.step("1")
    ui.shot("1-setup")
    ui.click("Next")
    ui.step("2")
    # 2. CAD: the table as a simple box, O1 and O2 from DXF in millimetres.
    ui.expand("Add a simple shape", ui.button("Add shape"))
    ui.fill_vec("Size (mm)", (1200, 1200, 20))
    ui.fill_vec("Centre at (mm)", (0, 0, -10))
    ui.choose("Shape role", "fixture")
    ui.fill("Name", "table")
    ui.click("Add shape")
    ui.wait_cell("table")
    ui.choose("Units", "mm")
    for part in ("O1", "O2"):
        ui.upload("Upload CAD file", SAMPLE / "dxf" / f"{part}.dxf")
        ui.wait_text(f"Imported {part}")
    ui.shot("2-cad")
    ui.click("Next")
    ui.step("3.1")
    # 3. Place by numbers.
    # Imported parts wait behind the robot, side by side, until placed (`web.panels.cad`).
    for part, y, waiting in (("O1", -200, "(-450, -150, 0)"), ("O2", 200, "(-450, 150, 0)")):
        ui.choose("Part", part)
        ui.wait_text(f"{part} is at {waiting} mm")  # the fields now show this part
        ui.fill_vec("Position (mm)", (220, y, 0))
        ui.click("Place part")
        ui.wait_text(f"{part} is at (220, {y}, 0) mm")
    ui.shot("3-placed")
    ui.click("Next")
    ui.step("3.2")
    ui.click("Next")
    ui.step("4.1")
    # 4.1 Teach: P1 and P10 by numbers, P7 and P8 by pointer dwell.
    ui.expand("From the robot or by numbers", ui.button("Teach this pose"))
    for name, y in (("P1", -340), ("P10", 340)):
        ui.fill("Name", name)
        ui.fill_vec("Position (mm)", (80, y, 200))
        ui.fill_vec("A, B, C (deg)", (0, 0, 180))  # as the script: tool down
        ui.click("Teach this pose")
        ui.wait_cell(name)
    # The synthetic camera's noise seed follows the name (P7: 7, P8: 8), as in the script.
    for name, y in (("P7", -70), ("P8", 70)):
        ui.fill("Name", name)
        ui.fill_vec("Point (mm)", (340, y, 60))
        ui.click("Teach by pointer dwell")
        ui.wait_cell(name)
    ui.choose("Location", "P1")
    ui.click("Make it the start")
    ui.wait_cell("start")
    ui.choose("Location", "P10")
    ui.click("Make it the goal")
    ui.wait_cell("goal")
    ui.shot("4-taught")
    ui.click("Next")
    ui.step("4.2")
    ui.fill("Path name", "SEAM")
    ui.fill("Through", "P7, P8")
    ui.click("Add path")
    ui.wait_cell("SEAM")
    ui.shot("4-paths")
    ui.click("Next")
    ui.step("5")
    # 5. World model with progress; 6. plan, execute (O3 is met), re-plan.
    ui.click("Build world model")
    ui.wait_text("World model ready", timeout=LONG_MS)
    ui.shot("5-world")
    ui.click("Next")
    ui.step("6")
    ui.click("Plan")
    ui.wait_enabled("Execute on the robot", timeout=LONG_MS)
    ui.shot("6-planned")
    ui.click("Execute on the robot")
    ui.wait_text("The robot is moving")
    ui.wait_text(re.compile(r"Collision #\d+ recorded"), timeout=LONG_MS)
    ui.shot("6-collision")
    ui.wait_enabled("Next", timeout=LONG_MS)
    ui.wait_text("Goal reached: the robot is at P10")  # said once, in the operator's words
    ui.shot("6-executed")
    moves = re.search(r"Mission planned: (\d+) moves", ui.page.inner_text("body"))
    assert moves is not None
    assert not ui.errors(), ui.errors()  # the execution ended with a verified plan
    ui.click("Next")
    ui.step("7")
    ui.choose("Robot language", "Mitsubishi MELFA BASIC IV")
    ui.click("Write program")
    ui.wait_enabled("Download", timeout=LONG_MS)
    ui.wait_text(".MB4")
    ui.shot("7-export")
    name, data = ui.download("Download")
    assert name.endswith(".zip")
    (tmp_path / name).write_bytes(data)
    # The headless twin: the same actions through `cellteach run`.
    ref = run_reference(ref_out)
    assert ref.returncode == 0, ref.stderr
    # The page counts the moves as report.json does (one source for every count).
    report = json.loads((ref_out / "report.json").read_text())
    assert int(moves.group(1)) == sum(report["primitives"].values())
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
