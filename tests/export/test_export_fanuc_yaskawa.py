"""FANUC TP and Yaskawa INFORM specifics (issue 55): configuration flags from the planned
joints, joint values where CONFIG cannot place an axis, the controllers' limits enforced with
a note when something is renamed or split, INFORM's arcs and positioning levels, outputs.
The common checks (round trip, grammar, goldens, names, axes) run with the other dialects."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest
from grammars import check_report

from assistant.export import (
    Comment,
    ExportError,
    FanucDialect,
    Frame,
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    SetOutput,
    YaskawaDialect,
    export_files,
    round_trip,
)
from assistant.export.dialect import lower_splines
from assistant.export.fanuc import config_text
from assistant.export.program import renamed
from assistant.export.yaskawa import rconf_text


def comment_texts(text: str) -> list[str]:
    """The text of every comment instruction: FANUC ``n:  !text ;``, INFORM ``'text``."""
    return [m.group(1).rstrip() for row in text.splitlines()
            if (m := re.match(r"^\s*(?:\d+:\s*!|')([^;]*)", row))]


# ------------------------------------------------------------------ configuration
def test_fanuc_config_follows_the_planned_posture(rv2aj):
    up = np.radians([10.0, 20.0, 90.0, 70.0, 0.0])
    assert config_text(rv2aj, up) == "N U T, 0, 0, 0"
    down = np.radians([-20.0, 70.0, -40.0, 80.0, 10.0])  # elbow below the shoulder line
    assert config_text(rv2aj, down).startswith("N D T")
    turned = up.copy()
    turned[4] = np.radians(190.0)  # J6 one turn beyond (-180, 180]
    assert config_text(rv2aj, turned) == "N U T, 0, 0, 1"
    behind = np.radians([10.0, -50.0, 100.0, -60.0, 0.0])  # wrist behind the J1 axis
    assert config_text(rv2aj, behind).split(",")[0].endswith("B")


def test_yaskawa_rconf_follows_the_manipulator_types(ur5):
    q = np.radians([-25.8, -73.3, 116.6, -133.3, -90.0, 0.0])
    types = [int(v) for v in rconf_text(ur5, q).split(",")]
    assert len(types) == 24 and types[6:] == [0] * 18
    # R (wrist 1) at -133.3 deg: No-flip (90 < |R| <= 270), R within -180..180
    assert types[0] == 1 and types[3] == 0
    r_turned = q.copy()
    r_turned[3] += 2 * np.pi  # R at 226.7 deg: still No-flip, R >= 180
    turned = [int(v) for v in rconf_text(ur5, r_turned).split(",")]
    assert turned[0] == 1 and turned[3] == 1
    t_turned = q.copy()
    t_turned[5] = np.radians(200.0)
    assert [int(v) for v in rconf_text(ur5, t_turned).split(",")][4] == 1


def small_ur5_program(ur5) -> NeutralProgram:
    """A joint move, a blended line and an arc near the UR5's usual posture."""
    rng = np.random.default_rng(3)
    q0 = np.array([0.2, -1.4, 1.6, -1.8, -1.57, 0.3])
    T0 = ur5.fk(q0)

    def at(name, dp):
        T = T0.copy()
        T[:3, 3] += np.asarray(dp) + rng.uniform(-5e-4, 5e-4, 3)
        res = ur5.ik(T, q0)
        assert res.ok
        return Position(name, T, res.best(q0))

    a, b, v, c = (at("A", (0, 0, 0)), at("B", (0.05, 0.03, -0.02)),
                  at("V", (0.08, 0.06, -0.02)), at("C", (0.05, 0.09, -0.02)))
    return NeutralProgram("URDEMO", [
        Move(MoveKind.JOINT, a, speed=0.3, step="start"),
        Move(MoveKind.LINEAR, b, speed=0.1, blend_radius=0.002, step="line"),
        Move(MoveKind.CIRCULAR, c, v, speed=0.05, step="arc"),
        Gripper(1, True, "arc"),
        Move(MoveKind.JOINT, a, speed=0.3, step="back"),
    ], Frame("gripper", ur5.T_flange_tool), q_start=q0)


def test_a_ur5_in_fanuc_is_written_in_joint_values_and_round_trips(ur5):
    """The UR5's shoulder turns +-360 deg: CONFIG's turn numbers (J1, J4, J6) cannot say
    which turn, so every position is written as joints, with one note saying why."""
    prog = small_ur5_program(ur5)
    res = export_files(prog, "fanuc", ur5)
    text = res.files[0].data.decode("ascii")
    assert "CONFIG" not in text.split("/POS")[1] and text.count("J1=") == 4
    assert len(res.notes) == 1 and "shoulder_lift_joint can turn a full turn" in res.notes[0]
    rep = round_trip(prog, "fanuc", ur5, max_step=0.005)
    # joints written with 4 decimals: 0.00005 deg at 1 m is 0.9 um per joint
    assert rep.max_tcp_deviation < 5e-6 and not rep.instruction_differences
    assert check_report("fanuc", {f.name: f.data for f in res.files}).problems == []


