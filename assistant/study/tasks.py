"""The one task function every engine runs, and the per-process context it reads.

A task is (kind, candidate, anchors): "screen" runs the cheap screen, "plan" the full
evaluation. The context - the problem and its `Shared` data - is installed once per process:
by the parent before the local pool forks (the workers inherit it, nothing is pickled per
task), or on first use in a Ray worker from the problem sent once through the object store.
The answer depends on the candidate and the problem only, never on the process or the
order the tasks ran in.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.progress import Cancelled, Progress
from assistant.study.evaluate import PlanOutcome, Shared, plan_candidate
from assistant.study.problem import StudyProblem
from assistant.study.region import Candidate
from assistant.study.scoring import Scoring
from assistant.study.screen import ScreenResult, screen

Array = np.ndarray

_CONTEXTS: dict[str, tuple[StudyProblem, Scoring, Shared]] = {}
_LOCK = threading.Lock()
#: Set in a worker process by its pool's initializer: the parent's cancel flag.
_CANCEL: Any = None


@dataclass(frozen=True)
class Task:
    kind: str  # "screen" | "plan"
    candidate: Candidate
    #: For "plan": the screened postures (anchors of the world's joint positions).
    anchors: tuple[Array, ...] = field(default=(), compare=False)


@dataclass
class TaskOutput:
    task: Task
    screen: ScreenResult | None = None
    plan: PlanOutcome | None = None
    #: CPU seconds the task took in its process (wall time depends on the machine's load).
    cpu_seconds: float = 0.0
    #: The process that ran it (how many processes a study used).
    pid: int = field(default_factory=os.getpid)


def problem_key(problem: StudyProblem, scoring: Scoring) -> str:
    """A key naming the problem's content (the same study in any process has the same)."""
    blob = pickle.dumps((problem.cell.robot_spec, problem.mission.to_json(),
                         np.asarray(problem.cell.T_world_base).tolist(),
                         sorted(problem.cell.objects), problem.subject, problem.criteria,
                         repr(problem.world_config), repr(problem.planner_config),
                         repr(scoring)))
    return hashlib.sha1(blob).hexdigest()[:16]


def install(key: str, problem: StudyProblem, scoring: Scoring, shared: Shared) -> None:
    """Make the context known in this process (the parent, before its workers fork)."""
    with _LOCK:
        _CONTEXTS.clear()  # one study at a time per process: do not keep old stores
        _CONTEXTS[key] = (problem, scoring, shared)


def forget(key: str) -> None:
    """Drop a finished study's context (its store) from this process."""
    with _LOCK:
        _CONTEXTS.pop(key, None)


def context(key: str, problem: StudyProblem | None = None, scoring: Scoring | None = None,
            ) -> tuple[StudyProblem, Scoring, Shared]:
    with _LOCK:
        ctx = _CONTEXTS.get(key)
    if ctx is None:
        if problem is None or scoring is None:
            raise RuntimeError("study context missing in this worker process")
        shared = Shared.build(problem.robot(), problem.world_config)
        install(key, problem, scoring, shared)
        ctx = (problem, scoring, shared)
    return ctx


def set_cancel_flag(flag: Any) -> None:
    """Pool initializer: the parent's `multiprocessing.Event` that cancels every task."""
    global _CANCEL
    _CANCEL = flag


class _TaskProgress(Progress):
    """A worker's progress: cancelled when the parent's shared flag is set."""

    def check(self) -> None:
        if _CANCEL is not None and _CANCEL.is_set():
            self.cancel()
        super().check()


def run_task(key: str, task: Task, problem: StudyProblem | None = None,
             scoring: Scoring | None = None) -> TaskOutput:
    """Screen or plan one candidate (any process: local worker, Ray worker, the parent)."""
    cpu0 = time.process_time()
    prob, score, shared = context(key, problem, scoring)
    progress = _TaskProgress(f"candidate {task.candidate.index}")
    progress.check()
    cell, mission = prob.variant(task.candidate)
    robot = shared.robot
    obstacles = cell.collision_objects_in_base()
    T_wb = np.asarray(cell.T_world_base, dtype=float)
    q_seed = (np.asarray(prob.q_seed, dtype=float) if prob.q_seed is not None
              else np.clip(np.zeros(robot.dof), robot.limits.lower, robot.limits.upper))
    if task.kind == "screen":
        checker = CollisionChecker(robot, obstacles)
        res = screen(robot, checker, T_wb, mission, {**prob.location_names, **names_of(mission)},
                     prob.criteria.joint_margin, q_seed)
        return TaskOutput(task, screen=res, cpu_seconds=time.process_time() - cpu0)
    if task.kind == "plan":
        out = plan_candidate(shared, obstacles, mission, T_wb, q_seed, list(task.anchors),
                             prob.planner_config, score, progress)
        return TaskOutput(task, plan=out, cpu_seconds=time.process_time() - cpu0)
    raise ValueError(f"unknown study task {task.kind!r}")


def names_of(mission: Any) -> dict[str, Array]:
    """Taught location names by position (start and goal), to name path points."""
    out = {}
    for loc in (mission.start, mission.goal):
        if loc is not None:
            out[loc.name] = np.asarray(loc.position, dtype=float)
    return out


__all__ = ["Cancelled", "Task", "TaskOutput", "context", "install", "problem_key", "run_task",
           "set_cancel_flag"]
