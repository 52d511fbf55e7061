"""`run_study`: screen every candidate, plan the best screened ones, rank them all.

    problem = StudyProblem(cell, mission, q_seed=q_now)
    result = run_study(problem, Region.from_mm("-200,-200,200,200", 50, 4), StudySettings())
    result.ranked()[0].candidate, result.to_json()

1. Screen (all candidates, milliseconds each): IK with the margin, FCL at each location, the
   straight joint moves (`screen`).
2. Plan (at most `plan_top`, best screened first: fewest blocked straight moves, then the
   shortest estimate): world model, roadmap, mission plan, verification (`evaluate`).
   A count, not a time budget: the same study gives the same answer on any machine and in
   any engine.
3. Rank: planned candidates by cost (`scoring`), then screened-only ones by their estimate,
   then the failures with their reasons. The subject's current placement is planned too
   (`include_current`), to compare against.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from assistant.progress import Progress
from assistant.study import engines, tasks
from assistant.study.evaluate import PlanOutcome, Shared
from assistant.study.problem import StudyProblem
from assistant.study.region import Candidate, Region
from assistant.study.scoring import Scoring
from assistant.study.screen import ScreenResult

PLANNED, SCREENED, FAILED = "planned", "screened", "failed"


def local_cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class StudySettings:
    """How to run a study: how many candidates to plan fully, and where."""

    plan_top: int = 16
    #: "local" (worker processes), "inline" (this process), "ray" (see `ray_address`).
    engine: str = "local"
    workers: int = 0  # 0: every local core
    ray_address: str = "local"
    include_current: bool = True

    def __post_init__(self) -> None:
        if self.engine not in ("local", "inline", "ray"):
            raise ValueError(f"unknown engine {self.engine!r} (local, inline, ray)")
        if self.plan_top < 0 or self.workers < 0:
            raise ValueError("plan_top and workers must be >= 0")

    def make_engine(self) -> engines.Engine:
        n = self.workers or local_cores()
        if self.engine == "inline":
            return engines.Engine()
        if self.engine == "ray":
            return engines.RayEngine(self.ray_address, self.workers or None)
        return engines.LocalEngine(n)


@dataclass
class CandidateResult:
    candidate: Candidate
    status: str  # planned | screened | failed
    reason: str = ""
    screen: ScreenResult | None = None
    plan: PlanOutcome | None = None
    cost: float | None = None
    rank: int | None = None
    #: Errors of its tasks: why it failed, or what a retry got over.
    errors: list[str] = field(default_factory=list)

    def to_json(self, unit: str) -> dict:
        d: dict[str, Any] = {**self.candidate.to_json(), "status": self.status,
                             "rank": self.rank, "reason": self.reason}
        if self.cost is not None:
            d["cost"] = round(self.cost, 6)
            d["cost_unit"] = unit
        s = self.screen
        if s is not None and s.ok:
            d["joint_margin_deg"] = round(math.degrees(s.margin), 3)
            d["estimated_tcp_length_mm"] = round(s.estimate * 1000, 1)
            d["blocked_straight_moves"] = list(s.blocked)
        p = self.plan
        if p is not None and p.ok:
            d["tcp_path_length_mm"] = round(p.tcp_length * 1000, 3)
            d["joint_path_length_rad"] = round(p.joint_length, 6)
            d["min_clearance_mm"] = (None if p.min_clearance is None
                                     else round(p.min_clearance * 1000, 3))
            d["cycle"] = round(p.cycle, 6)
        if self.errors:
            d["task_errors"] = list(self.errors)
        return d


@dataclass
class StudyResult:
    subject: str
    region: Region
    candidates: list[CandidateResult]
    current: CandidateResult | None
    settings: StudySettings
    engine: str
    workers: int
    timings: dict[str, float]
    counts: dict[str, int]
    unit: str = "m"
    #: What was studied (for applying a candidate: `StudyProblem.pose_at`).
    problem: StudyProblem | None = field(default=None, repr=False)

    def ranked(self) -> list[CandidateResult]:
        """Every candidate, best first (failures last, by index)."""
        return sorted(self.candidates, key=lambda r: (r.rank is None, r.rank or 0,
                                                      r.candidate.index))

    def best(self) -> CandidateResult | None:
        top = self.ranked()
        return top[0] if top and top[0].status == PLANNED else None

    def to_json(self) -> dict:
        return {"subject": self.subject, "region": self.region.to_json(),
                "engine": self.engine, "workers": self.workers,
                "plan_top": self.settings.plan_top, "cost_unit": self.unit,
                "counts": dict(self.counts), "timings_s": {k: round(v, 4) for k, v in
                                                           self.timings.items()},
                "current": None if self.current is None else self.current.to_json(self.unit),
                "candidates": [r.to_json(self.unit) for r in self.ranked()]}


def run_study(problem: StudyProblem, region: Region, settings: StudySettings | None = None,
              progress: Progress | None = None, *, scoring: Scoring | None = None,
              task_fn: Callable[..., Any] = tasks.run_task,
              engine: engines.Engine | None = None) -> StudyResult:
    """Screen, plan the best, rank (module docstring). Raises `Cancelled` on Cancel."""
    settings = settings or StudySettings()
    scoring = scoring or Scoring()
    progress = progress or Progress("placement study")
    t0 = time.perf_counter()
    progress.update(0.0, "joint-position store")
    robot = problem.robot()
    shared = Shared.build(robot, problem.world_config)
    key = tasks.problem_key(problem, scoring)
    tasks.install(key, problem, scoring, shared)  # before the workers fork
    t_shared = time.perf_counter() - t0
    cands = region.candidates()
    x, y, yaw = problem.current_xy_yaw()
    current = Candidate(-1, x, y, yaw)
    own = engine is None
    eng = engine or settings.make_engine()
    try:
        eng.start(key, problem, scoring)
        t1 = time.perf_counter()
        items = [tasks.Task("screen", c) for c in cands]
        if settings.include_current:
            items.append(tasks.Task("screen", current))
        outs, fails1, retries1, log1 = engines.run_batch(eng, task_fn, key, items,
                                                   progress.sub(0.02, 0.3, "screening"))
        t2 = time.perf_counter()
        screens: dict[int, ScreenResult] = {}
        errors: dict[int, list[str]] = {}
        for item, out in zip(items, outs, strict=True):
            if out is not None:
                screens[item.candidate.index] = out.screen
        for k, errs in log1.items():
            errors[items[k].candidate.index] = list(errs)
        passed = sorted((c for c in cands if c.index in screens and screens[c.index].ok),
                        key=lambda c: (len(screens[c.index].blocked), screens[c.index].estimate,
                                       c.index))
        chosen = passed[:settings.plan_top]
        twin = next((c for c in chosen if _same_place(c, current)), None)
        if settings.include_current and twin is None and current.index in screens and \
                screens[current.index].ok:
            chosen = chosen + [current]  # (a grid point on it is planned once, for both)
        plan_items = [tasks.Task("plan", c, tuple(screens[c.index].q)) for c in chosen]
        pouts, fails2, retries2, log2 = engines.run_batch(eng, task_fn, key, plan_items,
                                                    progress.sub(0.3, 1.0, "planning"))
        t3 = time.perf_counter()
    finally:
        if own:
            eng.close()
        tasks.forget(key)
    plans = {it.candidate.index: o.plan for it, o in zip(plan_items, pouts, strict=True)
             if o is not None}
    for k, errs in log2.items():
        errors.setdefault(plan_items[k].candidate.index, []).extend(errs)
    if twin is not None and settings.include_current:
        if twin.index in plans:
            plans[current.index] = plans[twin.index]
        if twin.index in errors:
            errors[current.index] = errors[twin.index]
        chosen = chosen + [current]
    req = problem.criteria.clearance
    chosen_ids = {c.index for c in chosen}
    results = [_result(c, screens.get(c.index), plans.get(c.index), errors.get(c.index),
                       scoring, req, c.index in chosen_ids) for c in cands]
    cur = None
    if settings.include_current:
        cur = _result(current, screens.get(-1), plans.get(-1), errors.get(-1), scoring, req,
                      -1 in chosen_ids)
    _rank(results)
    task_s = {"screen_tasks_s": sum(s.seconds for s in screens.values()),
              "screen_cpu_s": sum(o.cpu_seconds for o in outs if o is not None),
              "plan_cpu_s": sum(o.cpu_seconds for o in pouts if o is not None),
              "world_build_tasks_s": sum(p.build_seconds for p in plans.values()),
              "plan_tasks_s": sum(p.plan_seconds for p in plans.values())}
    timings = {"shared_s": t_shared, "screen_s": t2 - t1, "plan_s": t3 - t2,
               "total_s": time.perf_counter() - t0, **task_s}
    done_outs = [o for o in list(outs) + list(pouts) if o is not None]
    pids = {o.pid for o in done_outs}
    per_pid = {pid: sum(o.cpu_seconds for o in done_outs if o.pid == pid) for pid in pids}
    # CPU seconds of the busiest worker: about the tasks' wall time on idle cores, whatever
    # else the machine runs (the sum over the workers is what one process would spend).
    timings["task_cpu_s"] = sum(per_pid.values())
    timings["busiest_process_cpu_s"] = max(per_pid.values(), default=0.0)
    counts = {"candidates": len(cands), "processes": len(pids),
              "screened_ok": sum(1 for c in cands if c.index in screens
                                 and screens[c.index].ok),
              "planned": sum(1 for c in cands if c.index in plans),
              "planned_ok": sum(1 for c in cands if c.index in plans and plans[c.index].ok),
              "failed_tasks": len(fails1) + len(fails2), "retries": retries1 + retries2}
    progress.update(1.0, "study done", force=True)
    return StudyResult(problem.subject.describe(), region, results, cur, settings, eng.name,
                       eng.workers, timings, counts, scoring.unit, problem)


def _result(c: Candidate, s: ScreenResult | None, p: PlanOutcome | None,
            errors: list[str] | None, scoring: Scoring, required: float,
            planned: bool) -> CandidateResult:
    r = _outcome(c, s, p, errors, scoring, required, planned)
    r.errors = list(errors or [])
    return r


def _outcome(c: Candidate, s: ScreenResult | None, p: PlanOutcome | None,
             errors: list[str] | None, scoring: Scoring, required: float,
             planned: bool) -> CandidateResult:
    if s is None or (planned and p is None):
        why = "; ".join(errors or ["no answer"])
        return CandidateResult(c, FAILED, f"task failed twice: {why}", s, p)
    if not s.ok:
        return CandidateResult(c, FAILED, s.reason, s)
    if p is None:
        note = "not planned (beyond the plan budget)"
        if s.blocked:
            note += "; straight move blocked: " + ", ".join(s.blocked)
        return CandidateResult(c, SCREENED, note, s)
    if not p.ok:
        return CandidateResult(c, FAILED, p.reason, s, p)
    cost = scoring.cost(p.cycle, p.min_clearance, required)
    note = ""
    if p.min_clearance is not None and p.min_clearance < required:
        note = (f"clearance {p.min_clearance * 1000:.1f} mm, below the required "
                f"{required * 1000:.0f} mm")
    return CandidateResult(c, PLANNED, note, s, p, cost)


def _same_place(a: Candidate, b: Candidate) -> bool:
    d_yaw = (a.yaw - b.yaw + math.pi) % (2 * math.pi) - math.pi
    return abs(a.x - b.x) < 1e-9 and abs(a.y - b.y) < 1e-9 and abs(d_yaw) < 1e-9


def _rank(results: list[CandidateResult]) -> None:
    planned = sorted((r for r in results if r.status == PLANNED),
                     key=lambda r: (r.cost, r.candidate.index))
    screened = sorted((r for r in results if r.status == SCREENED),
                      key=lambda r: (len(r.screen.blocked), r.screen.estimate,
                                     r.candidate.index))
    for k, r in enumerate(planned + screened):
        r.rank = k + 1