def test_a_ur5_in_yaskawa_names_the_types_and_the_axes_rconf_cannot_place(ur5):
    prog = small_ur5_program(ur5)
    res = export_files(prog, "yaskawa", ur5)
    text = res.files[0].data.decode("ascii")
    assert text.count("///RCONF") >= 1 and re.search(r"^C00003=", text, re.M)
    turn = [n for n in res.notes if "RCONF has no flag" in n]
    assert turn and "shoulder_lift_joint" in turn[0]
    rep = round_trip(prog, "yaskawa", ur5, max_step=0.005)
    assert rep.max_tcp_deviation < 3e-6 and not rep.config_mismatches
    assert not rep.instruction_differences


# ------------------------------------------------------------------ controller limits
def test_names_beyond_the_controllers_limits_are_renamed_once_with_a_note(rv2aj,
                                                                          thesis_program):
    prog = renamed(thesis_program, {"P7": "SEAM_START_POINT", "P8": "SEAM_START_POINT2"})
    fanuc = export_files(prog, "fanuc", rv2aj)  # position comments: 16 characters
    assert len(fanuc.renames) == 1 and "FANUC TP allows at most 16" in fanuc.renames[0]
    text = fanuc.files[0].data.decode("ascii")
    assert 'P[7:"SEAM_START_POINT"]' in text and "SEAM_START_POINT2" not in text
    yaskawa = export_files(prog, "yaskawa", rv2aj)  # name comments: 32 - len("from ")
    assert yaskawa.renames == ()
    assert "'to SEAM_START_POINT2" in yaskawa.files[0].data.decode("ascii")


def test_program_and_job_names_follow_the_controllers(rv2aj, thesis_program):
    with pytest.raises(ExportError, match="'THESIS_CELL' is 11 characters long; FANUC TP "
                                          "allows at most 8"):
        FanucDialect().write(replace(thesis_program, name="thesis_cell"), rv2aj)
    YaskawaDialect().write(replace(thesis_program, name="thesis_cell"), rv2aj)
    with pytest.raises(ExportError, match="33 characters long; Yaskawa INFORM allows at most 32"):
        YaskawaDialect().write(replace(thesis_program, name="T" * 33), rv2aj)


@pytest.mark.parametrize("dialect", ["fanuc", "yaskawa"])
def test_comments_are_wrapped_to_32_characters(rv2aj, thesis_program, dialect):
    text = "check the fingers of the gripper before the next cycle starts " * 4
    prog = replace(thesis_program, instructions=[Comment(text)] + thesis_program.instructions)
    res = export_files(prog, dialect, rv2aj)
    body = res.files[0].data.decode("ascii")
    texts = comment_texts(body)
    assert max(len(t) for t in texts) <= 32
    assert " ".join(t for t in texts if "gripper" in t or "fingers" in t or "check" in t)
    assert check_report(dialect, {f.name: f.data for f in res.files}).problems == []


@pytest.mark.parametrize("dialect, limit", [(FanucDialect(max_lines=30), 30),
                                            (YaskawaDialect(max_lines=45), 45)],
                         ids=["fanuc", "yaskawa"])
def test_a_program_over_the_line_limit_is_split_with_a_note(rv2aj, drawing_program, dialect,
                                                            limit):
    res = export_files(drawing_program, dialect, rv2aj)
    assert len(res.files) > 2
    assert len(res.notes) >= 1 and any("split into" in n for n in res.notes)
    main = res.files[0].data.decode("ascii")
    for f in res.files[1:]:
        assert f.name.rsplit(".", 1)[0] in main  # the main calls each part
    rows = [f.data.decode("ascii") for f in res.files]
    if dialect.name == "fanuc":
        counts = [int(re.search(r"LINE_COUNT\t= (\d+);", t).group(1)) for t in rows]
    else:
        counts = [len(t.split("\r\nNOP\r\n")[1].splitlines()) + 1 for t in rows]
    assert max(counts) <= limit
    rep = round_trip(drawing_program, dialect, rv2aj)
    assert rep.max_tcp_deviation < 5e-6 and not rep.instruction_differences
    assert check_report(dialect.name, {f.name: f.data for f in res.files}).problems == []


