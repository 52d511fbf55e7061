"""Round trip for every move type in every dialect: write -> read -> simulate -> compare.

MELFA, KRL, RAPID, FANUC and Yaskawa run on the thesis RV-2AJ (5 axes), URScript on a UR5
(UR arms have 6 axes; `robot_for` in conftest picks the arm)."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

from assistant.export import (
    Comment,
    Frame,
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    SetOutput,
    Wait,
    check_program,
    get_dialect,
    round_trip,
)
from assistant.export.dialect import ProgramFile
from assistant.export.roundtrip import RoundTripReport
from assistant.export.samples import R_DOWN
from assistant.transforms import make_T, rot_z

ALL = ("melfa", "krl", "rapid", "urscript", "fanuc", "yaskawa")
#: What each number format allows: MELFA 0.01 mm / 0.01 deg; KRL and RAPID 0.001 mm and
#: 0.001 deg joints (0.0005 deg at 0.4 m is 3.5 um); URScript 1 um and 1 urad; FANUC 0.001 mm
#: and 0.001 deg (W, P, R: as KRL); Yaskawa 0.001 mm and 0.0001 deg (0.9 um + 0.35 um).
TOLERANCE = {"melfa": 2e-5, "krl": 5e-6, "rapid": 5e-6, "urscript": 3e-6, "fanuc": 5e-6,
             "yaskawa": 3e-6}
#: Simulation step (m): the UR5's numerical IK (every solution, each sample) is slow, so its
#: paths are compared every 20 mm rather than every 2 mm; the number format shows either way.
MAX_STEP = {"urscript": 0.02}


def _pos(robot, name, xyz, seed, rng, *, R=R_DOWN):
    """A non-round target (jitter below a millimetre) with the IK solution nearest `seed`."""
    p = np.asarray(xyz) + rng.uniform(-5e-4, 5e-4, 3)
    R = rot_z(rng.uniform(-0.3, 0.3)) @ R
    T = make_T(R, p)
    res = robot.ik(T, seed)
    assert res.ok, res.message
    return Position(name, T, res.best(seed))


#: Per axis count: IK seed near PA, the HOME joints, where the figure is moved (m) and the
#: tool orientation it is drawn with (turned about base z at random). The RV-2AJ draws in
#: front of its base, elbow up, tool pointing down; the UR5 in its usual posture, shoulder
#: and elbow at +-90 deg, wrist 2 at -90 deg, its flange (x of ee_link) pointing down.
_UR5_POSTURE = np.radians([0.0, -90.0, 90.0, -90.0, -90.0, 0.0])
ARMS = {
    5: (np.radians([-20.0, 40.0, 80.0, 60.0, 0.0]), np.radians([5.0, 25.0, 85.0, 60.0, 10.0]),
        (0.0, 0.0, 0.0), R_DOWN),
    6: (_UR5_POSTURE, _UR5_POSTURE + np.radians([5.0, 5.0, -5.0, 5.0, 5.0, 10.0]),
        (0.30, 0.15, 0.25), np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])),
}


def every_move_program(robot, rng, *, work: Frame | None = None) -> NeutralProgram:
    seed, home, shift, R = ARMS[robot.dof]

    def pos(name, xyz, seed):
        return _pos(robot, name, np.add(xyz, shift), seed, rng, R=R)

    a = pos("PA", (0.26, -0.12, 0.20), seed)
    b = pos("PB", (0.30, -0.05, 0.16), a.q)
    v = pos("PV", (0.33, 0.00, 0.15), b.q)
    c = pos("PC", (0.30, 0.06, 0.14), v.q)
    s = [pos(f"S{k}", (0.30 - 0.01 * k, 0.06 + 0.012 * k, 0.14 + 0.003 * k * k), c.q)
         for k in range(1, 6)]
    home_q = home + rng.uniform(-0.01, 0.01, robot.dof)
    home = Position("HOME", None, home_q, joint_target=True)
    ins = [
        Comment("every move type"),
        Move(MoveKind.JOINT, home, speed=0.4, step="home"),
        Move(MoveKind.JOINT, a, speed=0.35, acceleration=0.6, step="to A"),
        Gripper(1, True, "to A"),
        Move(MoveKind.LINEAR, b, speed=0.125, blend_radius=0.004, step="line"),
        Move(MoveKind.CIRCULAR, c, v, speed=0.08, step="arc"),
        SetOutput(3, True, "arc"),
        Wait(0.5, "arc"),
        Move(MoveKind.SPLINE, s[-1], through=tuple(s[:-1]), speed=0.05, step="free shape"),
        Move(MoveKind.LINEAR, a, speed=0.2, step="back"),
        Gripper(1, False, "back"),
        SetOutput(3, False, "back"),
    ]
    prog = NeutralProgram("EVERY", ins, Frame("gripper", make_T(p=[0, 0, 0.1])),
                          work or Frame("robot_base"), q_start=home_q)
    return prog


@pytest.fixture(scope="module")
def program(rv2aj) -> NeutralProgram:
    prog = every_move_program(rv2aj, np.random.default_rng(7))
    check_program(prog, rv2aj)
    return prog


@pytest.fixture(scope="module")
def program_in_work_frame(rv2aj) -> NeutralProgram:
    work = Frame("table", make_T(rot_z(0.3), [0.05, -0.02, 0.03]))
    return every_move_program(rv2aj, np.random.default_rng(8), work=work)


@pytest.fixture(scope="module")
def programs(rv2aj, ur5, program, program_in_work_frame):
    """(robot, work frame?) -> the every-move program for that arm, checked."""
    made = {(rv2aj.name, False): program, (rv2aj.name, True): program_in_work_frame}

    def get(robot, in_work_frame: bool = False) -> NeutralProgram:
        key = (robot.name, in_work_frame)
        if key not in made:
            work = Frame("table", make_T(rot_z(0.3), [0.05, -0.02, 0.03])) \
                if in_work_frame else None
            prog = every_move_program(robot, np.random.default_rng(8 if in_work_frame else 7),
                                      work=work)
            check_program(prog, robot)
            made[key] = prog
        return made[key]

    return get


@pytest.mark.parametrize("dialect", ALL)
def test_every_move_type_round_trips(robot_for, programs, dialect):
    robot = robot_for(dialect)
    program = programs(robot)
    rep = round_trip(program, dialect, robot, max_step=MAX_STEP.get(dialect, 0.002))
    kinds = [m.kind for m in get_dialect(dialect).lower(program).moves()]
    assert set(kinds) >= {MoveKind.JOINT, MoveKind.LINEAR, MoveKind.CIRCULAR}
    assert rep.primitives == len(kinds)
    assert rep.max_tcp_deviation <= TOLERANCE[dialect], rep.per_move
    assert rep.max_tcp_deviation > 0.0 or dialect != "melfa"  # MELFA's 2 decimals do show
    assert not rep.instruction_differences
    assert not rep.config_mismatches


@pytest.mark.parametrize("dialect", ALL)
def test_settings_read_back(robot_for, programs, dialect):
    robot = robot_for(dialect)
    program = programs(robot)
    d = get_dialect(dialect)
    planned = d.lower(program).moves()
    back = d.read(d.write(program, robot), robot).moves()
    for a, b in zip(planned, back, strict=True):
        assert a.kind == b.kind
        assert b.blend_radius == pytest.approx(a.blend_radius, abs=5e-5)
        if a.speed is not None:
            rel = 0.01 if dialect == "melfa" else 1e-3  # whole % and mm/s on MELFA
            assert b.speed == pytest.approx(a.speed, rel=rel, abs=5e-4)
        assert b.step == a.step
    if dialect in ("melfa", "krl", "urscript", "fanuc", "yaskawa"):
        acc = [m.acceleration for m in back if m.acceleration is not None]
        assert acc and acc[0] == pytest.approx(0.6, abs=0.01)


@pytest.mark.parametrize("dialect", ["krl", "rapid", "urscript", "fanuc", "yaskawa"])
def test_work_frame_round_trips(robot_for, programs, dialect):
    robot = robot_for(dialect)
    program_in_work_frame = programs(robot, in_work_frame=True)
    rep = round_trip(program_in_work_frame, dialect, robot,
                     max_step=MAX_STEP.get(dialect, 0.002))
    assert rep.max_tcp_deviation <= TOLERANCE[dialect]
    files = get_dialect(dialect).write(program_in_work_frame, robot)
    text = "\n".join(f.text for f in files)
    assert {"krl": "$BASE = {X 50.000", "rapid": "wobjdata wTable", "urscript": "TABLE = p[",
            "fanuc": "!UFRAME[1] table ;\n  16:  !X 50.000 Y -20.000",
            "yaskawa": "'USER 1 table\n'X 50.000 Y -20.000"}[dialect] in text


def test_krl_spline_block_and_linear_fallback(rv2aj, program):
    from assistant.export import KrlDialect

    src = KrlDialect().write(program, rv2aj)[0].text
    block = src[src.index("SPLINE"):src.index("ENDSPLINE")]
    assert block.count("SPL X") == 5
    src_lin = KrlDialect(spline=False).write(program, rv2aj)[0].text
    assert "SPLINE" not in src_lin and src_lin.count("LIN XS") == 5
    assert round_trip(program, KrlDialect(spline=False), rv2aj).max_tcp_deviation < 5e-6


def test_krl_tangent_bezier_segments_share_one_spline_block_corners_stop(rv2aj):
    """A Bezier chain arrives as one spline move per segment: where the planner lets one
    blend into the next (tangent join) they are one SPLINE block; at a corner the block ends."""
    from assistant.export import KrlDialect

    rng = np.random.default_rng(11)
    seed = np.radians([0.0, 40.0, 80.0, 60.0, 0.0])
    xs = np.linspace(0.26, 0.34, 9)
    # S1..S8 on a straight-ish curve in x (segments 1 and 2 join tangentially), then a 90 deg
    # corner into y for segment 3.
    pts = [_pos(rv2aj, f"S{k}", (x, -0.05 + 0.001 * np.sin(8 * x), 0.15), seed, rng)
           for k, x in enumerate(xs[1:], 1)]
    corner = [_pos(rv2aj, f"T{k}", (xs[-1], -0.05 + 0.02 * k, 0.15), pts[-1].q, rng)
              for k in range(1, 4)]
    start = _pos(rv2aj, "P0", (xs[0], -0.05, 0.15), seed, rng)
    prog = NeutralProgram("CHAIN", [
        Move(MoveKind.LINEAR, start, speed=0.05, step="draw"),
        Move(MoveKind.SPLINE, pts[3], through=tuple(pts[:3]), speed=0.05, blend_radius=5e-4,
             step="draw"),
        Move(MoveKind.SPLINE, pts[7], through=tuple(pts[4:7]), speed=0.05, step="draw"),
        Move(MoveKind.SPLINE, corner[-1], through=tuple(corner[:-1]), speed=0.05,
             step="draw"),
    ], Frame("pen", make_T(p=[0, 0, 0.1])), q_start=start.q)
    check_program(prog, rv2aj)
    src = KrlDialect().write(prog, rv2aj)[0].text
    blocks = [b.split("ENDSPLINE")[0] for b in src.split("  SPLINE")[1:]]
    assert [b.count("SPL X") for b in blocks] == [8, 3]
    rep = round_trip(prog, "krl", rv2aj)
    assert rep.max_tcp_deviation <= TOLERANCE["krl"] and not rep.instruction_differences


# ------------------------------------------------------------------ the proof can fail
_TAMPER = {
    "melfa": (r"(PB=\(\+)(\d+\.\d+)", lambda v: f"{float(v) + 1.0:.2f}"),
    "krl": (r"(XPB=\{X )(-?\d+\.\d+)", lambda v: f"{float(v) + 1.0:.3f}"),
    "rapid": (r"(PB := \[\[)(-?\d+\.\d+)", lambda v: f"{float(v) + 1.0:.3f}"),
    "urscript": (r"(PB = p\[)(-?\d+\.\d+)", lambda v: f"{float(v) + 0.001:.6f}"),
    "fanuc": (r'(P\[\d+:"PB"\]\{\n   GP1:\n[^\n]*\n\tX = *)(-?\d+\.\d+)',
              lambda v: f"{float(v) + 1.0:.3f}"),
    "yaskawa": (r"(C00002=)(-?\d+\.\d+)", lambda v: f"{float(v) + 1.0:.3f}"),  # PB
}


@pytest.mark.parametrize("dialect", ALL)
def test_a_millimetre_changed_in_the_text_is_seen(robot_for, programs, dialect, monkeypatch):
    robot = robot_for(dialect)
    program = programs(robot)
    d = get_dialect(dialect)
    files = d.write(program, robot)
    rx, bump = _TAMPER[dialect]
    changed = []
    for f in files:
        text, n = re.subn(rx, lambda m: m.group(1) + bump(m.group(2)), f.text, count=1)
        changed.append(ProgramFile(f.name, text, f.mime, f.newline))
        if n:
            break
    else:  # pragma: no cover - the pattern must match
        pytest.fail("tamper pattern did not match")
    changed += files[len(changed):]
    monkeypatch.setattr(type(d), "write", lambda self, prog, robot: changed)
    rep: RoundTripReport = round_trip(program, d, robot, max_step=MAX_STEP.get(dialect, 0.002))
    assert 0.9e-3 < rep.max_tcp_deviation < 1.5e-3


def test_melfa_flags_changed_in_the_text_are_seen(rv2aj, program, monkeypatch):
    """Turning PA's FL1 from ABOVE to BELOW sends the joint move to the other branch."""
    from assistant.export import MelfaDialect

    d = MelfaDialect()
    files = d.write(program, rv2aj)
    pos = files[1]
    assert re.search(r"^PA=\(.*\)\(6,0\)$", pos.text, re.M)
    bad = [files[0], replace(pos, text=re.sub(r"^(PA=\(.*\))\(6,0\)$", r"\1(4,0)", pos.text,
                                              flags=re.M))]
    monkeypatch.setattr(MelfaDialect, "write", lambda self, prog, robot: bad)
    try:
        rep = round_trip(program, d, rv2aj)
    except Exception as e:  # the elbow-down branch may also be out of limits: also detected
        assert "PA" in str(e) or "limit" in str(e)
        return
    assert rep.config_mismatches or rep.max_tcp_deviation > 0.01


