"""Placement studies: where should the robot base (or a fixture) stand so that every taught
location is reachable with margin, every transfer is plannable with clearance, and the cycle
is short (issue 38).

Owns the candidates (`region`: a grid of x, y and yaw steps over a rectangle), what a study
asks of one candidate (`problem`: the cell and mission moved to it), the cheap screen (`screen`:
IK with a margin to the joint limits, FCL at each location, straight joint moves between
them), the full evaluation of the best screened candidates (`evaluate`: world model, roadmap,
`MissionPlanner`, verification), the score (`scoring`), the fan-out of candidates as
independent tasks over local worker processes or a Ray cluster, each retried once
(`engines`, `tasks`), the study itself (`study`) and its picture (`picture`).

May import: planning, world, roadmap, collision, robots, cell, mission, transforms, progress.
Never `assistant.session`, `web` or viser: the Session runs studies, the page shows them.
Units: metres and radians inside; millimetres and degrees only in `study.json` and the map.
"""

from assistant.study.problem import StudyCriteria, StudyProblem, Subject
from assistant.study.region import Candidate, Region
from assistant.study.scoring import Scoring
from assistant.study.study import CandidateResult, StudyResult, StudySettings, run_study

__all__ = ["Candidate", "CandidateResult", "Region", "Scoring", "StudyCriteria",
           "StudyProblem", "StudyResult", "StudySettings", "Subject", "run_study"]
