"""What a candidate's score and reason say: a base that reaches everything is planned and
ranked above one that cannot reach a location, whose reason names it and by how much (the
shortfall checked against the robot's own IK); a region out of reach names every reason."""

from __future__ import annotations

import re

import numpy as np
import pytest

from assistant.study import Region, StudySettings, run_study
from assistant.study.screen import reach_shortfall
from assistant.transforms import inv_T


@pytest.fixture(scope="module")
def small_study(thesis_problem):
    # (0, 0) is the sample's own base (reaches everything); (0, 300) mm leaves P1 far away.
    region = Region(0.0, 0.0, 0.0, 0.3, 0.3, 1)
    return run_study(thesis_problem, region, StudySettings(plan_top=1, engine="inline",
                                                           include_current=False))


def test_reaching_placement_ranks_above_one_out_of_reach(small_study):
    by_xy = {(round(r.candidate.x, 3), round(r.candidate.y, 3)): r
             for r in small_study.candidates}
    good, bad = by_xy[(0.0, 0.0)], by_xy[(0.0, 0.3)]
    assert good.status == "planned" and good.rank == 1 and good.cost is not None
    assert good.plan.ok and good.plan.tcp_length > 0.3  # P1 -> P7 -> P8 -> P10 is > 0.3 m
    assert np.degrees(good.screen.margin) >= 5.0  # the default margin to the joint limits
    assert bad.status == "failed" and bad.rank is None
    assert re.fullmatch(r"P1 out of reach by \d+ mm", bad.reason), bad.reason
    assert small_study.best() is good
    assert small_study.counts == {"candidates": 2, "processes": 1, "screened_ok": 1,
                                  "planned": 1, "planned_ok": 1, "failed_tasks": 0,
                                  "retries": 0}


def test_out_of_reach_distance_is_what_ik_says(small_study, thesis_problem):
    """Moving P1 toward the shoulder by the reported amount makes it reachable; 5 mm less
    does not (the reason's figure is the robot's, to the millimetre it prints)."""
    bad = next(r for r in small_study.candidates if r.status == "failed")
    mm = float(re.search(r"by (\d+) mm", bad.reason).group(1))
    robot = thesis_problem.robot()
    T_bt = inv_T(thesis_problem.pose_at(bad.candidate)) @ thesis_problem.mission.start.T_world_tool
    short = reach_shortfall(robot, T_bt)
    assert abs(short * 1000 - mm) <= 0.5
    shoulder = robot.link_poses(np.zeros(robot.dof))[2][:3, 3]
    u = (shoulder - T_bt[:3, 3]) / np.linalg.norm(shoulder - T_bt[:3, 3])

    def moved(d: float) -> np.ndarray:
        T = T_bt.copy()
        T[:3, 3] += u * d
        return T

    assert robot.ik(moved(short + 0.001)).ok
    assert not robot.ik(moved(short - 0.005)).ok


def test_unreachable_region_gives_every_candidate_a_reason(thesis_problem):
    region = Region(1.5, 1.5, 1.6, 1.6, 0.1, 2)  # 1.5 m away: nothing is in reach
    res = run_study(thesis_problem, region, StudySettings(plan_top=4, engine="inline",
                                                          include_current=False))
    assert len(res.candidates) == 8
    assert all(r.status == "failed" for r in res.candidates)
    assert all(re.match(r"P1 out of reach", r.reason) for r in res.candidates)
    assert res.best() is None and res.counts["planned"] == 0
    doc = res.to_json()
    assert [c["reason"] for c in doc["candidates"]] == [r.reason for r in res.ranked()]


def _motions_as_seconds(robot, trajectory) -> float:
    """A stand-in cycle-time prediction: one second per motion."""
    return float(len(trajectory.motions))


def test_score_takes_a_cycle_time_and_penalises_low_clearance():
    from assistant.study import Scoring

    plain, timed = Scoring(), Scoring(cycle_time=_motions_as_seconds)
    assert (plain.unit, timed.unit) == ("m", "s")

    class _Traj:
        motions = [0, 1, 2]

    assert plain.cycle(None, _Traj(), 1.25) == 1.25  # path length until a prediction exists
    assert timed.cycle(None, _Traj(), 1.25) == 3.0
    assert plain.cost(2.0, 0.012, 0.010) == 2.0  # clearance kept: the cycle alone
    assert plain.cost(2.0, 0.005, 0.010) == pytest.approx(3.0)  # half the clearance short
    assert plain.cost(2.0, 0.005, 0.010) > plain.cost(2.1, 0.010, 0.010)
