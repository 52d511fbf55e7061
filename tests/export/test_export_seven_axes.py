"""A 7-axis arm exported in RAPID and KRL (issue 32 item 5): the vendors' conventions.

RAPID (ABB IRB 14000 YuMi): the third joint along the chain is the external axis eax_a of
jointtargets and robtargets, the others rax_1..rax_6. KRL (KUKA LBR): the third joint is E1
of E6AXIS and E6POS, the others A1..A6 (`assistant.export.redundant_axis`). The Panda from
example-robot-data is the arm; its program has a joint move to a Cartesian target, an arc, a
line and a joint move to an axis target, planned along one IK branch with joint 3 moving
(every joint value distinct, so a swapped mapping shows as a wrong number).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from grammars import check_report
from test_export_axes import chain_urdf

from assistant.export import (
    ExportError,
    Frame,
    Move,
    MoveKind,
    NeutralProgram,
    Position,
    export_files,
    get_dialect,
    predict_cycle_time,
    round_trip,
)
from assistant.export.dialect import ProgramFile
from assistant.export.redundant_axis import (
    SEVEN_AXIS_SLOTS,
    axis_values,
    joints_from_axes,
    solve_pinned,
)
from assistant.robots.urdf_robot import URDFRobot
from assistant.transforms import make_T, rot_x

#: Panda "ready" posture the targets are solved from, one after the other.
READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
#: Targets (m, tool down) and the value joint 3 is held at in each (rad).
TARGETS = {"P1": ((0.45, -0.15, 0.35), 0.20), "P2": ((0.50, -0.10, 0.30), 0.25),
           "P3": ((0.55, 0.0, 0.28), 0.30), "P4": ((0.50, 0.10, 0.30), 0.35),
           "P5": ((0.40, 0.15, 0.35), 0.30), "P6": ((0.42, 0.0, 0.40), 0.10)}
#: A value written with 3 decimals is within half a unit of the last place (+ float noise).
HALF_MDEG = 0.0005 + 1e-9


@pytest.fixture(scope="module")
def seven(panda) -> NeutralProgram:
    pos = {}
    prev = READY
    for name, (xyz, q3) in TARGETS.items():
        T = make_T(rot_x(np.pi), np.array(xyz))
        sols = solve_pinned(panda, T, 2, q3, [prev])
        assert sols, name
        prev = sols[0]
        pos[name] = Position(name, T, prev, None, joint_target=name == "P6")
    return NeutralProgram("seven", [
        Move(MoveKind.JOINT, pos["P2"], speed=0.3, step="to P2"),
        Move(MoveKind.CIRCULAR, pos["P4"], pos["P3"], speed=0.1, step="arc"),
        Move(MoveKind.LINEAR, pos["P5"], speed=0.1, step="line"),
        Move(MoveKind.JOINT, pos["P6"], speed=0.3, step="back"),
    ], Frame("tool"), q_start=pos["P1"].q)


def _q(program: NeutralProgram, name: str) -> np.ndarray:
    return next(p.q for m in program.moves() for p in m.positions() if p.name == name)


def _text(files: list[ProgramFile], suffix: str) -> str:
    return next(f.text for f in files if f.name.endswith(suffix))


def _floats(text: str) -> list[float]:
    return [float(v) for v in re.findall(r"[-+]?\d+\.\d+|9E\+09", text)]


def test_the_program_can_tell_a_swapped_mapping(seven):
    """Every joint value differs from every other by far more than the file's precision,
    so writing e.g. joint 7 as the external axis gives other numbers in every test below."""
    for name in ("P2", "P3", "P4", "P5", "P6"):
        deg = np.degrees(_q(seven, name))
        gaps = np.abs(deg[:, None] - deg[None, :])[~np.eye(7, dtype=bool)]
        assert gaps.min() > 0.01, name


def test_the_mapping_is_the_vendors_and_undoes_itself():
    assert SEVEN_AXIS_SLOTS == (1, 2, 7, 3, 4, 5, 6)
    q = np.array([10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0])
    main, ext = axis_values(SEVEN_AXIS_SLOTS, q)
    assert main.tolist() == [10.0, 20.0, 40.0, 50.0, 60.0, 70.0] and ext == 30.0
    assert joints_from_axes(SEVEN_AXIS_SLOTS, main, ext).tolist() == q.tolist()
    with pytest.raises(ValueError, match="external axis has no value"):
        joints_from_axes(SEVEN_AXIS_SLOTS, main, None)


# ------------------------------------------------------------------ RAPID: eax_a
def test_rapid_writes_the_third_joint_as_eax_a(panda, seven):
    files = get_dialect("rapid").write(seven, panda)
    text = _text(files, ".mod")
    decl = dict(re.findall(r"CONST (?:robtarget|jointtarget) (\w+) := (.*);", text))
    assert set(decl) == {"P2", "P3", "P4", "P5", "P6"}
    # MoveAbsJ target: [[rax_1..rax_6],[eax_a, 9E9 x5]] = joints 1, 2, 4, 5, 6, 7 and 3
    vals = _floats(decl["P6"])
    deg = np.degrees(_q(seven, "P6"))
    assert decl["P6"].endswith(",9E+09,9E+09,9E+09,9E+09,9E+09]]")
    assert np.abs(np.array(vals[:6]) - deg[[0, 1, 3, 4, 5, 6]]).max() <= HALF_MDEG
    assert abs(vals[6] - deg[2]) <= HALF_MDEG
    # robtargets: [[x,y,z],[q1..q4],[cf1,cf4,cf6,cfx],[eax_a, 9E9 x5]], eax_a = the arm
    # angle the planned posture has (joint 3)
    for name in ("P2", "P3", "P4", "P5"):
        ext = decl[name].rsplit("],[", 1)[1]
        eax_a, *rest = ext.rstrip("]").split(",")
        assert rest == ["9E+09"] * 5, name
        assert abs(float(eax_a) - np.degrees(_q(seven, name)[2])) <= HALF_MDEG, name
    assert check_report("rapid", {f.name: f.data for f in files}).problems == []


def test_rapid_reads_eax_a_back(panda, seven):
    d = get_dialect("rapid")
    back = d.read(d.write(seven, panda), panda)
    pos = {p.name: p for m in back.moves() for p in m.positions()}
    assert np.abs(np.degrees(pos["P6"].q - _q(seven, "P6"))).max() <= HALF_MDEG
    for name in ("P2", "P3", "P4", "P5"):
        joint, value = pos[name].config.redundant
        assert joint == 2
        assert abs(np.degrees(value - _q(seven, name)[2])) <= HALF_MDEG


def test_an_edited_eax_a_is_what_the_reader_holds(panda, seven):
    """The reader takes the arm angle from the file, not from anywhere else."""
    d = get_dialect("rapid")
    files = d.write(seven, panda)
    text = files[0].text
    line = next(ln for ln in text.splitlines() if "robtarget P5 " in ln)
    eax_a = float(line.rsplit("],[", 1)[1].split(",")[0])
    edited = line.replace(f"[{eax_a:.3f},9E+09", "[25.000,9E+09")
    assert edited != line
    back = d.read([ProgramFile(files[0].name, text.replace(line, edited))], panda)
    p5 = next(p for m in back.moves() for p in m.positions() if p.name == "P5")
    assert p5.config.redundant == (2, pytest.approx(np.radians(25.0), abs=1e-12))


# ------------------------------------------------------------------ KRL: E1
def test_krl_writes_the_third_joint_as_e1(panda, seven):
    files = get_dialect("krl").write(seven, panda)
    dat = _text(files, ".dat")
    decl = {n: dict(item.split() for item in body.split(","))
            for n, body in re.findall(r"DECL E6(?:POS|AXIS) X(\w+)=\{(.*)\}", dat)}
    assert set(decl) == {"P2", "P3", "P4", "P5", "P6"}
    deg = np.degrees(_q(seven, "P6"))
    axes = np.array([float(decl["P6"][f"A{k}"]) for k in range(1, 7)])
    assert np.abs(axes - deg[[0, 1, 3, 4, 5, 6]]).max() <= HALF_MDEG
    assert abs(float(decl["P6"]["E1"]) - deg[2]) <= HALF_MDEG
    for name in ("P2", "P3", "P4", "P5"):
        q = _q(seven, name)
        assert abs(float(decl[name]["E1"]) - np.degrees(q[2])) <= HALF_MDEG, name
        assert [decl[name][f"E{k}"] for k in range(2, 7)] == ["0.0"] * 5
        # Turn bits of A1..A6 only (joints 1, 2, 4, 5, 6, 7): E1 has none
        want_t = sum(1 << k for k, v in enumerate(q[[0, 1, 3, 4, 5, 6]]) if v < 0.0)
        assert int(decl[name]["T"]) == want_t, name
    assert check_report("krl", {f.name: f.data for f in files}).problems == []


def test_krl_reads_e1_back(panda, seven):
    d = get_dialect("krl")
    back = d.read(d.write(seven, panda), panda)
    pos = {p.name: p for m in back.moves() for p in m.positions()}
    assert np.abs(np.degrees(pos["XP6"].q - _q(seven, "P6"))).max() <= HALF_MDEG
    for name in ("P2", "P3", "P4", "P5"):
        joint, value = pos["X" + name].config.redundant
        assert joint == 2
        assert abs(np.degrees(value - _q(seven, name)[2])) <= HALF_MDEG


# ------------------------------------------------------------------ the round trip
@pytest.mark.parametrize("dialect", ["rapid", "krl"])
def test_a_seven_axis_program_round_trips(panda, seven, dialect):
    """Joint, circular, linear and axis moves read back onto the planned path.

    What remains is the number format: joint values with 3 decimals of a degree (each off by
    at most 0.0005 deg) move the TCP by at most that angle times its distance from each
    axis (`arm_radii`), summed; millimetres with 3 decimals are far below that."""
    rep = round_trip(seven, dialect, panda)
    bound = np.radians(0.0005) * float(panda.arm_radii().sum())
    assert rep.primitives == 4 and not rep.instruction_differences
    assert rep.config_mismatches == ()
    assert rep.max_tcp_deviation <= bound, (rep.per_move, bound)


@pytest.mark.parametrize("dialect", ["rapid", "krl"])
def test_a_seven_axis_program_downloads_with_its_checks(panda, seven, dialect):
    res = export_files(seven, dialect, panda)
    assert res.dialect == dialect and res.primitives == 4
    assert 0.5 < res.cycle_time.total_s < 60.0
    head = res.files[0].data.decode("ascii")
    assert res.cycle_time.header_text() in head and "for panda" in head
    # the prediction runs on its own (its path follower has no IK restarts) to the same time
    alone = predict_cycle_time(seven, panda).total_s
    assert alone == pytest.approx(res.cycle_time.total_s, abs=0.05)


def test_a_read_back_arm_angle_that_was_changed_moves_the_arm_elsewhere(panda, seven):
    """A robtarget reached by MoveJ with another eax_a: the same TCP at the target, another
    posture, so the joint move there takes another path."""
    d = get_dialect("rapid")
    files = d.write(seven, panda)
    text = files[0].text
    line = next(ln for ln in text.splitlines() if "robtarget P2 " in ln)
    eax_a = float(line.rsplit("],[", 1)[1].split(",")[0])
    changed = text.replace(line, line.replace(f"[{eax_a:.3f},", f"[{eax_a + 5.0:.3f},"))
    from assistant.export.simulate import simulate

    good = simulate(d.read(files, panda), panda, seven.q_start)
    bad = simulate(d.read([ProgramFile(files[0].name, changed)], panda), panda, seven.q_start,
                   samples=good.sample_counts())
    at_p2 = bad.moves[0].q[-1]
    assert abs(np.degrees(at_p2[2]) - (eax_a + 5.0)) < 1e-6
    assert np.allclose(panda.fk(at_p2), panda.fk(good.moves[0].q[-1]), atol=1e-7)
    # the joint move there bends the TCP path (20x the number format's bound: 5 um) ...
    assert np.linalg.norm(good.moves[0].tcp - bad.moves[0].tcp, axis=1).max() > 1e-4
    # ... and the next target's own eax_a puts the arm back on the planned posture
    assert np.abs(good.moves[2].q[-1] - bad.moves[2].q[-1]).max() < 1e-6


# ------------------------------------------------------------------ any 7-axis URDF
@pytest.mark.parametrize("dialect,external", [("rapid", r"\[\[10\.000,20\.000,40\.000,"
                                               r"50\.000,60\.000,70\.000\],\[30\.000,9E\+09"),
                                              ("krl", r"A1 10\.000,A2 20\.000,A3 40\.000,"
                                               r"A4 50\.000,A5 60\.000,A6 70\.000,E1 30\.000,")])
def test_a_generic_seven_axis_urdf_writes_joint_3_as_the_external_axis(tmp_path, dialect,
                                                                       external):
    robot = URDFRobot.from_string(chain_urdf(7), base_dir=tmp_path, load_visual=False)
    q = np.radians([10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0])
    prog = NeutralProgram("chain", [Move(MoveKind.JOINT, Position("P1", None, q,
                                                                   joint_target=True))],
                          Frame("tool"), q_start=np.zeros(7))
    files = get_dialect(dialect).write(prog, robot)
    assert re.search(external, "\n".join(f.text for f in files))
    back = get_dialect(dialect).read(files, robot)
    assert np.allclose(back.moves()[0].target.q, q, atol=1e-12)


def test_a_jointtarget_without_eax_a_is_refused_for_a_seven_axis_arm(panda, seven):
    d = get_dialect("rapid")
    files = d.write(seven, panda)
    text = re.sub(r"(jointtarget P6 := \[\[[^\]]*\]),\[[-\d.]+,", r"\1,[9E+09,", files[0].text)
    with pytest.raises(ExportError, match="P6: the 7-axis arm's external axis eax_a is 9E9"):
        d.read([ProgramFile(files[0].name, text)], panda)


def test_an_e6pos_without_e1_is_refused_for_a_seven_axis_arm(panda, seven):
    d = get_dialect("krl")
    files = d.write(seven, panda)
    dat = next(f for f in files if f.name.endswith(".dat"))
    text = re.sub(r"(DECL E6POS XP3=\{[^}]*),E1 [-\d.]+", r"\1", dat.text)
    assert text != dat.text
    files = [f if f is not dat else ProgramFile(f.name, text) for f in files]
    with pytest.raises(ExportError, match="XP3: the 7-axis arm's external axis E1 is missing"):
        d.read(files, panda)
