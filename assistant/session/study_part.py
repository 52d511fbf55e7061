"""The placement study: where should the robot base (or an object) stand? Runs in the
background with progress and Cancel like the other long actions; applying a candidate is an
ordinary undoable edit of the cell.

A part of the `Session`, composed rather than mixed in (`Session.studies`): it owns the last
study's result; the session's study verbs hand over to it, and it reaches the rest of the
session only through the parts' contract (`PartContract`). The study itself lives in
`assistant.study`.
"""

from __future__ import annotations

import math
from concurrent.futures import Future
from typing import TYPE_CHECKING, Any

import numpy as np

from assistant.progress import Progress
from assistant.session.contract import PartContract
from assistant.session.events import Notice, SceneChanged
from assistant.session.types import EDIT_PLACEMENT, SessionError

if TYPE_CHECKING:  # the study (and the planner behind it) loads on first use
    from assistant.study import Region, Scoring, StudyProblem, StudyResult, StudySettings

#: Steps the study may run in: the cell is placed and the mission taught.
STUDY_STEPS = ("place", "teach", "explore", "plan")


class StudyPart:
    """The placement study and applying one of its candidates."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: The last study's result (None before the first).
        self.placement_study: StudyResult | None = None

    def study_problem(self, *, object_name: str | None = None, carry: bool = True,
                      joint_margin_deg: float = 5.0,
                      clearance_mm: float | None = None) -> StudyProblem:
        """The study of this session's cell and mission (a copy: later edits do not leak in)."""
        from assistant.cell.model import Cell
        from assistant.study import StudyCriteria, StudyProblem, Subject

        with self._core.lock:
            cell = Cell(self._core.cell.robot_spec, self._core.T_world_base().copy(),
                        dict(self._core.cell.objects), dict(self._core.cell.frames))
            mission = self._core.teaching.resolved_mission()
            clearance = self._core.world_settings.clearance_mm if clearance_mm is None \
                else clearance_mm
            try:
                return StudyProblem(
                    cell, mission, Subject(object_name, carry),
                    StudyCriteria(math.radians(float(joint_margin_deg)),
                                  float(clearance) / 1000.0),
                    q_seed=self._core.current_joints(),
                    world_config=self._core.world_settings.world_config(self._core.robot),
                    planner_config=self._core.planning.planner_config(),
                    location_names={n: loc.position.copy()
                                    for n, loc in self._core.locations.items()})
            except (ValueError, KeyError) as exc:
                raise SessionError(str(exc)) from None

    def start_study_placement(self, region: Region, settings: StudySettings | None = None,
                              *, scoring: Scoring | None = None, **problem: Any) -> Future:
        """Run a placement study in the background (progress, Cancel); the future gives the
        `StudyResult`, also kept as `placement_study` and announced as SceneChanged("study").
        `problem`: `study_problem`'s options (object_name, carry, joint_margin_deg, ...);
        `scoring`: e.g. `Scoring(cycle_time=...)` once a cycle-time prediction exists."""
        from assistant.study import StudySettings, run_study

        prob = self.study_problem(**problem)
        settings = settings or StudySettings()

        def work(progress: Progress) -> StudyResult:
            result = run_study(prob, region, settings, progress, scoring=scoring)
            with self._core.lock:
                self.placement_study = result
            best = result.best()
            c = result.counts
            msg = (f"placement study: {c['candidates']} candidates, {c['screened_ok']} passed "
                   f"the screen, {c['planned_ok']} of {c['planned']} planned")
            if best is not None:
                msg += f"; best {best.candidate.label()}"
            self._core.bus.emit(Notice(msg))
            self._core.bus.emit(SceneChanged("study"))
            return result

        return self._core.run_busy("placement study", work, STUDY_STEPS)

    def study_placement(self, region: Region, settings: StudySettings | None = None,
                        *, scoring: Scoring | None = None, **problem: Any) -> StudyResult:
        return self.start_study_placement(region, settings, scoring=scoring,
                                          **problem).result()

    def apply_placement(self, index: int) -> np.ndarray:
        """Move the study's subject (robot base or object) to candidate `index` of the last
        study - an undoable edit like any placement. Returns the new pose (world)."""
        study = self.placement_study
        if study is None:
            raise SessionError("no placement study yet: run one first")
        match = [r for r in study.candidates if r.candidate.index == index]
        if not match:
            raise SessionError(f"the study has no candidate #{index}")
        problem = study.problem
        if problem is None:  # a result kept without its problem (loaded, not run here)
            raise SessionError("the study's problem is not kept: run the study again")
        T = problem.pose_at(match[0].candidate)
        label = f"move {problem.subject.describe()} to {match[0].candidate.label()}"
        with self._core.action(label, EDIT_PLACEMENT, scene="robot" if problem.subject.is_base
                               else "objects"):
            if problem.subject.is_base:
                self._core.cell.set_base_pose(T)
                if self._core.link_settings.kind == "simulated":
                    # its hidden obstacles are placed in the base frame
                    self._core.setup.drop_link()
            else:
                assert problem.subject.object_name is not None
                self._core.cell.set_object_pose(problem.subject.object_name, T)
        return T
