"""Independent readers (issue 35 item 4): every program we export - the golden files, fresh
exports of the samples in every file layout the writers have (the sample cells' programs:
tests/samples/test_sample_cells.py) - passes a grammar of the controller's documented
syntax plus a checker of what a grammar cannot say (tests/export/grammars). Hand-broken
programs are refused with a message naming the file and line. The readers share no code
with the writers: a test below reads their imports.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from grammars import CHECKERS, check_report, check_text

from assistant.export import (
    FanucDialect,
    KrlDialect,
    MelfaDialect,
    RapidDialect,
    YaskawaDialect,
    export_files,
    get_dialect,
    program_from_trajectory,
)
from assistant.export.program import Frame
from assistant.export.samples import drawing_trajectory, paper_frame
from assistant.trajectory.bezier_drawings import drawing

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
GOLDEN = HERE / "golden"
GRAMMARS = HERE / "grammars"
ALL = ("melfa", "krl", "rapid", "urscript", "fanuc", "yaskawa")
SCENARIOS = ("thesis", "drawing", "frame")
#: Fresh exports: URScript runs on the UR5, whose samples take ~15 s each to plan (the golden
#: URScript files, checked in the fast run, are the same text: test_export_golden).
FRESH = [pytest.param(d, marks=pytest.mark.slow) if d == "urscript" else d for d in ALL]


def golden(dialect: str, scenario: str) -> dict[str, str]:
    folder = GOLDEN / dialect / scenario
    return {p.name: p.read_text(encoding="ascii") for p in sorted(folder.iterdir())}


# ------------------------------------------------------------------ the readers stand alone
def test_the_readers_import_nothing_of_ours():
    """Independence is the point: no module of the readers imports the assistant."""
    for path in sorted(GRAMMARS.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for n in names:
                assert n.split(".")[0] in {"grammars", "lark", "__future__", "re", "math",
                                           "dataclasses", "functools", "pathlib"}, \
                    f"{path.name} imports {n}"
    assert sorted(p.stem for p in GRAMMARS.glob("*.lark")) == sorted(ALL)


def test_an_unknown_dialect_is_one_clear_error():
    with pytest.raises(ValueError, match="no reader for dialect 'gcode'"):
        check_text("gcode", {"a.nc": "G0 X1"})


# ------------------------------------------------------------------ golden files
@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("dialect", ALL)
def test_golden_programs_follow_the_documented_syntax(dialect, scenario):
    rep = check_report(dialect, golden(dialect, scenario))
    assert rep.problems == []
    assert rep.motions >= 5 and rep.positions >= 5, rep


# ------------------------------------------------------------------ fresh exports
def _variants(dialect: str) -> dict[str, object]:
    """Every file layout a writer has: MELFA .POS or positions below END, BASIC V, programs
    split into parts (a main calling them) when positions per file are limited."""
    base = {"default": get_dialect(dialect)}
    if dialect == "melfa":
        base |= {"one file": MelfaDialect(single_file=True), "BASIC V": MelfaDialect(variant="V"),
                 "parts": MelfaDialect(max_positions_per_file=4)}
    elif dialect == "krl":
        base |= {"parts": KrlDialect(max_positions_per_file=4)}
    elif dialect == "rapid":
        base |= {"parts": RapidDialect(max_positions_per_file=4)}
    elif dialect == "fanuc":
        base |= {"parts": FanucDialect(max_positions_per_file=4),
                 "line limit": FanucDialect(max_lines=40)}
    elif dialect == "yaskawa":
        base |= {"parts": YaskawaDialect(max_positions_per_file=4),
                 "line limit": YaskawaDialect(max_lines=45),
                 "PL zones": YaskawaDialect(position_levels_mm=(0.1, 0.5, 1, 5, 10, 25, 50,
                                                               100))}
    return base


@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("dialect", FRESH)
def test_exported_samples_follow_the_documented_syntax(robot_for, program_for, dialect,
                                                       scenario):
    robot = robot_for(dialect)
    program = program_for(scenario, robot)
    for label, d in _variants(dialect).items():
        result = export_files(program, d, robot)
        rep = check_report(dialect, {f.name: f.data for f in result.files})
        assert rep.problems == [], f"{label}: {rep.problems}"
        assert rep.motions > 0, label
        if label == "default":
            # the writer's own count and the reader's agree (a SPLINE block is one motion)
            assert rep.motions == result.primitives, (label, rep.motions, result.primitives)


@pytest.mark.parametrize("dialect", FRESH)
def test_a_drawing_in_a_work_frame_follows_the_documented_syntax(robot_for, dialect):
    """Targets in a calibrated frame: KRL $BASE, RAPID wobjdata, URScript pose_trans, FANUC
    UF 1, Yaskawa USER 1."""
    robot = robot_for(dialect)
    T = paper_frame((290.0, 0.0, 100.0))
    T[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    traj = drawing_trajectory(robot, drawing(1), T_base_paper=T, tolerance=1e-4, name="paper")
    program = program_from_trajectory(traj, robot, name="paper", work=Frame("paper", T))
    result = export_files(program, get_dialect(dialect), robot)
    assert check_text(dialect, {f.name: f.data for f in result.files}) == []


def test_a_blended_joint_move_follows_the_documented_syntax(rv2aj, thesis_program):
    """Blending at corners (issue 35 item 2) on a joint move, in every dialect."""
    from dataclasses import replace

    from assistant.export import Move, MoveKind

    ins = list(thesis_program.instructions)
    k = next(i for i, m in enumerate(ins) if i > 0 and isinstance(m, Move)
             and m.kind == MoveKind.JOINT)
    ins[k] = replace(ins[k], blend_radius=0.01)
    program = replace(thesis_program, instructions=ins)
    problems = []
    for dialect in ("melfa", "rapid", "krl", "fanuc", "yaskawa"):
        result = export_files(program, get_dialect(dialect), rv2aj)
        problems += check_text(dialect, {f.name: f.data for f in result.files})
    assert problems == []


# The sample cells' own programs (and their plans in every other dialect) are checked where
# they are made: tests/samples/test_sample_cells.py, one planned run for both checks.


# ------------------------------------------------------------------ hand-written programs
EXAMPLES = GRAMMARS / "examples"


def example(dialect: str) -> dict[str, str]:
    """A program written by hand from the manuals' examples (other names, other keyword
    case, documented options our writers do not use), so the readers are not tuned to our
    writers' text."""
    return {p.name: p.read_text(encoding="ascii") for p in sorted((EXAMPLES / dialect).iterdir())}


