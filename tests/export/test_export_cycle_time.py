"""Predicted cycle time (`assistant.export.cycle_time`): real ruckig profiles, real kinematics.

Properties a time parametrisation must have, the closed-form single-axis time it must agree
with, and the header line every dialect writes from it."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from assistant.export import ExportError, export_files, get_dialect
from assistant.export.cycle_time import CycleTimeLimits, predict_cycle_time
from assistant.export.program import Gripper, Move, MoveKind, NeutralProgram, Position, Wait
from assistant.export.samples import waypoint
from assistant.robots.model import JointLimits
from web.panels.export import cycle_markdown

HEADER = re.compile(r"predicted cycle time (\d+\.\d) s \(a prediction, not measured")
#: ruckig and the closed form solve the same problem exactly; they differ by the root
#: finding's floating-point error only (ruckig's own tolerance is about 1e-12 s).
CLOSED_FORM_TOL = 1e-6


def _at(robot, name: str, q) -> Position:
    q = np.asarray(q, dtype=float)
    return Position(name, robot.fk(q), q)


def _program(robot, q_start, *moves) -> NeutralProgram:
    return NeutralProgram("t", list(moves), q_start=np.asarray(q_start, dtype=float))


Q0 = np.radians([0.0, 20.0, 90.0, 70.0, 0.0])  # elbow up, in front of the base


def _line_program(rv2aj, length: float, speed: float) -> NeutralProgram:
    a = waypoint(rv2aj, "A", [0.25, -0.1, 0.2])
    b = waypoint(rv2aj, "B", [0.25, -0.1 + length, 0.2], seed=a.q)
    return _program(rv2aj, a.q, Move(MoveKind.LINEAR, Position("B", b.T_base_tool, b.q),
                                     speed=speed, step="line"))


# ------------------------------------------------------------------------ closed form
def double_s_time(h: float, v: float, a: float, j: float) -> float:
    """Rest-to-rest time of the jerk-limited (double S) profile over distance h
    (Biagiotti & Melchiorri, Trajectory Planning for Automatic Machines, 3.4)."""
    if math.isinf(j):
        return h / v + v / a if h >= v * v / a else 2.0 * math.sqrt(h / a)
    # Does the profile reach v? The acceleration phase lasts Ta, covering v Ta / 2 ... twice.
    ta = v / a + a / j if v * j >= a * a else 2.0 * math.sqrt(v / j)
    if h >= v * ta:
        return h / v + ta
    tj = a / j
    ta = tj / 2.0 + math.sqrt((tj / 2.0) ** 2 + h / a)
    if ta >= 2.0 * tj:
        return 2.0 * ta
    return 4.0 * (h / (2.0 * j)) ** (1.0 / 3.0)


@pytest.mark.parametrize("jerk_factor", [10.0, None])
@pytest.mark.parametrize("dist_deg", [0.5, 5.0, 20.0, 60.0, 200.0])
@pytest.mark.parametrize("speed", [1.0, 0.3])
def test_one_axis_joint_move_matches_the_closed_form(rv2aj, dist_deg, speed, jerk_factor):
    """J1 alone: ruckig's time equals the textbook trapezoid / double-S time."""
    lim = CycleTimeLimits(jerk_factor=jerk_factor)
    q1 = Q0.copy()
    q1[0] += math.radians(dist_deg)
    prog = _program(rv2aj, Q0, Move(MoveKind.JOINT, _at(rv2aj, "B", q1), speed=speed))
    got = predict_cycle_time(prog, rv2aj, lim).total_s
    v = speed * rv2aj.limits.velocity[0]
    a = lim.acceleration_factor * rv2aj.limits.velocity[0]
    j = math.inf if jerk_factor is None else jerk_factor * a
    assert abs(got - double_s_time(math.radians(dist_deg), v, a, j)) < CLOSED_FORM_TOL


def test_a_longer_joint_move_takes_longer(rv2aj):
    times = []
    for deg in (5.0, 20.0, 45.0, 90.0):
        q1 = Q0 + np.radians([deg, deg / 2, -deg / 3, 0.0, deg])
        prog = _program(rv2aj, Q0, Move(MoveKind.JOINT, _at(rv2aj, "B", q1), speed=0.5))
        times.append(predict_cycle_time(prog, rv2aj).total_s)
    assert all(b > a for a, b in zip(times, times[1:], strict=False)), times


def test_a_move_at_the_speed_limit_takes_at_least_distance_over_speed(rv2aj):
    q1 = Q0 + np.radians([100.0, 30.0, -40.0, 20.0, 150.0])
    prog = _program(rv2aj, Q0, Move(MoveKind.JOINT, _at(rv2aj, "B", q1), speed=1.0))
    t = predict_cycle_time(prog, rv2aj).total_s
    bound = float(np.max(np.abs(q1 - Q0) / rv2aj.limits.velocity))
    assert t >= bound
    assert t < bound + 0.5  # the ramps at 4 x speed per second and 0.1 s jerk take < 0.5 s
    line = _line_program(rv2aj, 0.2, 0.1)
    assert predict_cycle_time(line, rv2aj).total_s >= 0.2 / 0.1


