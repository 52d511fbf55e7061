"""Controller rules with offending input: numbers, names, line lengths, positions per file.

Each dialect is tested on an arm its controller runs (`robot_for`): the thesis RV-2AJ, and
the UR5 for URScript."""

from __future__ import annotations

import re
from dataclasses import replace

import pytest

from assistant.export import (
    ExportError,
    FanucDialect,
    KrlDialect,
    MelfaDialect,
    RapidDialect,
    URScriptDialect,
    YaskawaDialect,
    get_dialect,
    round_trip,
)
from assistant.export.krl import krl_rules
from assistant.export.program import Comment, Move, MoveKind
from assistant.export.rules import check_lines, format_compact, format_fixed

ALL = ("melfa", "krl", "rapid", "urscript", "fanuc", "yaskawa")


# ------------------------------------------------------------------------------ numbers
@pytest.mark.parametrize("value, decimals, text", [
    (1e-20, 3, "0.000"), (-1e-20, 3, "0.000"), (-0.0, 3, "0.000"), (-0.0004, 3, "0.000"),
    (-0.0005001, 3, "-0.001"), (1234.56789, 3, "1234.568"), (1e7, 2, "10000000.00"),
    (123456.0, 0, "123456"), (-2.5e-7, 6, "0.000000"),
])
def test_fixed_numbers_never_have_exponents_or_negative_zero(value, decimals, text):
    assert format_fixed(value, decimals) == text


def test_melfa_style_sign_and_compact_settings():
    assert format_fixed(412.9, 2, plus=True) == "+412.90"
    assert format_fixed(-0.001, 2, plus=True) == "+0.00"
    assert format_compact(50.0, 1) == "50"
    assert format_compact(12.5, 1) == "12.5"
    assert format_compact(1e-12, 3) == "0"


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), 1e20])
def test_absurd_numbers_are_refused_not_written(bad):
    with pytest.raises(ExportError, match="cannot be written"):
        format_fixed(bad, 3, what="X of P7", step="P7->P8")


@pytest.mark.parametrize("dialect", ALL)
def test_exponent_prone_values_in_a_program_come_out_fixed(robot_for, program_for, dialect):
    """Coordinates like 1e-20 m and -0.0 m reach the text as plain zeros in every dialect."""
    robot = robot_for(dialect)
    thesis_program = program_for("thesis", robot)
    p = thesis_program.moves()[3].target  # P5 at y = -20 mm
    assert p.name == "P5"
    T = p.T_base_tool.copy()
    T[1, 3] = -1e-20  # a tiny negative coordinate, joints kept consistent with it
    q = robot.ik(T, p.q).best(p.q)
    prog = _with_target(thesis_program, 3, replace(p, T_base_tool=T, q=q))
    for f in get_dialect(dialect).write(prog, robot):
        text = f.text.replace("9E+09", "")
        assert not re.search(r"\d[eE][+-]?\d", text), f.name
        assert not re.search(r"(?<![\d.])-0\.0*(?![0-9.])", text), f.name
    assert re.search(r"(?<![\d.])-0\.0*(?![0-9.])", "Y -0.000,") is not None


def test_check_lines_catches_an_exponent_and_long_lines():
    rules = krl_rules()
    with pytest.raises(ExportError, match="exponent"):
        check_lines("  DECL E6POS XP1={X 1.5e-05,Y 0.0}", rules, "a.dat")
    with pytest.raises(ExportError, match="line 2 is 300 characters"):
        check_lines("ok\n" + "x" * 300, rules, "a.src")
    check_lines("  CONST robtarget P := [[1,2,3],[1,0,0,0],[0,0,0,0],[9E+09,9E+09]];",
                rules, "ok.mod")


# ------------------------------------------------------------------------------ names
@pytest.mark.parametrize("dialect", ALL)
def test_an_illegal_position_name_is_refused_naming_the_step(robot_for, program_for, dialect):
    robot = robot_for(dialect)
    prog = _rename(program_for("thesis", robot), "P8", "pick 1")
    with pytest.raises(ExportError) as e:
        get_dialect(dialect).write(prog, robot)
    assert str(e.value).startswith("step 'P7->P8': ")
    assert "pick 1" in str(e.value)


def test_krl_names_longer_than_24_characters_are_refused(rv2aj, thesis_program):
    prog = _rename(thesis_program, "P5", "P5_" + "A" * 21)  # X + 24 characters = 25
    with pytest.raises(ExportError, match="25 characters long; KUKA KRL allows at most 24"):
        KrlDialect().write(prog, rv2aj)
    ok = _rename(thesis_program, "P5", "P5_" + "A" * 20)  # exactly 24 with the X
    KrlDialect().write(ok, rv2aj)


