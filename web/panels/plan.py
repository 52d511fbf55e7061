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
from assistant.session.run_state import RunPhase
from web.gui_value import set_value
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


SPEED_HINT = "How fast the simulated robot moves: 1x is as fast as the real robot, slow " \
    "enough to watch it and press Collision! in time"

#: Choices of the simulated robot's speed, in times real time (1 = as fast as the real one).
SPEEDS = {"0.5x real time": 0.5, "1x real time": 1.0, "2x real time": 2.0,
          "5x real time": 5.0, "20x real time": 20.0}


FORGET_HINT = ("Forget what this collision indication taught: plans may pass there again. "
               "Only when you know nothing is there (a false alarm, an object removed)")

DRIVE_FINAL_HINT = ("Drives the robot from where it stands to the start, then through the "
                    "final program once (drawn in the scene) - to check it on the robot")


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
        # Collision! and Stop are the toolbar's (one of each on the page, and the Space key)
        self.resume = g.add_button("Resume", icon=viser.Icon.PLAYER_TRACK_NEXT, disabled=True,
                                   hint="Continue a stopped mission from where the robot is")
        self.drive_final = g.add_button("Drive the final program once",
                                        icon=viser.Icon.PLAYER_PLAY, visible=False,
                                        hint=DRIVE_FINAL_HINT)
        self.why = g.add_markdown("")
        self.speed = g.add_dropdown(
            "Simulation speed", tuple(SPEEDS), initial_value="1x real time",
            hint=SPEED_HINT)
        self.legend = g.add_markdown(legend())
        self.summary = g.add_markdown("")
        with g.add_folder("Planner report", expand_by_default=False):
            self.report = g.add_markdown("")
        with g.add_folder("Learnt collisions", expand_by_default=False) as self.learnt_folder:
            self.learnt = g.add_markdown("")
            self.forget_choice = g.add_dropdown("Indication", ("-",), hint=FORGET_HINT)
            self.forget = g.add_button("Forget this indication", icon=viser.Icon.ERASER,
                                       hint=FORGET_HINT)
        self.bind(self.plan, lambda e: self.session.start_plan())
        self.bind(self.execute, lambda e: self.session.start_execute(),
                  motion=True)
        self.bind(self.speed, lambda e: self._set_speed())
        self.bind(self.resume, lambda e: self.session.resume_execution(),
                  motion=True)
        self.bind(self.drive_final, lambda e: self.session.start_drive_final(), motion=True)
        self.bind(self.forget, lambda e: self._forget())

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

    def _forget(self) -> None:
        number = self.forget_choice.value.split(":", 1)[0]
        if number.isdigit():
            self.session.forget_indication(int(number))

    def _refresh_learnt(self, wait: str) -> None:
        """The learnt indications, numbered as a blocked re-plan names them, and the control
        that forgets one (the offer a re-plan makes when an inference blocks the goal)."""
        learnt = self.session.learnt_indications()
        self.learnt_folder.visible = bool(learnt)
        _content(self.learnt, "\n\n".join(f"<small>{t}</small>" for t in learnt))
        options = tuple(learnt) or ("-",)
        if tuple(self.forget_choice.options) != options:
            self.forget_choice.options = options
        gate(self.forget, wait or ("" if learnt else "nothing learnt"), FORGET_HINT)
        gate(self.forget_choice, wait, FORGET_HINT)

    def refresh(self) -> None:
        s = self.session
        mode = s.machine.mode.value
        run = s.run_state()
        has_plan = s.trajectory is not None
        wait = busy_reason(mode)
        label = "Re-plan" if has_plan else "Plan"
        if self.plan.label != label:
            self.plan.label = label
        stopped = run.phase == RunPhase.STOPPED
        reasons = {
            label: wait,
            "Execute": wait or ("" if has_plan else "plan the mission first"),
            "Resume": wait or ("" if stopped else "only after a stopped run"),
        }
        shown = {label, "Execute"} | ({"Resume"} if stopped else set())
        gate(self.plan, reasons[label], "Plan the mission in the known world")
        gate(self.execute, reasons["Execute"], "Run the planned mission on the robot")
        gate(self.resume, reasons["Resume"], "Continue a stopped mission from where it stopped")
        self.resume.visible = stopped  # a control of a stopped run only
        offer = run.phase == RunPhase.DONE and run.final_driven is False
        self.drive_final.visible = offer
        gate(self.drive_final, wait, DRIVE_FINAL_HINT)
        # While a run has the robot the heading says what to do; greyed reasons would only
        # repeat "the robot is moving" under it.
        _content(self.why, "" if run.robot_in_run else
                 why_greyed({k: v for k, v in reasons.items() if k in shown}))
        ls = s.link_settings
        self.speed.visible = ls.kind == "simulated"
        gate(self.speed, wait, SPEED_HINT)
        if ls.kind == "simulated" and self.speed.value != speed_label(ls.time_scale):
            if speed_label(ls.time_scale) not in SPEEDS:
                self.speed.options = (*SPEEDS, speed_label(ls.time_scale))
            set_value(self.speed, speed_label(ls.time_scale))
        c = s.counters
        if s.trajectory is not None:  # has_plan
            # The counts and times report.json gives (`assistant.session.report`).
            n, kinds = moves_words(s.trajectory.primitive_counts())
            plan_text = (f"Mission planned: {n} moves ({kinds}). Planning time "
                         f"{c.planning_time_s:.1f} s in all.")
        else:
            plan_text = "Mission not planned yet."
        learnt = "" if not c.collision_indications else \
            f" Collisions learnt: {c.collision_indications}, re-plans: {c.replans}."
        outcome = ""
        if run.phase in (RunPhase.DONE, RunPhase.STOPPED):
            head = goal_reached(s.mission.goal, s.last_run or {}) \
                if run.phase == RunPhase.DONE else ""
            outcome = "\n\n".join(x for x in (f"**{head}**" if head else "", run.sentence)
                                  if x) + "\n\n"
        self.summary.content = outcome + plan_text + learnt
        self.report.content = report_markdown(s.plan_report)
        self._refresh_learnt(wait)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, (StateChanged, PlanReady, CollisionRecorded, ErrorRaised,
                           ExecutionFinished, RobotHalted)) or \
                isinstance(ev, SceneChanged) and ev.what in ("all", "mission", "plan", "world"):
            self.refresh()
