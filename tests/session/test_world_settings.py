"""World settings: set by the Session or a script, checked with a clear message, saved with the
session, and they make the world model stale."""

from __future__ import annotations

import pytest

from assistant.session import Session
from assistant.session.types import SessionError
from assistant.session.world_settings import WorldSettings


def test_defaults_suit_every_robot_and_resolve_per_robot(rv2aj):
    ws = WorldSettings()
    cfg = ws.world_config(rv2aj)
    assert (cfg.size, cfg.grid().leaf) == (2.0, 0.0625)  # the thesis' octree for the RV-2AJ
    assert cfg.reach.store == "auto" and cfg.reach.memory_mb == 1536
    fine = ws.changed(resolution_mm=31.25).world_config(rv2aj)
    assert fine.grid().leaf == pytest.approx(0.03125) and fine.reach.d_step == pytest.approx(
        0.015625)


@pytest.mark.parametrize("changes, words", [
    ({"resolution_mm": 1}, "10-250 mm"),
    ({"joint_samples": 5}, "joint samples"),
    ({"memory_mb": 1}, "memory budget"),
    ({"store": "octree"}, "auto, grid, samples"),
    ({"clearence_mm": 5}, "unknown world setting clearence_mm"),
])
def test_a_bad_setting_is_refused_naming_what_is_allowed(tmp_path, changes, words):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    with pytest.raises(SessionError, match=words):
        s.set_world_settings(**changes)
    assert s.world_settings == WorldSettings()  # nothing changed


def test_settings_are_saved_and_make_the_world_stale(tmp_path):
    folder = tmp_path / "s"
    s = Session.from_sample("thesis_rv2aj", folder)
    key = s.obstacles_key()
    out = s.set_world_settings(joint_samples=100_000, memory_mb="800", resolution_mm="")
    assert out["joint_samples"] == 100_000 and out["memory_mb"] == 800
    assert out["resolution_mm"] is None
    assert s.obstacles_key() != key  # a built world would be rebuilt
    s.save(folder)
    back = Session.load(folder, autosave=False)
    assert back.world_settings == s.world_settings


def test_the_script_verb_sets_them(tmp_path):
    from assistant.session.script import parse_script, run_action

    script = tmp_path / "s.yaml"
    script.write_text("cell: thesis_rv2aj\nactions:\n"
                      "  - world_settings: {memory_mb: 1024, store: grid}\n", encoding="utf-8")
    sc = parse_script(script)
    s = Session.from_sample("thesis_rv2aj", tmp_path / "f")
    run_action(s, sc.actions[0], tmp_path, script)
    assert s.world_settings.memory_mb == 1024 and s.world_settings.store == "grid"


def test_a_plan_says_where_a_transfer_is_closer_than_the_required_clearance(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=True,
                            with_mission=True)
    s.goto("plan")
    s.set_world_settings(clearance_mm=200)  # more than any transfer of the thesis cell keeps
    rep = s.plan()
    assert rep["clearance_required_mm"] == 200
    short = rep["clearance_shortfalls"]
    assert short and all("short of the required 200 mm" in line for line in short)
    assert all(" -> " in line and "TCP near" in line for line in short)
    assert "clearance: " in rep["description"]
    s.set_world_settings(clearance_mm=0)  # 0: no requirement, nothing to report
    rep = s.plan()
    assert rep["clearance_shortfalls"] == []


def test_the_run_bound_is_a_setting_that_rebuilds_nothing(tmp_path):
    """Indications and seconds of planning per run (`planning.run_bounds`): set by the
    Session or a script, checked, saved, handed to the executor, and not the world's."""
    from assistant.session.script import parse_script, run_action

    s = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    assert (s.world_settings.max_indications, s.world_settings.planning_budget_s) == (20, 120.0)
    key = s.obstacles_key()
    out = s.set_world_settings(max_indications="5", planning_budget_s=30)
    assert out["max_indications"] == 5 and out["planning_budget_s"] == 30.0
    assert s.obstacles_key() == key  # a built world stays
    with pytest.raises(SessionError, match="1-3600 s"):
        s.set_world_settings(planning_budget_s=0)
    with pytest.raises(SessionError, match="1-1000"):
        s.set_world_settings(max_indications=0)
    script = tmp_path / "s.yaml"
    script.write_text("cell: thesis_rv2aj\nactions:\n"
                      "  - world_settings: {max_indications: 7, planning_budget_s: 45}\n"
                      "  - forget_indication: {number: 1}\n", encoding="utf-8")
    sc = parse_script(script)
    run_action(s, sc.actions[0], tmp_path, script)
    assert (s.world_settings.max_indications, s.world_settings.planning_budget_s) == (7, 45.0)
    with pytest.raises(Exception, match="no indication 1 to forget: 0 learnt"):
        run_action(s, sc.actions[1], tmp_path, script)
    s.save(tmp_path / "s")
    back = Session.load(tmp_path / "s", autosave=False)
    assert back.world_settings.planning_budget_s == 45.0