def test_melfa_basic_iv_names_are_short_and_have_no_underscore_second(rv2aj, thesis_program):
    with pytest.raises(ExportError, match="at most 8"):
        MelfaDialect().write(_rename(thesis_program, "P5", "P5ABCDEFG"), rv2aj)
    with pytest.raises(ExportError, match="not a legal MELFA"):
        MelfaDialect().write(_rename(thesis_program, "P5", "P_5"), rv2aj)
    MelfaDialect(variant="V").write(_rename(thesis_program, "P5", "P5ABCDEFG"), rv2aj)


def test_reserved_words_and_case_collisions(rv2aj, thesis_program, ur5, program_for):
    with pytest.raises(ExportError, match="reserved"):
        RapidDialect().write(_rename(thesis_program, "P5", "fine"), rv2aj)
    with pytest.raises(ExportError, match="reserved"):
        URScriptDialect().write(_rename(program_for("thesis", ur5), "P5", "def"), ur5)
    with pytest.raises(ExportError, match="not case-sensitive"):
        KrlDialect().write(_rename(thesis_program, "P5", "p4"), rv2aj)


def test_program_names_follow_the_controller(rv2aj, thesis_program):
    with pytest.raises(ExportError, match="program name"):
        KrlDialect().write(replace(thesis_program, name="1st_program"), rv2aj)
    with pytest.raises(ExportError, match="program name"):
        MelfaDialect().write(replace(thesis_program, name="THESIS_CELL"), rv2aj)


# ------------------------------------------------------------------------------ lines
@pytest.mark.parametrize("dialect", ALL)
def test_long_comments_are_wrapped_to_the_line_limit(robot_for, program_for, dialect):
    robot = robot_for(dialect)
    thesis_program = program_for("thesis", robot)
    text = "check the gripper fingers before the next cycle " * 10
    prog = replace(thesis_program, instructions=[Comment(text)] + thesis_program.instructions)
    d = get_dialect(dialect)
    for f in d.write(prog, robot):
        assert max(len(line) for line in f.text.splitlines()) <= d.rules.max_line


def test_a_tighter_line_limit_is_enforced(rv2aj, thesis_program):
    d = KrlDialect()
    d.rules = d.rules.with_limits(max_line=100)
    with pytest.raises(ExportError, match="allows at most 100"):
        d.write(thesis_program, rv2aj)


# ------------------------------------------------------------------------------ file size
@pytest.mark.parametrize("dialect", [MelfaDialect(max_positions_per_file=4),
                                     KrlDialect(max_positions_per_file=4),
                                     RapidDialect(max_positions_per_file=4),
                                     FanucDialect(max_positions_per_file=4),
                                     YaskawaDialect(max_positions_per_file=4)],
                         ids=["melfa", "krl", "rapid", "fanuc", "yaskawa"])
def test_too_many_positions_split_into_parts_with_a_main(rv2aj, thesis_program, dialect):
    files = dialect.write(thesis_program, rv2aj)
    names = [f.name for f in files]
    main = files[0]
    parts = [n.rsplit(".", 1)[0] for n in names[1:]]
    parts = list(dict.fromkeys(parts))
    assert len(parts) >= 3
    calls = re.findall(r"(\w+)\s*(?:\(\s*\)|;)|CALLP \"(\w+)\"|CALL JOB:(\w+)", main.text)
    called = [a or b or c for a, b, c in calls if (a or b or c) in parts]
    assert called == parts  # the main calls every part, in order
    for f in files[1:]:
        n_decl = len(re.findall(r"^\s*(?:P\w*=|J\w*=|DECL E6|CONST (?:robtarget|jointtarget)"
                                r"|P\[\d+:\"|C\d{5}=)", f.text, re.M))
        assert n_decl <= 4, f.name
    rep = round_trip(thesis_program, dialect, rv2aj)
    assert rep.primitives == thesis_program.primitive_count()
    assert rep.max_tcp_deviation < 2e-5
    assert not rep.instruction_differences


# ------------------------------------------------------------------------------ helpers
def _rename(prog, old, new):
    from assistant.export.program import renamed

    return renamed(prog, {old: new})


def _with_target(prog, move_index, pos):
    moves = [i for i in prog.instructions if isinstance(i, Move)]
    old = moves[move_index].target
    out = []
    for ins in prog.instructions:
        if isinstance(ins, Move):
            ins = replace(ins, target=pos if ins.target is old else ins.target,
                          via=pos if ins.via is old else ins.via)
        out.append(ins)
    assert any(isinstance(i, Move) and i.kind == MoveKind.LINEAR for i in out)
    return replace(prog, instructions=out)