@pytest.mark.parametrize("dialect", [FanucDialect(), YaskawaDialect()], ids=["fanuc", "yaskawa"])
def test_outputs_are_numbered_from_one(rv2aj, thesis_program, dialect):
    prog = replace(thesis_program, instructions=thesis_program.instructions + [
        SetOutput(0, True, "P8->P10")])
    with pytest.raises(ExportError, match="numbered from 1"):
        dialect.write(prog, rv2aj)


# ------------------------------------------------------------------ INFORM specifics
def test_consecutive_arcs_share_their_fpt_point(rv2aj, frame_program):
    """INFORM: three MOVC steps per arc; an arc that follows an arc starts at the previous
    end, marked FPT, instead of repeating it."""
    moves = frame_program.moves()
    arc = next(m for m in moves if m.kind == MoveKind.CIRCULAR)
    prev = moves[moves.index(arc) - 1]
    # a second arc straight after the first: back through the first arc's via to its start
    back = Move(MoveKind.CIRCULAR, prev.target, arc.via, speed=arc.speed, step=arc.step)
    ins = list(frame_program.instructions)
    ins.insert(ins.index(arc) + 1, back)
    prog = replace(frame_program, instructions=ins)
    text = YaskawaDialect().write(prog, rv2aj)[0].text
    steps = [r for r in text.splitlines() if r.startswith("MOV")]
    k = next(i for i, r in enumerate(steps) if r.endswith("FPT V=50.0") or " FPT " in r)
    assert steps[k - 2].startswith("MOVC") and steps[k + 1].startswith("MOVC")
    assert steps[k + 2].startswith("MOVC") and not steps[k + 3].startswith("MOVC")
    rep = round_trip(prog, "yaskawa", rv2aj)
    assert rep.max_tcp_deviation < 3e-6 and rep.primitives == len(prog.moves())
    grammar = check_report("yaskawa", {"FRAME.JBI": text})
    assert grammar.problems == [] and grammar.motions == len(prog.moves())


def test_a_circular_move_cannot_open_an_inform_job(rv2aj, thesis_program):
    arc = next(m for m in thesis_program.moves() if m.kind == MoveKind.CIRCULAR)
    with pytest.raises(ExportError, match="cannot come first"):
        YaskawaDialect().write(replace(thesis_program, instructions=[arc]), rv2aj)


def test_blends_need_the_controllers_positioning_zones(rv2aj, drawing_program):
    """PL=n rounds within zone n, a controller parameter: unknown, every move stops at its
    point (and the export says so); known, the highest level within the planned blend."""
    lowered = lower_splines(drawing_program)  # a spline becomes lines blended at its points
    assert [m for m in lowered.moves() if m.blend_radius > 0.0]
    plain = export_files(drawing_program, "yaskawa", rv2aj)
    assert "PL=" not in plain.files[0].data.decode("ascii")
    assert any("exact stops" in n for n in plain.notes)
    zones = (0.05, 0.1, 0.2, 0.5, 1.0, 5.0, 10.0, 50.0)
    d = YaskawaDialect(position_levels_mm=zones)
    text = d.write(drawing_program, rv2aj)[0].text
    levels = [int(v) for v in re.findall(r"PL=(\d)", text)]
    assert levels and max(levels) <= 8
    for m in d.lower(drawing_program).moves():
        assert m.blend_radius == 0.0 or round(m.blend_radius * 1000, 6) in zones
    for a, b in zip(lowered.moves(), d.lower(drawing_program).moves(), strict=True):
        assert b.blend_radius <= a.blend_radius + 1e-12  # never more rounding than planned
    rep = round_trip(drawing_program, d, rv2aj)
    assert not rep.instruction_differences and rep.max_tcp_deviation < 3e-6
    with pytest.raises(ValueError, match="eight increasing zones"):
        YaskawaDialect(position_levels_mm=(1.0, 2.0))


def test_joint_speeds_are_fractions_of_the_robots_own_limits(rv2aj, thesis_program):
    """A joint move's speed is a percentage of each axis' maximum (J n%, VJ=n), never more
    than 100: no joint is ever commanded above the robot's speed limit."""
    fanuc = FanucDialect().write(thesis_program, rv2aj)[0].text
    assert all(1 <= int(v) <= 100 for v in re.findall(r"^\s*\d+:J \S+ (\d+)%", fanuc, re.M))
    inform = YaskawaDialect().write(thesis_program, rv2aj)[0].text
    assert all(0.01 <= float(v) <= 100.0 for v in re.findall(r"VJ=([\d.]+)", inform))
