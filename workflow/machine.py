"""The workflow finite-state machine: where the operator is, what is allowed now, and why not.

A small table-driven machine rather than a library (python-statemachine, transitions): the
two rules that matter here - the thesis' numbered Previous/Next over a state *tree*, and
guards that answer with a sentence for the operator - are a few lines each on a table, while
a library would need both bolted on; the table also generates the README's Mermaid diagram.

The machine knows nothing of the domain: the session hands it `Facts` (counts and flags) and
the machine answers. On top of the step (a leaf of the tree) there is a *mode*: idle, busy
(long work running: only Cancel), moving (the robot moves: only Stop and Collision!) and
error (e.g. link lost: only Acknowledge/Reconnect).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from workflow.states import (
    NUMBER,
    STATES,
    first_leaf,
    leaves,
    main_state,
    next_state,
    previous_state,
)


class Mode(str, Enum):
    IDLE = "idle"
    BUSY = "busy"
    MOVING = "moving"
    ERROR = "error"


@dataclass(frozen=True)
class Facts:
    """What the guards need to know about the session, computed by the session."""

    robot_ready: bool = False
    objects: int = 0
    locations: int = 0
    has_start: bool = False
    has_goal: bool = False
    paths: int = 0
    world_ready: bool = False
    plan_ready: bool = False
    program_ready: bool = False
    link_ok: bool = True


class TransitionRefused(Exception):
    """An action the current state or mode does not allow; the message says what to do first."""


def _guard_messages(main: str, f: Facts) -> list[str]:
    """Conditions for *entering* a main state (cumulative along the standard path)."""
    order = ["setup", "cad", "place", "teach", "explore", "plan", "export"]
    msgs: list[str] = []
    k = order.index(main)
    if k >= order.index("cad") and not f.robot_ready:
        msgs.append("Choose a robot first")
    if k >= order.index("place") and f.objects == 0:
        msgs.append("Import or place at least one object first")
    if k >= order.index("explore"):
        if not f.has_start:
            msgs.append("The mission needs a start")
        if not f.has_goal:
            msgs.append("The mission needs a goal")
    if k >= order.index("export") and not f.plan_ready:
        msgs.append("Plan the mission first: there is no verified trajectory yet")
    return msgs


@dataclass(frozen=True)
class JumpSpec:
    """A transition that leaves the standard path (besides Previous/Next)."""

    source: str  # a leaf or a main state id (applies to all its leaves)
    event: str
    target: str  # a leaf id
    label: str


JUMPS: tuple[JumpSpec, ...] = (
    # A cell-layout drawing places its parts as drawn: placing and calibrating may wait.
    JumpSpec("cad", "teach_now", "teach.locations", "Skip to teaching"),
    JumpSpec("place", "import_more", "cad", "Import more CAD"),
    JumpSpec("teach", "fix_placement", "place.objects", "Fix placement"),
    JumpSpec("teach", "calibrate_cameras", "place.cameras", "Calibrate cameras"),
    JumpSpec("explore", "edit_mission", "teach.locations", "Edit mission"),
    JumpSpec("plan", "fix_placement", "place.objects", "Fix placement"),
    JumpSpec("plan", "edit_mission", "teach.locations", "Edit mission"),
    JumpSpec("export", "replan", "plan", "Re-plan"),
    JumpSpec("export", "edit_mission", "teach.locations", "Edit mission"),
)

#: Actions available in a mode, regardless of the step.
MODE_EVENTS: dict[Mode, tuple[tuple[str, str], ...]] = {
    Mode.BUSY: (("cancel", "Cancel"),),
    Mode.MOVING: (("collision", "Collision!"), ("stop", "Stop")),
    Mode.ERROR: (("acknowledge", "Acknowledge"), ("reconnect", "Reconnect")),
}


@dataclass(frozen=True)
class Transition:
    """One toolbar button: what it does, where it goes, whether it is allowed and why not."""

    event: str
    label: str
    target: str | None
    allowed: bool
    reason: str = ""


@dataclass
class Machine:
    state: str = "setup"
    mode: Mode = Mode.IDLE
    busy_task: str = ""
    error_message: str = ""
    visited: list[str] = field(default_factory=lambda: ["setup"])

    # ---------------------------------------------------------------- queries
    @property
    def number(self) -> str:
        return NUMBER[self.state]

    @property
    def title(self) -> str:
        return STATES[self.state].title

    @property
    def main(self) -> str:
        return main_state(self.state)

    def refusal(self, target: str, facts: Facts) -> str:
        """Why `target` cannot be entered now ('' if it can)."""
        if self.mode != Mode.IDLE:
            return self._mode_refusal()
        return "; ".join(_guard_messages(main_state(target), facts))

    def _mode_refusal(self) -> str:
        if self.mode == Mode.BUSY:
            return f"Wait for '{self.busy_task}' to finish or cancel it"
        if self.mode == Mode.MOVING:
            return "The robot is moving: stop it first"
        return f"Acknowledge the error first: {self.error_message}"

    def transitions(self, facts: Facts) -> list[Transition]:
        """Every button the toolbar shows now, enabled or not (with the reason)."""
        out: list[Transition] = []
        if self.mode != Mode.IDLE:
            for ev, label in MODE_EVENTS[self.mode]:
                out.append(Transition(ev, label, None, True))
        prev, nxt = previous_state(self.state), next_state(self.state)
        for ev, label, target in (("previous", "Previous", prev), ("next", "Next", nxt)):
            if target is None:
                out.append(Transition(ev, label, None, False, "No further step this way"))
            else:
                why = self.refusal(target, facts)
                out.append(Transition(ev, label, target, not why, why))
        for j in JUMPS:
            if j.source in (self.state, self.main) and j.target != self.state:
                why = self.refusal(j.target, facts)
                out.append(Transition(j.event, j.label, j.target, not why, why))
        exit_why = self._mode_refusal() if self.mode in (Mode.BUSY, Mode.MOVING) else ""
        out.append(Transition("exit", "Exit", None, not exit_why, exit_why))
        return out

    def allowed(self, facts: Facts) -> list[Transition]:
        return [t for t in self.transitions(facts) if t.allowed]

    # ---------------------------------------------------------------- changes
    def fire(self, event: str, facts: Facts) -> str:
        """Take a toolbar transition; raises TransitionRefused with the reason."""
        for t in self.transitions(facts):
            if t.event == event:
                if not t.allowed:
                    raise TransitionRefused(t.reason)
                if t.target is not None:
                    self._enter(t.target)
                return self.state
        raise TransitionRefused(f"'{event}' is not available in step {self.number} "
                                f"({self.title})")

    def goto(self, target: str, facts: Facts) -> str:
        """Jump to any step whose guards hold (the step list, loading a session)."""
        if target not in STATES:
            raise TransitionRefused(f"unknown step {target!r}")
        if target not in leaves():
            target = first_leaf(target)
        why = self.refusal(target, facts)
        if why:
            raise TransitionRefused(why)
        self._enter(target)
        return self.state

    def _enter(self, target: str) -> None:
        self.state = target
        if target not in self.visited:
            self.visited.append(target)

    def require(self, mains: tuple[str, ...], action: str) -> None:
        """Refuse a session action unless the step is one of `mains` and the mode is idle."""
        if self.mode != Mode.IDLE:
            raise TransitionRefused(f"Cannot {action} now: {self._mode_refusal()}")
        if self.main not in mains:
            names = " or ".join(f"'{STATES[m].title}'" for m in mains)
            raise TransitionRefused(f"Cannot {action} in step {self.number} ({self.title}); "
                                    f"go to {names} first")

    # modes
    def begin_busy(self, task: str) -> None:
        if self.mode != Mode.IDLE:
            raise TransitionRefused(f"Cannot start '{task}': {self._mode_refusal()}")
        self.mode, self.busy_task = Mode.BUSY, task

    def begin_moving(self) -> None:
        if self.mode not in (Mode.IDLE, Mode.BUSY):
            raise TransitionRefused(f"Cannot move the robot: {self._mode_refusal()}")
        self.mode = Mode.MOVING

    def end_mode(self) -> None:
        if self.mode != Mode.ERROR:
            self.mode, self.busy_task = Mode.IDLE, ""

    def enter_error(self, message: str) -> None:
        self.mode, self.error_message, self.busy_task = Mode.ERROR, message, ""

    def clear_error(self) -> None:
        if self.mode == Mode.ERROR:
            self.mode, self.error_message = Mode.IDLE, ""

    # ---------------------------------------------------------------- persistence
    def to_json(self) -> dict:
        # Busy/moving do not survive a restart: whatever ran is gone, so reload as idle.
        mode = self.mode if self.mode == Mode.ERROR else Mode.IDLE
        return {"state": self.state, "mode": mode.value, "error_message": self.error_message,
                "visited": list(self.visited)}

    @staticmethod
    def from_json(d: dict) -> Machine:
        state = d.get("state", "setup")
        if state not in STATES or state not in leaves():
            raise ValueError(f"unknown workflow step {state!r} in the session file")
        mode = Mode(d.get("mode", "idle"))
        visited = [s for s in d.get("visited", [state]) if s in STATES]
        return Machine(state, mode, "", str(d.get("error_message", "")), visited or [state])
