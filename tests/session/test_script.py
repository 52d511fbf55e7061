"""Scripted sessions: malformed scripts fail before running, with a line number and reason."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from assistant.session.script import ScriptError, parse_script

SAMPLE = Path(__file__).resolve().parents[2] / "sample_cells" / "thesis_rv2aj"


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.yaml"
    p.write_text(textwrap.dedent(text))
    return p


@pytest.mark.parametrize("text,line,match", [
    ("actions:\n  - next\n  - fly_away\n", 3, "unknown action 'fly_away'"),
    ("actions:\n  - teach: {name: P1}\n", 2, "teach needs pose"),
    ("actions:\n  - plan\n  - place: {object: O1, pose: [1,2,3,4,5,6], speed: 3}\n", 3,
     "place does not take speed"),
    ("actions:\n  - next\n  - teach: {name: P1, pose: [1, 2\n", 3, "not valid YAML"),
    ("cell: thesis_rv2aj\nsteps:\n  - next\n", 2, "unknown key 'steps'"),
    ("actions: plan\n", 1, "'actions' must be a list"),
    ("actions:\n  - {next: 1, plan: 2}\n", 2, "one-key mapping"),
])
def test_malformed_scripts_name_the_line_and_the_reason(tmp_path, text, line, match):
    with pytest.raises(ScriptError, match=match) as info:
        parse_script(write(tmp_path, text))
    assert f"s.yaml:{line}:" in str(info.value)


def test_scalar_shorthand_and_defaults(tmp_path):
    s = parse_script(write(tmp_path, """
        cell: thesis_rv2aj
        actions:
          - set_start: P1
          - export: krl
          - plan
    """))
    assert s.cell == "thesis_rv2aj" and not s.with_objects
    assert [(a.verb, a.args) for a in s.actions] == [
        ("set_start", {"name": "P1"}), ("export", {"dialect": "krl"}), ("plan", {})]
    assert [a.line for a in s.actions] == [4, 5, 6]


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "assistant", *args], capture_output=True,
                          text=True, timeout=300)


def test_cli_reports_a_failing_action_in_one_line_and_writes_the_report(tmp_path):
    script = write(tmp_path, f"""
        cell: {SAMPLE}
        actions:
          - next
          - import_cad: {{file: {SAMPLE}/dxf/O1.dxf, name: O1, units: mm}}
          - next
          - goto: teach.locations
          - teach: {{name: FAR, pose: [900, 0, 200, 0, 0, 180]}}
    """)
    out = tmp_path / "out"
    r = run_cli("run", str(script), "--out", str(out))
    assert r.returncode == 1
    last = r.stderr.strip().splitlines()[-1]
    assert "s.yaml:8: teach failed" in last and "reach" in last
    report = json.loads((out / "report.json").read_text())
    assert report["ok"] is False and "reach" in report["error"]
    assert report["operator_actions"] == 4  # next, import, next, goto


def test_cli_refuses_a_malformed_script_with_exit_code_2(tmp_path):
    r = run_cli("run", str(write(tmp_path, "actions:\n  - launch\n")), "--out",
                str(tmp_path / "o"))
    assert r.returncode == 2
    assert "s.yaml:2: unknown action 'launch'" in r.stderr


def test_cli_lists_the_sample_cells():
    r = run_cli("cells")
    assert r.returncode == 0
    assert "thesis_rv2aj" in r.stdout


def test_import_cad_of_a_device_or_a_pipe_is_one_clear_line(tmp_path):
    """Issue 54: /dev/zero grew the process to 3.2 GB and ended in an empty MemoryError;
    a FIFO would hang the run. Both are refused by what they are, in the run's one line."""
    import os

    os.mkfifo(tmp_path / "pipe.stl")
    for target, what in (("/dev/zero", "character device"),
                         (str(tmp_path / "pipe.stl"), "named pipe (FIFO)")):
        script = write(tmp_path, f"""
            cell: {SAMPLE}
            actions:
              - next
              - import_cad: {{file: {target}, name: part}}
        """)
        out = tmp_path / "out"
        r = run_cli("run", str(script), "--out", str(out))
        assert r.returncode == 1
        last = r.stderr.strip().splitlines()[-1]
        assert "s.yaml:5: import_cad failed" in last and what in last, last
        assert "MemoryError" not in r.stderr and "Traceback" not in r.stderr


def test_a_script_that_is_a_device_is_refused(tmp_path):
    with pytest.raises(ScriptError, match="/dev/zero is a character device, not a script"):
        parse_script("/dev/zero")
