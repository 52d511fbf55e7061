"""The UR5 and UR10 sample cells' programs in FANUC TP and Yaskawa INFORM, made by `cellteach
run` as a user would, kept as golden files with the plan they were written from.

For each cell and dialect: the sample folder is copied to a scratch folder, its script's
`export` action becomes `export: {dialect: D}`, ``python -m assistant run session.yaml --out
OUT`` runs it, and the program files it wrote go to ``tests/export/golden/D/CELL/`` with
``plan.json``: every position of the planned program (names as the dialect writes them) with
its planned joints (rad) and TCP pose in the robot base (m), from the session the run saved.
test_export_cell_golden.py reads the files back through the independent grammars and the
kinematics against that plan. A run takes about two minutes; review the diff like code.

    python tests/export/make_cell_golden.py [--cells ur5_cell ur10_cell] [--dialects fanuc yaskawa]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).resolve().parent / "golden"
CELLS = ("ur5_cell", "ur10_cell")
DIALECTS = ("fanuc", "yaskawa")


def run_cell(cell: str, dialect: str, scratch: Path) -> Path:
    """`cellteach run` on the cell's script with the export in `dialect`; the output folder."""
    src = ROOT / "sample_cells" / cell
    work = scratch / f"{cell}_{dialect}"
    shutil.copytree(src, work)
    script = work / "session.yaml"
    text, n = re.subn(r"^(\s*-\s*export:\s*)\{dialect:\s*\w+\}", rf"\1{{dialect: {dialect}}}",
                      script.read_text(encoding="utf-8"), flags=re.M)
    if n != 1:
        raise SystemExit(f"{cell}: expected one export action in session.yaml")
    script.write_text(text, encoding="utf-8")
    out = work / "out"
    proc = subprocess.run([sys.executable, "-m", "assistant", "run", str(script), "--out",
                           str(out)], cwd=work, capture_output=True, text=True,
                          env={"PYTHONPATH": str(ROOT), **_env()})
    if proc.returncode != 0:
        raise SystemExit(f"{cell} {dialect}: exit {proc.returncode}: {proc.stderr.strip()}")
    return out


def _env() -> dict[str, str]:
    import os

    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    return env


def plan_of(out: Path, dialect: str) -> dict:
    """The planned positions of the run's session, named as the dialect writes them."""
    sys.path.insert(0, str(ROOT))
    from assistant.export import get_dialect, program_from_trajectory
    from assistant.export.names import legal_for
    from assistant.session import Session

    s = Session.load(out / "session", autosave=False)
    program, _ = legal_for(program_from_trajectory(s.trajectory, s.robot, name="MISSION"),
                           get_dialect(dialect))
    return {"cell": s.sample, "robot": s.robot.name, "dialect": dialect,
            "note": "written by tests/export/make_cell_golden.py from the session `cellteach "
                    "run` saved: each position's planned joints (rad) and TCP pose in the "
                    "robot base (m)",
            "positions": [{"name": p.name, "joint_target": p.joint_target,
                           "q": [round(float(v), 12) for v in p.q],
                           "T_base_tool": [[round(float(v), 12) for v in row]
                                           for row in p.T_base_tool]}
                          for p in program.positions()]}


def plan_text(plan: dict) -> str:
    """plan.json with one line per position (reviewable in a diff)."""
    head = {k: v for k, v in plan.items() if k != "positions"}
    rows = ",\n".join("  " + json.dumps(p) for p in plan["positions"])
    return json.dumps(head, indent=1)[:-2] + ',\n "positions": [\n' + rows + "\n ]\n}\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", nargs="*", default=list(CELLS))
    ap.add_argument("--dialects", nargs="*", default=list(DIALECTS))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for cell in args.cells:
            for dialect in args.dialects:
                out = run_cell(cell, dialect, Path(tmp))
                report = json.loads((out / "report.json").read_text(encoding="utf-8"))
                folder = GOLDEN / dialect / cell
                if folder.exists():
                    shutil.rmtree(folder)
                folder.mkdir(parents=True)
                for name in report["program_files"]:
                    shutil.copyfile(out / name, folder / name)
                plan = plan_of(out, dialect) | {"renames": report.get("renames", [])}
                (folder / "plan.json").write_text(plan_text(plan), encoding="utf-8")
                print(f"{cell} {dialect}: {', '.join(report['program_files'])}, "
                      f"{report['primitives']}, wall {report['wall_time_s']} s")


if __name__ == "__main__":
    main()