def test_halving_the_speed_of_a_speed_limited_line_about_doubles_its_time(rv2aj):
    """t(v) = L/v + ramp; the ramp (< 0.2 s here) does not double, so the ratio is a bit
    under 2: between 1.8 and 2 for a 0.2 m line at 100 and 50 mm/s. Exactly, the profile
    never reaches the 2 m/s^2 TCP acceleration, so t = L/v + 2 sqrt(v/j)."""
    t1 = predict_cycle_time(_line_program(rv2aj, 0.2, 0.1), rv2aj).total_s
    t2 = predict_cycle_time(_line_program(rv2aj, 0.2, 0.05), rv2aj).total_s
    assert 1.8 < t2 / t1 <= 2.0, (t1, t2)
    j = CycleTimeLimits().tcp_jerk
    for t, v in ((t1, 0.1), (t2, 0.05)):
        assert abs(t - (0.2 / v + 2.0 * math.sqrt(v / j))) < 1e-3  # sampled path length


def test_blends_shorten_the_total(rv2aj, frame_program):
    """Frame 1's strokes and arcs blend into each other; without blends each one stops."""
    blended = predict_cycle_time(frame_program, rv2aj)
    stopped = predict_cycle_time(replace(frame_program, instructions=[
        replace(i, blend_radius=0.0) if isinstance(i, Move) else i
        for i in frame_program.instructions]), rv2aj)
    assert any(isinstance(i, Move) and i.blend_radius > 0 for i in frame_program.instructions)
    assert blended.total_s < stopped.total_s - 0.1, (blended.total_s, stopped.total_s)
    # Blended joint moves: the stop in between is skipped too.
    qa = Q0 + np.radians([30.0, 10.0, 0.0, 0.0, 0.0])
    qb = qa + np.radians([30.0, 0.0, -20.0, 0.0, 0.0])
    moves = [Move(MoveKind.JOINT, _at(rv2aj, "A", qa), speed=0.5, blend_radius=0.02),
             Move(MoveKind.JOINT, _at(rv2aj, "B", qb), speed=0.5)]
    with_blend = predict_cycle_time(_program(rv2aj, Q0, *moves), rv2aj).total_s
    moves[0] = replace(moves[0], blend_radius=0.0)
    without = predict_cycle_time(_program(rv2aj, Q0, *moves), rv2aj).total_s
    assert with_blend < without, (with_blend, without)


def test_total_is_the_sum_of_moves_waits_and_gripper_actions(rv2aj, thesis_program):
    base = predict_cycle_time(thesis_program, rv2aj)
    assert base.total_s == pytest.approx(sum(e.seconds for e in base.entries), abs=1e-12)
    grips = sum(isinstance(i, Gripper) for i in thesis_program.instructions)
    assert grips >= 1
    assert base.total_s == pytest.approx(base.moves_s() + 0.3 * grips, abs=1e-12)
    waited = replace(thesis_program, instructions=[*thesis_program.instructions[:3],
                                                  Wait(1.25, "dwell"),
                                                  *thesis_program.instructions[3:]])
    got = predict_cycle_time(waited, rv2aj)
    # A wait stops the arm; the moves around it did not blend, so nothing else changes.
    assert got.total_s - base.total_s == pytest.approx(1.25, abs=1e-9)
    assert [e.kind for e in got.entries].count("wait") == 1
    steps = dict(got.by_step())
    assert steps["dwell"] == pytest.approx(1.25)


@pytest.mark.parametrize("bad", ["speed", "blend", "position", "wait", "limits"])
def test_bad_input_is_a_clear_export_error(rv2aj, thesis_program, bad):
    ins = list(thesis_program.instructions)
    k = next(i for i, x in enumerate(ins) if isinstance(x, Move) and x.kind == MoveKind.LINEAR)
    m = ins[k]
    if bad == "speed":
        ins[k] = replace(m, speed=float("nan"))
        match = "step 'P4->P5': speed is not a finite number"
    elif bad == "blend":
        ins[k] = replace(m, blend_radius=float("inf"))
        match = "blend radius is not a finite number"
    elif bad == "position":
        T = m.target.T_base_tool.copy()
        T[0, 3] = float("nan")
        ins[k] = replace(m, target=replace(m.target, T_base_tool=T))
        match = "position 'P5' is not a finite number"
    elif bad == "wait":
        ins.insert(k, Wait(float("nan"), "dwell"))
        match = "step 'dwell': wait is not a finite number"
    else:
        with pytest.raises(ExportError, match="cycle time limit tcp_acceleration"):
            CycleTimeLimits(tcp_acceleration=-1.0)
        with pytest.raises(ExportError, match="3 values for 5 joints"):
            predict_cycle_time(thesis_program, rv2aj, CycleTimeLimits(acceleration=(1, 2, 3)))
        return
    with pytest.raises(ExportError, match=re.escape(match)):
        predict_cycle_time(replace(thesis_program, instructions=ins), rv2aj)


