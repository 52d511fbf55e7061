"""The simulated robot: timing at the speed limits, stop from another thread, hidden obstacles."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from link_fixtures import HOME, Q_A, Q_B, box_on_sweep, sweep

from assistant.collision.checker import CollisionChecker
from assistant.links.link import LinkError, LinkEventKind
from assistant.links.simulated import SimulatedRobot
from assistant.links.timing import RealClock, VirtualClock, time_parametrize, validate_path


def connected(robot, **kw) -> SimulatedRobot:
    sim = SimulatedRobot(robot, **kw)
    sim.connect()
    return sim


def record(link) -> list:
    events: list = []
    link.subscribe(events.append)
    return events


def test_moves_at_the_slowest_joints_speed_limit_on_a_virtual_clock(rv2aj):
    clock = VirtualClock()
    sim = connected(rv2aj, clock=clock, event_period_s=0.02)
    events = record(sim)
    # J1 turns 90 deg (180 deg/s -> 0.5 s), J2 30 deg (90 deg/s -> 0.333 s): J1 decides.
    goal = np.radians([90.0, 30.0, 0.0, 0.0, 0.0])
    ev = sim.move_path(np.array([np.zeros(5), goal]))
    assert ev.kind == LinkEventKind.REACHED and ev.path_index == 1
    assert clock.now() == pytest.approx(0.5, abs=1e-9)
    assert np.allclose(sim.current_joints(), goal)
    moved = [e for e in events if e.kind == LinkEventKind.MOVED]
    # A MOVED every 20 ms of robot time, the last step ends in REACHED.
    assert len(moved) == 24
    assert np.allclose(np.diff([e.time_s for e in moved]), 0.02)
    # Between events no joint exceeds its limit and J1 runs exactly at its limit.
    qs = np.array([np.zeros(5)] + [e.q for e in moved])
    speed = np.abs(np.diff(qs, axis=0)) / 0.02
    assert np.all(speed <= rv2aj.limits.velocity * (1 + 1e-9))
    assert np.allclose(speed[:, 0], rv2aj.limits.velocity[0])
    assert np.allclose(speed[:, 1], rv2aj.limits.velocity[0] * 30.0 / 90.0)


def test_speed_scale_and_a_first_leg_from_where_the_robot_is(rv2aj):
    clock = VirtualClock()
    sim = connected(rv2aj, clock=clock)
    a = np.radians([45.0, 0.0, 0.0, 0.0, 0.0])
    b = np.radians([45.0, 0.0, 0.0, 0.0, 90.0])
    # The robot is at 0: it first goes to a (0.25 s), then to b at half speed.
    ev = sim.move_path(np.array([a, b]), speed_scale=0.5)
    assert ev.kind == LinkEventKind.REACHED and ev.path_index == 1
    expected = (np.radians(45.0) / rv2aj.limits.velocity[0]
                + np.radians(90.0) / rv2aj.limits.velocity[4]) / 0.5
    assert clock.now() == pytest.approx(expected, abs=1e-9)


def test_time_parametrize_and_validate_path(rv2aj):
    tp = time_parametrize(np.radians([[0, 0, 0, 0, 0], [18, 9, 0, 0, 0], [18, 9, 27, 0, 0]]),
                          rv2aj.limits.velocity)
    assert np.allclose(tp.t, [0.0, 0.1, 0.3])
    q, seg = tp.sample(0.2)
    assert seg == 1 and np.allclose(np.degrees(q), [18, 9, 13.5, 0, 0])
    with pytest.raises(LinkError, match="J1=170.0 deg outside"):
        validate_path(rv2aj, np.radians([[0, 0, 0, 0, 0], [170, 0, 0, 0, 0]]))
    with pytest.raises(LinkError, match="speed_scale"):
        time_parametrize(tp.q, rv2aj.limits.velocity, 1.5)


def test_stop_from_another_thread_ends_the_move_where_it_is(rv2aj):
    # Wall time: the whole path would take 2.3 s; the stop comes right after the first event.
    sim = connected(rv2aj, clock=RealClock(time_scale=1.0), event_period_s=0.02)
    first_move = threading.Event()
    sim.subscribe(lambda e: first_move.set() if e.kind == LinkEventKind.MOVED else None)
    stopper = threading.Thread(target=lambda: first_move.wait(30.0) and sim.stop())
    stopper.start()
    path = sweep(np.radians([-140.0, 0, 0, 0, 0]), np.radians([140.0, 0, 0, 0, 0]), 11)
    # (the robot first travels from 0 to -140 deg, then sweeps to +140)
    ev = sim.move_path(path)
    stopper.join(timeout=30.0)
    assert not stopper.is_alive()
    assert ev.kind == LinkEventKind.STOPPED
    q = sim.current_joints()
    assert np.allclose(q, ev.q)
    assert ev.path_index < len(path) - 1 and q[0] < np.radians(140.0) - 0.1
    assert q[0] != 0.0  # it had started
    # The next move starts from there and completes.
    sim.clock = VirtualClock()
    assert sim.move_path(np.array([HOME])).kind == LinkEventKind.REACHED


def test_hidden_box_stops_the_arm_at_the_last_free_posture(rv2aj):
    box = box_on_sweep(rv2aj, Q_A, Q_B, 0.5)
    sim = connected(rv2aj, clock=VirtualClock(), hidden_obstacles=[box], start_q=Q_A)
    events = record(sim)
    path = sweep(Q_A, Q_B, 5)  # vertices at 0, .25, .5, .75, 1 of the sweep
    ev = sim.move_path(path)
    assert ev.kind == LinkEventKind.COLLISION_INDICATED
    assert ev.details["obstacles"] == ["hidden"] and ev.details["source"] == "hidden_obstacle"
    # The first contact along the sweep, found independently by dense FCL sampling.
    chk = CollisionChecker(rv2aj, [box], self_collision=False)
    fr = np.linspace(0.0, 1.0, 20001)
    hit = np.nonzero(~chk.is_valid_batch(Q_A[None] + fr[:, None] * (Q_B - Q_A)[None]))[0]
    f_contact = fr[hit[0]]
    f_stop = (ev.q[0] - Q_A[0]) / (Q_B[0] - Q_A[0])
    assert chk.is_valid(ev.q)  # free ...
    assert f_stop < f_contact  # ... before the contact ...
    arm_gap = float(np.sum(rv2aj.arm_radii() * np.abs((f_contact - f_stop) * (Q_B - Q_A))))
    assert arm_gap <= 0.005 + 1e-9  # ... by no more than one 5 mm check step
    assert ev.path_index == int(f_contact // 0.25)  # the segment being executed
    assert all(chk.is_valid(e.q) for e in events if e.kind == LinkEventKind.MOVED)
    # The planner backs off along a free path: that works from the reported posture.
    assert sim.move_path(np.array([ev.q, HOME])).kind == LinkEventKind.REACHED


def test_same_path_gives_the_same_events(rv2aj):
    box = box_on_sweep(rv2aj, Q_A, Q_B, 0.6)

    def run() -> list[tuple]:
        sim = connected(rv2aj, clock=VirtualClock(), hidden_obstacles=[box], start_q=Q_A)
        events = record(sim)
        sim.move_path(sweep(Q_A, Q_B, 7))
        return [(e.kind, e.time_s, e.path_index, tuple(np.round(e.q, 12))) for e in events]

    assert run() == run()


def test_operator_button_while_moving_and_when_idle(rv2aj):
    sim = connected(rv2aj, clock=VirtualClock(), event_period_s=0.02, start_q=Q_A)
    events = record(sim)
    count = {"moved": 0}

    def press_on_fifth(e):
        if e.kind == LinkEventKind.MOVED:
            count["moved"] += 1
            if count["moved"] == 5:
                sim.indicate_collision("operator saw the gripper touch the fixture")

    sim.subscribe(press_on_fifth)
    ev = sim.move_path(sweep(Q_A, Q_B, 3))
    assert ev.kind == LinkEventKind.COLLISION_INDICATED
    assert ev.details["source"] == "operator" and "fixture" in ev.message
    assert np.allclose(ev.q, [e.q for e in events if e.kind == LinkEventKind.MOVED][4])
    n = len(events)
    sim.indicate_collision()
    assert len(events) == n + 1 and events[-1].kind == LinkEventKind.COLLISION_INDICATED
    assert np.allclose(events[-1].q, ev.q)


def test_refusals_and_uploads(rv2aj):
    sim = SimulatedRobot(rv2aj, clock=VirtualClock())
    with pytest.raises(LinkError, match="not connected"):
        sim.move_path(np.array([HOME]))
    sim.connect()
    with pytest.raises(LinkError, match="outside the joint limits"):
        sim.move_path(np.radians([[0, 0, 0, 0, 0], [0, 0, 0, 100, 0]]))
    assert np.allclose(sim.current_joints(), 0.0)  # nothing moved
    a = sim.upload_program("pick place", {"prog.mb4": b"10 MOV P1\n"})
    b = sim.upload_program("pick place", {"prog.mb4": b"10 MOV P2\n"})
    assert a != b and sim.programs[a] != sim.programs[b]


@pytest.mark.parametrize("press", ["collision", "stop"])
def test_the_pages_robot_halts_at_the_contact_and_waits_for_the_operator(rv2aj, press):
    """The page's simulated robot (`wait_for_operator`) halts where the self-reporting one
    reports the contact, and waits: Collision! records that very posture, Stop ends the move."""
    box = box_on_sweep(rv2aj, Q_A, Q_B, 0.5)
    path = sweep(Q_A, Q_B, 5)
    reference = connected(rv2aj, clock=VirtualClock(), hidden_obstacles=[box], start_q=Q_A)
    expected = reference.move_path(path)
    sim = connected(rv2aj, clock=VirtualClock(), hidden_obstacles=[box], start_q=Q_A)
    sim.wait_for_operator = True
    halted = threading.Event()
    sim.subscribe(lambda e: e.details.get("halted") and halted.set())
    result: list = []
    mover = threading.Thread(target=lambda: result.append(sim.move_path(path)))
    mover.start()
    assert halted.wait(30)  # it halts ...
    mover.join(0.8)
    assert mover.is_alive()  # ... and waits (more than one 0.5 s check of the buttons)
    if press == "collision":
        sim.indicate_collision()
    else:
        sim.stop()
    mover.join(10)
    assert not mover.is_alive()
    ev = result[0]
    if press == "collision":
        assert ev.kind == LinkEventKind.COLLISION_INDICATED
        assert ev.details["source"] == "operator" and ev.details["obstacles"] == ["hidden"]
        # where the self-reporting robot reports the contact: within one 5 mm check step of
        # the arm (not bit for bit - a kernel may finish compiling between the two runs and
        # the contact test run compiled in one and interpreted in the other)
        gap = float(np.sum(rv2aj.arm_radii() * np.abs(ev.q - expected.q)))
        assert gap <= 0.005 + 1e-9, gap
        assert abs(ev.path_index - expected.path_index) <= 1
    else:
        assert ev.kind == LinkEventKind.STOPPED