# ------------------------------------------------------------------ a six-axis robot (UR5)
def test_urscript_round_trip_on_a_ur5(ur5):
    rng = np.random.default_rng(3)
    q0 = np.array([0.2, -1.4, 1.6, -1.8, -1.57, 0.3])
    T0 = ur5.fk(q0)

    def at(name, dp):
        T = T0.copy()
        T[:3, 3] += np.asarray(dp) + rng.uniform(-5e-4, 5e-4, 3)
        res = ur5.ik(T, q0)
        assert res.ok
        return Position(name, T, res.best(q0))

    a, b, v, c = at("A", (0, 0, 0)), at("B", (0.05, 0.03, -0.02)), at("V", (0.08, 0.06, -0.02)), \
        at("C", (0.05, 0.09, -0.02))
    prog = NeutralProgram("ur5_demo", [
        Move(MoveKind.JOINT, a, speed=0.3, step="start"),
        Move(MoveKind.LINEAR, b, speed=0.1, blend_radius=0.002, step="line"),
        Move(MoveKind.CIRCULAR, c, v, speed=0.05, step="arc"),
        Gripper(1, True, "arc"),
        Move(MoveKind.JOINT, a, speed=0.3, step="back"),
    ], Frame("gripper", ur5.T_flange_tool), q_start=q0)
    rep = round_trip(prog, "urscript", ur5, max_step=0.005)
    assert rep.max_tcp_deviation < 3e-6
    assert not rep.instruction_differences
    text = rep.files[0].text
    assert "movec(V, C, v=0.05, mode=0)" in text and "set_tool_digital_out(0, True)" in text
    # Poses are in the controller's base frame (the URDF's `base`, base_link turned 180 deg
    # about z), as a UR teach pendant shows them: x and y of the model's pose negated.
    m = re.search(r"^  B = p\[([^\]]*)\]", text, re.M)
    assert m, text
    x, y, z = (float(v) for v in m.group(1).split(",")[:3])
    assert np.allclose([x, y, z], [-b.T_base_tool[0, 3], -b.T_base_tool[1, 3],
                                   b.T_base_tool[2, 3]], atol=1e-6)
    assert "# poses in URDF link 'base' (the controller's base frame" in text


