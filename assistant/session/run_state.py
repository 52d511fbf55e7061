"""The one state of a run the page shows: what the robot and the planner are doing, and the
one sentence that says it.

The toolbar's heading, the plan step's buttons and their greyed reasons all derive from
`RunState`, so they can never disagree (halted yet "moving", two outcomes at once, an old
"planned" line after the run).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class RunPhase(str, Enum):
    UNPLANNED = "unplanned"
    WORKING = "working"  # a long task on the worker: planning, the world model, an import
    PLANNED = "planned"
    MOVING = "moving"
    HALTED = "halted"  # the simulated robot stands against the unknown, waiting for Collision!
    STOPPED = "stopped"  # a run that ended resumably: Resume continues it
    DONE = "done"  # the goal reached; the final program planned (and maybe driven)


@dataclass(frozen=True)
class RunState:
    phase: RunPhase
    #: The sentence the page shows for it (markdown).
    sentence: str
    #: None without a final program; else whether it was driven on the robot.
    final_driven: bool | None = None

    @property
    def robot_in_run(self) -> bool:
        """The robot moves, or stands halted inside a run: only Collision! and Stop act."""
        return self.phase in (RunPhase.MOVING, RunPhase.HALTED)


MOVING = ("**The robot is moving.** Press **Collision!** (or the Space key) the moment it "
          "would hit something; **Stop** halts it.")
HALTED = ("**The robot has stopped against something the model does not know.** Press "
          "**Collision!** (Space) to teach it: the plan is repaired and the robot carries on; "
          "**Stop** ends the run.")


def run_state(mode: str, busy_task: str, halts: int, planned: bool,
              last_run: dict | None, final_driven: bool | None) -> RunState:
    """The run state from the session's mode, the halt it stands at (0: none; numbered within
    the run, so each halt gets its own press), whether a plan exists and how the last run
    ended (`ExecutionFinished.summary`, None when planned since)."""
    if mode == "moving":
        if halts:
            return RunState(RunPhase.HALTED, f"{HALTED} (halt {halts} of this run)",
                            final_driven)
        return RunState(RunPhase.MOVING, MOVING, final_driven)
    if mode == "busy":
        return RunState(RunPhase.WORKING, f"**Working:** {busy_task or 'long task'} (Cancel "
                        "stops it; nothing is lost)", final_driven)
    if last_run is not None and last_run.get("resumable"):
        return RunState(RunPhase.STOPPED, "**The run stopped.** Resume continues it from "
                        "where the robot stands.", final_driven)
    if last_run is not None and last_run.get("ok"):
        tail = ("The final program was driven once on the robot without a collision."
                if final_driven else
                "The final program is planned from everything learnt and checked in "
                "simulation; **Drive the final program once** to check it on the robot.")
        return RunState(RunPhase.DONE, tail, final_driven)
    if planned:
        return RunState(RunPhase.PLANNED, "", final_driven)
    return RunState(RunPhase.UNPLANNED, "", final_driven)
