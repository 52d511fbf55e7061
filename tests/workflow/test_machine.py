"""The operator workflow: numbering, Previous/Next by the thesis' rule, guards with messages."""

from __future__ import annotations

import pytest

from workflow.machine import Facts, Machine, Mode, TransitionRefused
from workflow.states import NUMBER, leaves, next_state, previous_state

READY = Facts(robot_ready=True, objects=2, locations=3, has_start=True, has_goal=True, paths=1,
              world_ready=True, plan_ready=True, program_ready=True)


def test_states_are_numbered_along_the_standard_path():
    assert [NUMBER[s] for s in leaves()] == ["1", "2", "3.1", "3.2", "4.1", "4.2", "5", "6", "7"]


def test_next_and_previous_follow_siblings_then_parents():
    assert next_state("cad") == "place.objects"  # entering a composite: its first child
    assert next_state("place.objects") == "place.cameras"
    assert next_state("place.cameras") == "teach.locations"  # the parent's next
    assert next_state("export") is None
    assert previous_state("teach.locations") == "place.cameras"  # parent's previous, last child
    assert previous_state("place.objects") == "cad"
    assert previous_state("setup") is None
    # Walking Next from the start visits every leaf once, in number order.
    s, seen = "setup", ["setup"]
    while (s := next_state(s)) is not None:
        seen.append(s)
    assert seen == leaves()


def test_guards_refuse_with_a_message_for_the_operator():
    m = Machine()
    with pytest.raises(TransitionRefused, match="Choose a robot first"):
        m.fire("next", Facts())
    m.fire("next", Facts(robot_ready=True))
    assert m.state == "cad"
    with pytest.raises(TransitionRefused, match="Import or place at least one object first"):
        m.fire("next", Facts(robot_ready=True))
    facts = Facts(robot_ready=True, objects=1, has_start=True)
    m.goto("teach.paths", facts)
    nxt = [t for t in m.transitions(facts) if t.event == "next"][0]
    assert not nxt.allowed and nxt.reason == "The mission needs a goal"
    with pytest.raises(TransitionRefused, match="The mission needs a goal"):
        m.fire("next", facts)
    assert m.state == "teach.paths"  # a refusal changes nothing


def test_toolbar_lists_previous_next_exit_and_the_jumps_allowed_here():
    m = Machine(state="plan")
    events = {t.event: t for t in m.transitions(READY)}
    assert {"previous", "next", "exit", "fix_placement", "edit_mission"} <= set(events)
    assert all(t.allowed for t in events.values())
    m.fire("fix_placement", READY)  # leaving the standard path after a misplaced model
    assert m.state == "place.objects"


def test_export_needs_a_verified_plan():
    m = Machine(state="plan")
    facts = Facts(robot_ready=True, objects=1, has_start=True, has_goal=True)
    with pytest.raises(TransitionRefused, match="Plan the mission first"):
        m.fire("next", facts)


def test_modes_restrict_the_toolbar():
    m = Machine(state="plan")
    m.begin_busy("planning")
    evs = {t.event: t for t in m.transitions(READY)}
    assert evs["cancel"].allowed
    assert not evs["next"].allowed and "planning" in evs["next"].reason
    with pytest.raises(TransitionRefused):
        m.fire("previous", READY)
    with pytest.raises(TransitionRefused, match="Cannot start"):
        m.begin_busy("other")
    m.end_mode()
    m.begin_moving()
    assert {t.event for t in m.allowed(READY)} == {"collision", "stop"}
    m.end_mode()
    m.enter_error("link lost")
    with pytest.raises(TransitionRefused, match="link lost"):
        m.require(("plan",), "execute")
    m.clear_error()
    m.require(("plan",), "execute")
    with pytest.raises(TransitionRefused, match="go to 'Import CAD' first"):
        m.require(("cad",), "import CAD")


def test_serialisation_round_trip_drops_transient_modes():
    m = Machine()
    m.fire("next", READY)
    m.begin_busy("table")
    d = m.to_json()
    back = Machine.from_json(d)
    assert back.state == "cad" and back.mode == Mode.IDLE
    with pytest.raises(ValueError, match="unknown workflow step"):
        Machine.from_json({"state": "nowhere"})