def test_dialects_implement_the_protocol():
    from assistant.export import Dialect

    for name in ALL:
        d = get_dialect(name)
        assert isinstance(d, Dialect) and d.name == name and d.file_extensions
        assert d.axis_counts and d.axis_rule


def test_melfa_single_file_and_basic_v(rv2aj, program):
    from assistant.export import MelfaDialect

    single = MelfaDialect(single_file=True)
    files = single.write(program, rv2aj)
    assert [f.name for f in files] == ["EVERY.MB4"]
    body, _, tail = files[0].text.partition(" END\n")
    assert "PA=(" in tail and "PA=(" not in body
    assert round_trip(program, single, rv2aj).max_tcp_deviation <= TOLERANCE["melfa"]
    v = MelfaDialect(variant="V")
    text = v.write(program, rv2aj)[0].text
    assert "JOVRD 40" in text and "OVRD" not in text.replace("JOVRD", "")
    assert v.write(program, rv2aj)[0].name == "EVERY.MB5"
    rep = round_trip(program, v, rv2aj)
    assert rep.max_tcp_deviation <= TOLERANCE["melfa"] and not rep.instruction_differences


def test_long_splines_are_cut_to_fit_the_position_limit(rv2aj, drawing_program):
    from assistant.export import KrlDialect

    d = KrlDialect(max_positions_per_file=6)
    files = d.write(drawing_program, rv2aj)
    assert len(files) > 4
    n_spl = sum(f.text.count("ENDSPLINE") for f in files)
    assert n_spl >= 3  # the 12-point spline was cut into pieces through the same points
    rep = round_trip(drawing_program, d, rv2aj)
    assert rep.max_tcp_deviation < 5e-6


