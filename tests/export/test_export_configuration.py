"""Configuration flags from joint solutions: MELFA FL1/FL2, KUKA S/T, ABB confdata."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.export import KrlDialect, MelfaDialect, Position, RapidDialect
from assistant.export.configuration import (
    FLANGE,
    arm_configuration,
    axis_slots,
    quadrant,
    turn_count,
)
from assistant.robots.rv2aj import L2, L3, L6


def _random_q(robot, rng, n):
    lo, hi = robot.limits.lower, robot.limits.upper
    return rng.uniform(lo, hi, size=(n, robot.dof))


def test_rv2aj_axes_map_to_controller_slots_without_a4(rv2aj):
    assert axis_slots(rv2aj) == [1, 2, 3, 5, 6]


def test_geometric_flags_match_the_rv2aj_closed_form(rv2aj, rng):
    """RIGHT = flange in front of the J1 axis; ABOVE = J3 >= 0 (elbow up)."""
    for q in _random_q(rv2aj, rng, 300):
        q1, q2, q3, q5, q6 = q
        r_flange = L2 * np.sin(q2) + L3 * np.sin(q2 + q3) + L6 * np.sin(q2 + q3 + q5)
        r_wrist = L2 * np.sin(q2) + L3 * np.sin(q2 + q3)
        flange = arm_configuration(rv2aj, q, front_reference=FLANGE)
        wrist = arm_configuration(rv2aj, q)
        if abs(r_flange) > 1e-6:
            assert flange.front == (r_flange > 0.0)
        if abs(r_wrist) > 1e-6:
            assert wrist.front == (r_wrist > 0.0)
        if abs(q3) > 1e-6:
            assert wrist.elbow_up == (q3 > 0.0)
        assert wrist.wrist_negative == (q5 < 0.0)


def test_melfa_fl1_distinguishes_the_ik_branches_of_one_pose(rv2aj):
    """One TCP pose, the elbow-up and elbow-down solutions: (6,0) vs (4,0)."""
    T = rv2aj.fk(np.radians([-20.0, 70.0, -40.0, 80.0, 10.0]))
    sols = rv2aj.ik(T).solutions
    flags = {MelfaDialect.flags(rv2aj, Position("P", T, q)) for q in sols}
    up = [q for q in sols if q[2] > 0]
    down = [q for q in sols if q[2] < 0]
    assert up and down
    assert MelfaDialect.flags(rv2aj, Position("P", T, up[0])) == (6, 0)
    assert MelfaDialect.flags(rv2aj, Position("P", T, down[0]))[0] == 4
    assert len(flags) >= 2


def test_melfa_left_and_fl2_turns(rv2aj):
    q = np.radians([10.0, -40.0, 30.0, -20.0, 190.0])  # leaning back: flange behind J1
    fl1, fl2 = MelfaDialect.flags(rv2aj, Position("P", None, q))
    assert fl1 & 4 == 0  # LEFT
    assert fl1 & 2 == 2  # J3 > 0: ABOVE
    assert fl2 == 1 << 20  # J6 one turn up, in the J6 nibble
    q[4] = np.radians(-190.0)
    assert MelfaDialect.flags(rv2aj, Position("P", None, q))[1] == 0xF << 20
    q[4] = np.radians(170.0)
    assert MelfaDialect.flags(rv2aj, Position("P", None, q))[1] == 0


def test_kuka_status_and_turn(rv2aj):
    q = np.radians([-30.0, 20.0, 90.0, 60.0, 10.0])
    s, t = KrlDialect.status_turn(rv2aj, Position("P", None, q))
    assert s == 2  # in front, A3 >= phi (elbow up), A5 > 0
    assert t == 1  # only A1 negative
    q = np.radians([30.0, -50.0, -30.0, -40.0, -10.0])
    s, t = KrlDialect.status_turn(rv2aj, Position("P", None, q))
    assert s == 1 + 0 + 4  # behind (overhead area), elbow down, A5 < 0
    assert t == (1 << 1) | (1 << 2) | (1 << 4) | (1 << 5)  # A2, A3, A5, A6 (no A4)


def test_abb_confdata(rv2aj):
    q = np.radians([-30.0, 20.0, 90.0, -60.0, 100.0])
    assert RapidDialect.confdata(rv2aj, Position("P", None, q)) == (-1, 0, 1, 1)
    q = np.radians([100.0, -50.0, -30.0, 40.0, -100.0])
    assert RapidDialect.confdata(rv2aj, Position("P", None, q)) == (1, 0, -2, 4 + 2)


@pytest.mark.parametrize("deg, turns, quad", [(0, 0, 0), (179, 0, 1), (180, 0, 2), (181, 1, 2),
                                              (-179, 0, -2), (-181, -1, -3), (359, 1, 3),
                                              (-90, 0, -1), (89.9, 0, 0)])
def test_turn_and_quadrant_numbers(deg, turns, quad):
    assert turn_count(np.radians(deg)) == turns
    assert quadrant(np.radians(deg)) == quad


@pytest.mark.parametrize("dialect", ["melfa", "krl", "rapid", "fanuc", "yaskawa"])
def test_flags_read_back_select_the_planned_branch(rv2aj, dialect):
    """Write the elbow-down solution of a pose; the reader's flags must pick it again."""
    from assistant.export import Move, MoveKind, NeutralProgram, get_dialect
    from assistant.export.simulate import simulate

    down = np.radians([-20.0, 70.0, -40.0, 80.0, 10.0])
    T = rv2aj.fk(down)
    home = np.radians([0.0, 20.0, 90.0, 30.0, 0.0])
    prog = NeutralProgram("branch", [Move(MoveKind.JOINT, Position("PD", T, down), speed=0.5)],
                          q_start=home)
    d = get_dialect(dialect)
    back = d.read(d.write(prog, rv2aj), rv2aj)
    q_end = simulate(back, rv2aj, home).moves[0].q[-1]
    assert np.allclose(q_end, down, atol=1e-3)
    # The nearest solution to the start is the elbow-up one: without flags it would be taken.
    nearest = min(rv2aj.ik(T).solutions, key=lambda s: float(np.linalg.norm(s - home)))
    assert nearest[2] > 0
