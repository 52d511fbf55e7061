"""Mission planning, execution with re-planning, and workspace exploration (SPEC §1, §6).

Owns: solving taught locations into joints with honest errors (`locations`), the planner of a
whole mission - ordering, transfers through the roadmap and the elastic net, application
paths, one verified `Trajectory` (`mission_planner`, `pieces`, `report`) - the known world as
the planners' check (`known_world`: FCL against CAD plus the operator's recorded collision
postures), the re-planning execution loop on any `RobotLink` (`execution`, `backoff`), the
automatic exploration modes (`exploration`) and loading a sample cell with its hidden
obstacles and mission (`scenario`).

Builds on `assistant.world`, `assistant.roadmap` and `assistant.trajectory`; must not import
the UI (`web`, `viser`) or `workflow`. Units: metres and radians; poses are named by frames
(`T_world_base`, `T_base_tool`), joints are in the robot's order.
"""

from assistant.planning.config import ExecutionConfig, MissionPlannerConfig
from assistant.planning.execution import (
    EndReason,
    ExecutionReport,
    MissionExecutor,
)
from assistant.planning.exploration import ExplorationConfig, ExplorationReport, Explorer
from assistant.planning.locations import LocationError, LocationProblem, solve_location
from assistant.planning.mission_planner import MissionPlan, MissionPlanner
from assistant.planning.pieces import PieceKind, PlanPiece
from assistant.planning.report import MissionPlanReport, PieceReport
from assistant.planning.scenario import Scenario, load_scenario

__all__ = [
    "EndReason",
    "ExecutionConfig",
    "ExecutionReport",
    "ExplorationConfig",
    "ExplorationReport",
    "Explorer",
    "LocationError",
    "LocationProblem",
    "MissionExecutor",
    "MissionPlan",
    "MissionPlanReport",
    "MissionPlanner",
    "MissionPlannerConfig",
    "PieceKind",
    "PieceReport",
    "PlanPiece",
    "Scenario",
    "load_scenario",
    "solve_location",
]