def test_a_five_axis_line_with_a_tilted_tool_keeps_the_tcp_on_the_line(rv2aj):
    from assistant.export.simulate import simulate

    qa = np.radians([-30.0, 30.0, 80.0, 40.0, 10.0])
    qb = np.radians([30.0, 35.0, 75.0, 40.0, -20.0])
    prog = NeutralProgram("T", [Move(MoveKind.LINEAR, Position("B", rv2aj.fk(qb), qb))],
                          q_start=qa)
    tcp = simulate(prog, rv2aj, max_step=0.002).moves[0].tcp
    a, b = rv2aj.fk(qa)[:3, 3], rv2aj.fk(qb)[:3, 3]
    off_line = np.linalg.norm(np.cross(tcp - a, b - a), axis=1) / np.linalg.norm(b - a)
    assert off_line.max() < 1e-9


def test_arc_simulation_follows_the_circle(rv2aj):
    from assistant.export.simulate import circle_through

    p0, pv, p1 = np.array([0.3, -0.05, 0.15]), np.array([0.33, 0.0, 0.16]), np.array(
        [0.3, 0.05, 0.15])
    arc = circle_through(p0, pv, p1)
    pts = arc(np.linspace(0, 1, 201))
    c = np.linalg.solve(np.array([2 * (pv - p0), 2 * (p1 - p0), np.cross(pv - p0, p1 - p0)]),
                        np.array([pv @ pv - p0 @ p0, p1 @ p1 - p0 @ p0,
                                  np.cross(pv - p0, p1 - p0) @ p0]))
    r = np.linalg.norm(pts - c, axis=1)
    assert np.ptp(r) < 1e-12
    assert np.allclose(pts[0], p0) and np.allclose(pts[-1], p1)
    assert np.min(np.linalg.norm(pts - pv, axis=1)) < 1e-3  # passes the via point
