"""The same study on a local Ray instance started here gives the same ranking and scores as
the local pool. Ray is the optional [cluster] extra: the test is marked `cluster`, which the
README's command leaves out and .ci/run runs after installing the extra."""

from __future__ import annotations

import pytest

from assistant.study import Region, StudySettings, run_study

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_ray_and_local_pool_rank_alike(thesis_problem):
    from assistant.study.engines import RayEngine

    region = Region(0.0, 0.0, 0.1, 0.1, 0.1, 3)  # 2 x 2 positions x 3 yaws = 12
    settings = StudySettings(plan_top=2, include_current=False)
    local = run_study(thesis_problem, region, StudySettings(plan_top=2, workers=2,
                                                            include_current=False))
    engine = RayEngine("local", 2)
    try:
        on_ray = run_study(thesis_problem, region, settings, engine=engine)
    finally:
        engine.close()
    drop = {"processes"}
    assert on_ray.engine == "ray"
    assert {k: v for k, v in on_ray.counts.items() if k not in drop} == \
        {k: v for k, v in local.counts.items() if k not in drop}
    assert local.counts["planned_ok"] >= 1
    a = [(r.candidate.index, r.status, r.rank, r.reason) for r in local.ranked()]
    b = [(r.candidate.index, r.status, r.rank, r.reason) for r in on_ray.ranked()]
    assert a == b
    for x, y in zip(local.ranked(), on_ray.ranked(), strict=True):
        if x.cost is not None:
            assert abs(x.cost - y.cost) < 1e-6  # same code and inputs in another process
