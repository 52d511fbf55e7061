"""Step 6 - plan and execute: plan (progress + Cancel), watch the robot run the plan, press the
big red Collision! (or Space) the moment it would hit something; the assistant records the
posture, re-plans and carries on. The path is drawn with lines and arcs in their own colours."""

from __future__ import annotations

import contextlib
from typing import Any

import viser

from assistant.session.events import (
    CollisionRecorded,
    ErrorRaised,
    Event,
    ExecutionFinished,
    PlanReady,
    RobotHalted,
    SceneChanged,
    StateChanged,
)
from web.panels.base import Panel, busy_reason, gate, why_greyed
from web.scene.plan import KIND_COLORS
from web.wording import goal_reached, moves_words, report_rows

LEGEND_NAMES = {"joint": "joint move (MOV/PTP)", "linear": "line (MVS/LIN)",
                "circular": "arc (MVR/CIRC)", "spline": "curve (SPLINE)"}


def legend() -> str:
    items = [f"<span style='color:rgb{c}'>&#9644;</span> {LEGEND_NAMES[k]}"
             for k, c in KIND_COLORS.items()]
    return "<small>" + " &nbsp; ".join(items) + "</small>"


def report_markdown(report: dict[str, Any] | None) -> str:
    """The planner's report as a two-column table in mm, degrees and seconds (the raw one,
    in metres and radians, is in report.json)."""
    if not report:
        return "*Not planned yet.*"
    rows = ["| | |", "|---|---|"]
    rows += [f"| {label} | {_cell(value)} |" for label, value in report_rows(report)]
    return "\n".join(rows)


def _content(md: Any, text: str) -> None:
    if md.content != text:
        md.content = text


def _cell(text: str) -> str:
    return str(text).replace("|", "/").replace("\n", " ").replace("<", "&lt;")


COLLISION_HINT = "Space key. Stops the robot, remembers the posture, re-plans"
SPEED_HINT = "How fast the simulated robot moves: 1x is as fast as the real robot, slow " \
    "enough to watch it and press Collision! in time"

#: Choices of the simulated robot's speed, in times real time (1 = as fast as the real one).
SPEEDS = {"0.5x real time": 0.5, "1x real time": 1.0, "2x real time": 2.0,
          "5x real time": 5.0, "20x real time": 20.0}


HALTED = ("**Halted against something the model does not know: press Collision! (Space) "
          "to teach it.**")


def speed_label(time_scale: float) -> str:
    for label, v in SPEEDS.items():
        if abs(v - time_scale) < 1e-9:
            return label
    return f"{time_scale:g}x real time"


