"""Step 6 - plan and execute: plan (progress + Cancel), watch the robot run the plan, press the
big red Collision! (or Space) the moment it would hit something; the assistant records the
posture, re-plans and carries on. The path is drawn with lines and arcs in their own colours."""

from __future__ import annotations

from typing import Any

import viser

from assistant.session.events import (
    CollisionRecorded,
    ErrorRaised,
    Event,
    PlanReady,
    SceneChanged,
    StateChanged,
)
from web.panels.base import Panel
from web.scene.plan import KIND_COLORS

LEGEND_NAMES = {"joint": "joint move (MOV/PTP)", "linear": "line (MVS/LIN)",
                "circular": "arc (MVR/CIRC)", "spline": "curve (SPLINE)"}


def legend() -> str:
    items = [f"<span style='color:rgb{c}'>&#9644;</span> {LEGEND_NAMES[k]}"
             for k, c in KIND_COLORS.items()]
    return "<small>" + " &nbsp; ".join(items) + "</small>"


def report_markdown(report: dict[str, Any] | None) -> str:
    """The planner's report as a short list (scalars only; nested detail stays in the file)."""
    if not report:
        return "*Not planned yet.*"
    rows = []
    for k, v in report.items():
        if isinstance(v, float):
            rows.append(f"- {k.replace('_', ' ')}: {v:.3g}")
        elif isinstance(v, (int, str, bool)):
            rows.append(f"- {k.replace('_', ' ')}: {v}")
    return "\n".join(rows[:14])


class PlanPanel(Panel):
    title = "Plan & execute"
    steps = ("plan",)

    def build(self) -> None:
        g = self.gui
        self.plan = g.add_button("Plan", icon=viser.Icon.ROUTE)
        self.execute = g.add_button("Execute on the robot", icon=viser.Icon.PLAYER_PLAY,
                                    disabled=True)
        self.collision = g.add_button("Collision!", color="red", icon=viser.Icon.ALERT_OCTAGON,
                                      disabled=True, hint="Space key. Stops the robot, remembers "
                                                          "the posture, re-plans")
        self.stop = g.add_button("Stop", color="orange", icon=viser.Icon.PLAYER_STOP,
                                 disabled=True)
        self.resume = g.add_button("Resume", icon=viser.Icon.PLAYER_TRACK_NEXT, disabled=True,
                                   hint="Continue a stopped mission from where the robot is")
        self.legend = g.add_markdown(legend())
        self.summary = g.add_markdown("")
        with g.add_folder("Planner report", expand_by_default=False):
            self.report = g.add_markdown("")
        self.bind(self.plan, lambda e: self.session.start_plan())
        self.bind(self.execute, lambda e: self.session.start_execute(),
                  motion=True)
        self.bind(self.collision, lambda e: self.session.fire("collision"))
        self.bind(self.stop, lambda e: self.session.fire("stop"))
        self.bind(self.resume, lambda e: self.session.resume_execution(),
                  motion=True)
        self._resumable = False

    def refresh(self) -> None:
        s = self.session
        mode = s.machine.mode.value
        idle = mode == "idle"
        has_plan = s.trajectory is not None
        self.plan.disabled = not idle
        self.plan.label = "Re-plan" if has_plan else "Plan"
        self.execute.disabled = not (idle and has_plan)
        self.collision.disabled = mode != "moving"
        self.stop.disabled = mode != "moving"
        self.resume.disabled = not (idle and self._resumable)
        c = s.counters
        drawn = self.app.scene_layers.plan.motions_drawn
        state = "planned" if has_plan else "not planned yet"
        self.summary.content = (f"Mission {state}; {drawn} motions drawn. Collisions recorded: "
                                f"{c.collision_indications}, re-plans: {c.replans}, "
                                f"planning time {c.planning_time_s:.1f} s.")
        self.report.content = report_markdown(s.plan_report)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, ErrorRaised):
            self._resumable = "Resume" in ev.message
        elif isinstance(ev, PlanReady):
            self._resumable = False
        if isinstance(ev, (StateChanged, PlanReady, CollisionRecorded, ErrorRaised)) or \
                isinstance(ev, SceneChanged) and ev.what in ("all", "mission", "plan", "world"):
            self.refresh()
