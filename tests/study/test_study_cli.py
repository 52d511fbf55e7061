"""`cellteach study placement` headless: study.json with every candidate ranked or with its
reason, and a PNG map; bad input is one line and exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "sample_cells" / "thesis_rv2aj" / "session.yaml"


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "assistant", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=240)


def test_cli_writes_study_json_and_a_map(tmp_path):
    """The thesis sample cell: 2 x 1 positions x 2 yaws, the best screened candidate and the
    cell's own placement planned in two worker processes."""
    out = tmp_path / "study"
    r = _cli("study", "placement", "thesis_rv2aj", "--region=0,0,100,0", "--step", "100",
             "--yaw-steps", "2", "--plan-top", "1", "--workers", "2", "--out", str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "study.json").read_text())
    assert doc["counts"]["candidates"] == 4 and doc["engine"] == "local"
    assert doc["subject"] == "the robot base"
    cands = doc["candidates"]
    assert len(cands) == 4
    assert cands[0]["rank"] == 1 and cands[0]["status"] == "planned"
    assert cands[0]["tcp_path_length_mm"] > 300 and cands[0]["min_clearance_mm"] is not None
    failed = [c for c in cands if c["status"] == "failed"]
    assert failed and all(c["reason"] for c in failed)
    assert doc["current"]["status"] == "planned"  # the script's own placement, to compare
    img = cv2.imread(str(out / "placement.png"))
    assert img is not None and img.shape[0] > 200 and img.shape[1] > 200
    # the planned candidate is drawn green, the failures grey
    green = (img[..., 1] > 150) & (img[..., 2] < 120) & (img[..., 0] < 120)
    grey = np.all(np.abs(img.astype(int) - 170) <= 2, axis=2)
    assert green.sum() > 20 and grey.sum() > 20


def test_cli_bad_region_is_one_line(tmp_path):
    r = _cli("study", "placement", "thesis_rv2aj", "--region", "0,0,100", "--step", "50",
             "--out", str(tmp_path))
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "X0,Y0,X1,Y1" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.slow
def test_cli_studies_a_session_script(tmp_path):
    """A session script runs up to its first build_world, then the study (nothing planned:
    --plan-top 0 and the current placement still is)."""
    out = tmp_path / "study"
    r = _cli("study", "placement", str(SCRIPT), "--region=-100,0,100,0", "--step", "100",
             "--plan-top", "0", "--inline", "--out", str(out))
    assert r.returncode == 1, r.stderr  # nothing of the region planned: says so
    doc = json.loads((out / "study.json").read_text())
    assert doc["current"]["status"] == "planned"
    names = " ".join(c["reason"] for c in doc["candidates"])
    assert "P7" in names or "P8" in names or "P1" in names or "not planned" in names