@pytest.mark.parametrize("dialect", ALL)
def test_hand_written_programs_follow_the_documented_syntax(dialect):
    rep = check_report(dialect, example(dialect))
    assert rep.problems == []
    assert rep.motions == 6 and rep.positions >= 5, rep


def _edit(files: dict[str, str], suffix: str, old: str, new: str) -> dict[str, str]:
    name = next(n for n in files if n.endswith(suffix))
    assert old in files[name], f"{old!r} not in {name}"
    return {**files, name: files[name].replace(old, new, 1)}


def _line_of(files: dict[str, str], suffix: str, text: str) -> int:
    """The last line that is `text`, else the last that holds it."""
    name = next(n for n in files if n.endswith(suffix))
    rows = files[name].splitlines()
    exact = [k for k, row in enumerate(rows, start=1) if row.strip() == text]
    holds = [k for k, row in enumerate(rows, start=1) if text in row]
    assert exact or holds, f"{text!r} not in {name}"
    return (exact or holds)[-1]


J6 = "[0.0, -1.57, 1.57, -1.57, -1.57, 0.0]"
J7 = "[0.0, -1.57, 1.57, -1.57, -1.57, 0.0, 0.3]"
# (dialect, file suffix, old, new, what the message says, a text on the named line)
BROKEN = [
    ("melfa", ".MB4", "150 Mvs P10", "150 Mvs P11", "P11 is used but never defined", "Mvs P11"),
    ("melfa", ".POS", "P10=(+230.00", "P10=(+2.3e+02", "number with an exponent", "P10=("),
    ("melfa", ".POS", "P10=(+230.00", "P10=(230", "not a signed fixed-point value", "P10=("),
    ("melfa", ".MB4", "90 Mvs PSEAM_A", "90 Mvs PSEAMSTART",
     "PSEAMSTART is 10 characters; MELFA BASIC IV takes 8", "PSEAMSTART"),
    ("melfa", ".MB4", "\n200 End", "", "no END step", "190 Mov J1"),
    ("melfa", ".MB4", "150 Mvs P10", "150 Mvs P10 P7", "unexpected", "Mvs P10 P7"),
    ("melfa", ".MB4", "20 REM names", "20 REM " + "x" * 120 + " names",
     "characters; the controller allows 127", "20 REM"),
    ("melfa", ".POS", "P7=", "P_7=", "second character", "P_7="),
    ("melfa", ".MB4", "130 Mvr PSEAM_A,P7", "130 Mvr P1_V1,P7", "adds a straight move",
     "130 Mvr"),
    ("melfa", ".MB4", "150 Mvs P10", "150 Mvs P10\n150 Dly 1", "does not follow", "150 Dly 1"),
    ("krl", ".src", "LIN XSEAM_A C_DIS", "LIN XSEAM_C C_DIS", "XSEAM_C is used but not declared",
     "LIN XSEAM_C"),
    ("krl", ".dat", "X 320.0,Y -20.0", "X 3.2E2,Y -20.0", "number with an exponent",
     "XSEAM_A="),
    ("krl", ".src", "  PTP XHOME\nEND", "  PTP XHOME\n  WAIT SEC 1", "ends too early",
     "WAIT SEC 1"),
    ("krl", ".dat", "XP7=", "XP7_IS_A_VERY_LONG_POSITION=", "27 characters; KRL takes 24",
     "XP7_IS_A"),
    ("krl", ".src", "PTP XP1_V1 C_PTP", "PTP XP1_V1 C_SPL", "unexpected", "PTP XP1_V1 C_SPL"),
    ("krl", ".dat", "S 2,T 35}\n  DECL E6POS XSEAM_A", "S 2,S 35}\n  DECL E6POS XSEAM_A",
     "S given twice", "XP1_V1="),
    ("krl", ".src", "CIRC XP7, XSEAM_B", "CIRC XHOME, XSEAM_B", "CIRC needs a Cartesian point",
     "CIRC XHOME"),
    ("krl", ".dat", "DEFDAT seam", "DEFDAT seams", "module name to be the file name",
     "DEFDAT seams"),
    ("rapid", ".mod", "MoveL SEAM_A, v100", "MoveL SEAM_C, v100",
     "SEAM_C (robtarget) is not declared", "MoveL SEAM_C"),
    ("rapid", ".mod", "[[320,-20,170]", "[[3.2E2,-20,170]", "has an exponent", "SEAM_A :="),
    ("rapid", ".mod", "ENDMODULE", "", "ends too early", "ENDPROC"),
    ("rapid", ".mod", "robtarget P7 :=", "robtarget " + "P" * 33 + " :=",
     "is 33 characters; RAPID takes 32", "PPPP"),
    ("rapid", ".mod", "vSeam, zSeam", "v55, zSeam", "v55 (speeddata) is not declared", "v55"),
    ("rapid", ".mod", "[[300,40,160],[0,1,0,0]", "[[300,40,160],[0,1.1,0,0]",
     "not a unit quaternion", "P7 :="),
    ("rapid", ".mod", "MoveAbsJ jHome\\NoEOffs, v500, fine, tNozzle;",
     "MoveAbsJ P7\\NoEOffs, v500, fine, tNozzle;", "P7 is robtarget, the instruction wants",
     "MoveAbsJ P7"),
    ("rapid", ".mod", "MoveJ P1_V1, v500, z50, tNozzle\\WObj:=wTable;",
     "MoveJ P1_V1, v500, z50;", "unexpected", "MoveJ P1_V1"),
    ("urscript", ".script", f"HOME_q = {J6}", f"HOME_q = {J7}",
     "has 7 joint values; UR arms have 6", "movej(HOME_q"),
    ("urscript", ".script", f"movej({J6}", f"movej({J7}", "has 7 joint values", "movej([0.0"),
    ("urscript", ".script", "movel(SEAM_A, a=1.2, v=0.25)", "movel(SEAM_C, a=1.2, v=0.25)",
     "SEAM_C is used before it is assigned", "movel(SEAM_C"),
    ("urscript", ".script", "SEAM_A = p[-0.32", "SEAM_A = p[-3.2e-1", "number with an exponent",
     "SEAM_A = p["),
    ("urscript", ".script", "\nend\n", "\n", "ends too early", "seam()"),
    ("urscript", ".script", "mode=1)", "mode=2)", "mode is 0 or 1", "movec(P7"),
    ("urscript", ".script", "movel(SEAM_A, a=1.2, v=0.25)", "movel(SEAM_A, a=1.2, speed=0.25)",
     "no parameter speed", "movel(SEAM_A"),
    ("urscript", ".script", "3.1416, 0.0]\n  SEAM_B", "3.1416]\n  SEAM_B",
     "a pose has 6 values", "P7 = p["),
    ("fanuc", ".LS", "L P[3:SEAM_A] 250mm/sec", "L P[9:SEAM_A] 250mm/sec",
     "P[9] is used but not in /POS", "P[9:SEAM_A]"),
    ("fanuc", ".LS", "X =   320.000  mm", "X =   3.2e2  mm", "number with an exponent",
     "3.2e2"),
    ("fanuc", ".LS", "LINE_COUNT\t= 21;", "LINE_COUNT\t= 22;",
     "LINE_COUNT = 22 but /MN has 21 lines", "LINE_COUNT"),
    ("fanuc", ".LS", "J P[2:P1_V1] 40%", "J P[2:P1_V1] 400mm/sec", "J with a speed in mm/sec",
     "J P[2:P1_V1]"),
    ("fanuc", ".LS", "J P[1:HOME] 100% FINE", "J P[1:HOME] 150% FINE", "outside 1..100 %",
     "150%"),
    ("fanuc", ".LS", "!Glue seam, nozzle on UT 2", "!Glue the seam with the nozzle on UTOOL 2",
     "a comment of 40 characters; the controller takes 32", "!Glue the seam"),
    ("fanuc", ".LS", "'F U T, 0, 0, 1'", "'F X T, 0, 0, 1'", "is not 'F|N", "F X T"),
    ("fanuc", ".LS", "Y =   -20.000  mm,\tZ =   170.000  mm,", "Y =   -20.000  mm,",
     "P[3] lacks Z", 'P[3:"SEAM_A"]{'),
    ("fanuc", ".LS", 'P[6:"P8"]{\n   GP1:\n\tUF : 1', 'P[6:"P8"]{\n   GP1:\n\tUF : 2',
     "P[6] is taught in UF 2 but UFRAME_NUM is 1", "L P[6:P8] 1500cm/min"),
    ("fanuc", ".LS", "L P[3:SEAM_A] 250mm/sec CNT10", "L P[3:SEAM_A] 250mm/sec", "unexpected",
     "L P[3:SEAM_A]"),
    ("fanuc", ".LS", "/PROG  SEAM", "/PROG  SEAMS", "the program is named as its file",
     "/PROG  SEAMS"),
    ("fanuc", ".LS", "\n/END", "", "ends too early", "};"),
    ("fanuc", ".LS", "DO[1:dispenser]=ON", "DO[0:dispenser]=ON", "I/O are numbered from 1",
     "DO[0:dispenser]"),
    ("fanuc", ".LS", 'P[4:"P7"]{', 'P[4:"P7_ON_THE_ARC_TOP"]{',
     "has 17 characters; the controller takes 16", "P7_ON_THE_ARC_TOP"),
    ("fanuc", ".LS", "C P[4:P7]    \n    :  P[5:SEAM_B]", "C P[5:SEAM_B]",
     "a circular motion names two points", "C P[5:SEAM_B]"),
    ("yaskawa", ".JBI", "MOVL C00005 V=66.0", "MOVL C00007 V=66.0",
     "C00007 is used but not defined", "MOVL C00007"),
    ("yaskawa", ".JBI", "C00002=320.000", "C00002=3.2e2", "number with an exponent",
     "C00002="),
    ("yaskawa", ".JBI", "///NPOS 6,0,0,1,0,0", "///NPOS 7,0,0,1,0,0",
     "///NPOS says 7 C positions, 6 follow", "///NPOS"),
    ("yaskawa", ".JBI", "MOVL C00002 V=250.0", "MOVL C00002 VJ=25.00",
     "MOVL takes its speed as V=", "MOVL C00002"),
    ("yaskawa", ".JBI", "PL=3", "PL=9", "PL=9: a whole number 0..8", "PL=9"),
    ("yaskawa", ".JBI", "MOVC C00003 V=100.0\n", "", "are not whole arcs",
     "MOVC C00002 V=100.0"),
    ("yaskawa", ".JBI", "'glue the seam, nozzle on tool 2",
     "'glue the seam with the nozzle on tool 2", "a comment of 39 characters",
     "'glue the seam with"),
    ("yaskawa", ".JBI", "//NAME SEAM", "//NAME SEAMS", "a job is named as its file",
     "//NAME SEAMS"),
    ("yaskawa", ".JBI", "\nEND", "", "ends too early", "MOVJ C00000 VJ=50.00"),
    ("yaskawa", ".JBI", "DOUT OT#(1) ON", "DOUT OT#(0) ON", "outputs are numbered from 1",
     "DOUT OT#(0)"),
    ("yaskawa", ".JBI", "TIMER T=0.50", "TIMER T=0.00", "TIMER T=0.00: 0.01..655.35 s",
     "TIMER"),
    ("yaskawa", ".JBI", "C00001=220.000,-220.000,230.000,180.0000",
     "C00001=220.000,-220.000,230.000,190.0000", "Rx, Ry, Rz within", "C00001="),
    ("yaskawa", ".JBI", "///RECTAN\n///RCONF 1,0,0,0,0,0,0,0\n", "///RECTAN\n",
     "Cartesian data after a ///RCONF", "C00001="),
    ("yaskawa", ".JBI", "///COMM GLUE SEAM", "///COMM GLUE THE SEAM ON THE PLATE, TOOL 2",
     "///COMM of 34 characters", "///COMM"),
    ("yaskawa", ".JBI", "MOVJ C00001 VJ=40.00", "MOVJ C00001 VJ=0.00",
     "VJ=0.00: 0.01..100.00 %", "MOVJ C00001"),
]


@pytest.mark.parametrize("dialect, suffix, old, new, says, on_line", BROKEN,
                         ids=[f"{b[0]}:{b[4][:28]}" for b in BROKEN])
def test_a_broken_program_is_refused_naming_the_line(dialect, suffix, old, new, says, on_line):
    files = _edit(example(dialect), suffix, old, new)
    problems = check_text(dialect, files)
    hits = [p for p in problems if says in p]
    assert hits, problems
    name = next(n for n in files if n.endswith(suffix))
    want = _line_of(files, suffix, on_line)
    assert hits[0].startswith(f"{name} line {want}:"), (hits[0], want)


def test_each_dialect_has_broken_examples():
    assert {b[0] for b in BROKEN} == set(CHECKERS)