@pytest.mark.parametrize("velocity", [np.zeros(5), np.full(5, np.nan), np.ones(4)])
def test_a_robot_without_speed_limits_is_refused(rv2aj, thesis_program, velocity):
    import copy

    blind = copy.copy(rv2aj)
    blind.limits = JointLimits(rv2aj.limits.lower, rv2aj.limits.upper, velocity)
    with pytest.raises(ExportError, match="has no joint speed limits for all its 5 joints"):
        predict_cycle_time(thesis_program, blind)
    with pytest.raises(ExportError, match="cycle time cannot be predicted"):
        export_files(thesis_program, "melfa", blind)


@pytest.mark.parametrize("dialect", ["melfa", "krl", "rapid"])
def test_every_dialect_writes_the_predicted_total_in_its_header(rv2aj, thesis_program, dialect):
    result = export_files(thesis_program, dialect, rv2aj)
    ct = result.cycle_time
    assert ct is not None and ct.total_s > 0
    main = result.files[0].data.decode("ascii")
    head = main.splitlines()[:6]
    found = [HEADER.search(line) for line in head]
    assert sum(f is not None for f in found) == 1, head
    secs = float(next(f for f in found if f).group(1))
    assert abs(secs - ct.total_s) <= 0.05  # written with one decimal
    # The reader still reads the file (export_files verified it) and skips the line.
    back = get_dialect(dialect).read([replace_file(f) for f in result.files], rv2aj)
    assert len(back.moves()) == result.primitives


@pytest.mark.parametrize("dialect", ["fanuc", "yaskawa"])
def test_thirty_two_character_comments_carry_the_total_and_the_caveat(rv2aj, thesis_program,
                                                                      dialect):
    """FANUC and INFORM comments hold 32 characters: the total is a comment line of its own
    near the top, the caveat wraps onto the next ones (INFORM's job comment holds it too)."""
    result = export_files(thesis_program, dialect, rv2aj)
    ct = result.cycle_time
    rows = result.files[0].data.decode("ascii").splitlines()
    # a comment's text: after "!" (FANUC, up to " ;") or "'" (INFORM)
    texts = [m.group(1).strip() for row in rows
             if (m := re.search(r"^\s*(?:\d+:\s*!|')([^;]*)", row))]
    found = [k for k, t in enumerate(texts) if re.fullmatch(r"predicted cycle time \d+\.\d s", t)]
    assert len(found) == 1, texts[:10]
    assert found[0] <= 3  # in the header: after the name and the robot
    secs = float(texts[found[0]].split()[-2])
    assert abs(secs - ct.total_s) <= 0.05  # written with one decimal
    assert " ".join(texts[found[0] + 1:found[0] + 3]) == \
        "(a prediction, not measured on a controller)"
    if dialect == "yaskawa":
        assert f"///COMM predicted cycle time {secs:.1f} s" in rows


def replace_file(f):
    from assistant.export.dialect import ProgramFile

    return ProgramFile(f.name, f.data.decode("ascii").replace("\r\n", "\n"))


def test_the_export_panel_shows_the_total_and_seconds_per_step(rv2aj, thesis_program):
    result = export_files(thesis_program, "melfa", rv2aj)
    md = cycle_markdown(result)
    assert f"**{result.cycle_time.total_s:.1f} s**" in md
    assert "not measured on a controller" in md
    for step, sec in result.cycle_time.by_step():
        assert f"| {step} | {sec:.2f} |" in md


def test_collinear_blended_lines_take_as_long_as_one_line(rv2aj):
    """Four blended pieces of one straight line pass their junctions at full speed: the
    time equals the single line's (to the path sampling, < 1 %); unblended, each stops."""
    one = _line_program(rv2aj, 0.2, 0.1)
    a = waypoint(rv2aj, "A", [0.25, -0.1, 0.2])
    pieces, seed = [], a.q
    for k in range(1, 5):
        w = waypoint(rv2aj, f"B{k}", [0.25, -0.1 + 0.05 * k, 0.2], seed=seed)
        seed = w.q
        pieces.append(Move(MoveKind.LINEAR, Position(w.name, w.T_base_tool, w.q), speed=0.1,
                           blend_radius=0.01 if k < 4 else 0.0, step="line"))
    t_one = predict_cycle_time(one, rv2aj).total_s
    t_blended = predict_cycle_time(_program(rv2aj, a.q, *pieces), rv2aj).total_s
    stopped = [replace(m, blend_radius=0.0) for m in pieces]
    t_stopped = predict_cycle_time(_program(rv2aj, a.q, *stopped), rv2aj).total_s
    assert abs(t_blended - t_one) < 0.01 * t_one, (t_blended, t_one)
    # Each of the 3 extra stops adds one ramp down and up: 2 sqrt(v/j) (closed form above).
    ramp = 2.0 * math.sqrt(0.1 / CycleTimeLimits().tcp_jerk)
    assert t_stopped - t_one == pytest.approx(3 * ramp, abs=2e-3), (t_stopped, t_one)