class PlanPanel(Panel):
    title = "Plan & execute"
    steps = ("plan",)

    def build(self) -> None:
        g = self.gui
        self.plan = g.add_button("Plan", icon=viser.Icon.ROUTE)
        self.execute = g.add_button("Execute on the robot", icon=viser.Icon.PLAYER_PLAY,
                                    disabled=True)
        self.collision = g.add_button("Collision!", color="red", icon=viser.Icon.ALERT_OCTAGON,
                                      disabled=True, hint=COLLISION_HINT)
        self.stop = g.add_button("Stop", color="orange", icon=viser.Icon.PLAYER_STOP,
                                 disabled=True)
        self.resume = g.add_button("Resume", icon=viser.Icon.PLAYER_TRACK_NEXT, disabled=True,
                                   hint="Continue a stopped mission from where the robot is")
        self.why = g.add_markdown("")
        #: Shown only while the simulated robot stands against something unknown.
        self.halted = g.add_markdown(HALTED, visible=False)
        self.speed = g.add_dropdown(
            "Simulation speed", tuple(SPEEDS), initial_value="1x real time",
            hint=SPEED_HINT)
        self.legend = g.add_markdown(legend())
        self.summary = g.add_markdown("")
        with g.add_folder("Planner report", expand_by_default=False):
            self.report = g.add_markdown("")
        self.bind(self.plan, lambda e: self.session.start_plan())
        self.bind(self.execute, lambda e: self.session.start_execute(),
                  motion=True)
        self.bind(self.collision, lambda e: self.session.fire("collision"))
        self.bind(self.speed, lambda e: self._set_speed())
        self.bind(self.stop, lambda e: self.session.fire("stop"))
        self.bind(self.resume, lambda e: self.session.resume_execution(),
                  motion=True)
        self._resumable = False
        #: "Goal reached: ..." after a good run, until the mission is planned again.
        self._outcome = ""

    def on_enter(self) -> None:
        """Entering the step plans the mission when there is no plan yet (progress and Cancel
        in the toolbar), so the operator's first click here is Execute."""
        s = self.session
        if s.trajectory is None and s.mission.start is not None and \
                s.mission.goal is not None and s.machine.mode.value == "idle":
            with contextlib.suppress(Exception):  # the session has shown the reason
                s.start_plan()

    def _set_speed(self) -> None:
        label = self.speed.value
        scale = SPEEDS.get(label)
        if scale is not None and scale != self.session.link_settings.time_scale:
            self.session.set_simulation_speed(scale)

    def refresh(self) -> None:
        s = self.session
        mode = s.machine.mode.value
        has_plan = s.trajectory is not None
        wait = busy_reason(mode)
        label = "Re-plan" if has_plan else "Plan"
        if self.plan.label != label:
            self.plan.label = label
        not_moving = "" if mode == "moving" else "only while the robot moves"
        reasons = {
            label: wait,
            "Execute": wait or ("" if has_plan else "plan the mission first"),
            "Collision! / Stop": not_moving,
            "Resume": wait or ("" if self._resumable else "only after a stopped run"),
        }
        gate(self.plan, reasons[label], "Plan the mission in the known world")
        gate(self.execute, reasons["Execute"], "Run the planned mission on the robot")
        gate(self.collision, not_moving, COLLISION_HINT)
        gate(self.stop, not_moving, "Halt the robot")
        gate(self.resume, reasons["Resume"], "Continue a stopped mission from where it stopped")
        _content(self.why, why_greyed(reasons))
        ls = s.link_settings
        self.speed.visible = ls.kind == "simulated"
        gate(self.speed, wait, SPEED_HINT)
        if ls.kind == "simulated" and self.speed.value != speed_label(ls.time_scale):
            if speed_label(ls.time_scale) not in SPEEDS:
                self.speed.options = (*SPEEDS, speed_label(ls.time_scale))
            self.speed.value = speed_label(ls.time_scale)
        c = s.counters
        if has_plan:
            # The counts and times report.json gives (`assistant.session.report`).
            n, kinds = moves_words(s.trajectory.primitive_counts())
            plan_text = (f"Mission planned: {n} moves ({kinds}). Planning time "
                         f"{c.planning_time_s:.1f} s in all.")
        else:
            plan_text = "Mission not planned yet."
        learnt = "" if not c.collision_indications else \
            f" Collisions learnt: {c.collision_indications}, re-plans: {c.replans}."
        self.summary.content = (f"**{self._outcome}**\n\n" if self._outcome else "") + \
            plan_text + learnt
        self.report.content = report_markdown(s.plan_report)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, RobotHalted):
            self._halts = getattr(self, "_halts", 0) + 1  # numbered: each wants its press
            self.halted.content = f"{HALTED} (halt {self._halts} of this run)"
            self.halted.visible = True
        elif isinstance(ev, (CollisionRecorded, ExecutionFinished, ErrorRaised)) or \
                isinstance(ev, StateChanged) and self.session.machine.mode.value != "moving":
            self.halted.visible = False
            if not isinstance(ev, CollisionRecorded):
                self._halts = 0
        if isinstance(ev, ErrorRaised):
            self._resumable = "Resume" in ev.message
        elif isinstance(ev, ExecutionFinished):
            goal = self.session.mission.goal
            self._outcome = goal_reached(goal and goal.name, ev.summary) if ev.ok else ""
            self._after_run = ev.ok
        elif isinstance(ev, PlanReady):
            self._resumable = False
            if not getattr(self, "_after_run", False):
                self._outcome = ""  # planned again: the last run's outcome is history
            self._after_run = False
        if isinstance(ev, (StateChanged, PlanReady, CollisionRecorded, ErrorRaised)) or \
                isinstance(ev, SceneChanged) and ev.what in ("all", "mission", "plan", "world"):
            self.refresh()
