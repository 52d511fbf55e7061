"""Step 4.2 - application paths: lines, arcs and Bezier chains through taught locations, with
the gripper actions before and after; reorder and delete them."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from assistant.mission.model import Mission
from assistant.mission.motion import ToolAction, ToolActionKind
from assistant.session.events import Event, SceneChanged, StateChanged
from web.gui_value import set_value
from web.panels.base import Panel, gate

KINDS = {"line (2+ points)": "line", "arc (start, via, end)": "arc",
         "Bezier chain (1 + 3k points)": "bezier"}
ACTIONS: dict[str, list[ToolAction]] = {
    "nothing": [],
    "close the gripper": [ToolAction(ToolActionKind.GRIPPER_CLOSE)],
    "open the gripper": [ToolAction(ToolActionKind.GRIPPER_OPEN)],
}


def action_label(actions: list[ToolAction]) -> str:
    if not actions:
        return "-"
    return ", ".join(a.kind.value.replace("_", " ") for a in actions)


def parse_points(text: str) -> list[str]:
    names = [t for t in text.replace(";", ",").replace(" ", ",").split(",") if t]
    if not names:
        raise ValueError("list the path's points by name, e.g. 'P7, P8'")
    return names


def application_points(locations: Iterable[str], mission: Mission) -> list[str]:
    """The taught locations a new path most likely runs through, in the order they were
    taught (`locations` in insertion order): all but the mission's start and goal and those a
    path of the mission already uses."""
    taken = {n for n in (mission.start, mission.goal) if n is not None}
    taken |= {n for path in mission.paths for seg in path.segments for n in seg.names if n}
    return [n for n in locations if n not in taken]


def free_path_name(used: Iterable[str], prefix: str = "L") -> str:
    """L1, L2, ...: the first not used by a path (compared without case)."""
    taken = {n.lower() for n in used}
    k = 1
    while f"{prefix}{k}".lower() in taken:
        k += 1
    return f"{prefix}{k}"


class PathsPanel(Panel):
    title = "Application paths"
    steps = ("teach.paths",)

    def build(self) -> None:
        g = self.gui
        self.name = g.add_text("Path name", "L1")
        self.kind = g.add_dropdown("Kind", tuple(KINDS))
        self.points = g.add_text("Through", "", hint="Taught locations, in order (the "
                                 "ones no path uses yet, but the start and goal, by default)")
        #: The defaults last put in Name / Through: a field still showing its default was not
        #: typed in, so it follows the locations and paths; what the operator typed stays.
        self._auto_name = self.name.value
        self._auto_points = self.points.value
        self.before = g.add_dropdown("Before", tuple(ACTIONS), initial_value="close the gripper")
        self.after = g.add_dropdown("After", tuple(ACTIONS), initial_value="open the gripper")
        self.speed = g.add_number("Speed (mm/s)", 50.0, min=1.0, max=2000.0, step=1.0)
        self.add = g.add_button("Add path")
        with g.add_folder("Pen drawing on a frame", expand_by_default=False):
            g.add_markdown("One of the cell's drawings (1-3 frames, 4-6 keyboards, 7-9 screens) "
                           "as chained Bezier curves on a calibrated frame (step 3.1).")
            self.d_name = g.add_text("Drawing name", "DRAW1")
            self.d_frame = g.add_dropdown("On frame", ("-",))
            self.d_number = g.add_number("Drawing", 1, min=1, max=9, step=1)
            self.d_at = g.add_vector2("At (mm)", (0.0, 0.0), step=1.0,
                                      hint="Where the drawing's origin goes in the frame")
            self.d_angle = g.add_number("Turned (deg)", 0.0, step=1.0)
            self.d_lift = g.add_number("Pen lift (mm)", 30.0, min=1.0, max=200.0, step=1.0)
            self.add_drawing = g.add_button("Add drawing")
        with g.add_folder("Mission"):
            self.table = g.add_markdown("")
            self.pick = g.add_dropdown("Path", ("-",))
            self.order_btn = g.add_button("Order for the shortest transfers")
            self.up = g.add_button("Move up")
            self.down = g.add_button("Move down")
            self.set_actions = g.add_button("Use the Before/After above")
            self.delete = g.add_button("Delete path", color="red")
        self.bind(self.add, lambda e: self._add())
        self.bind(self.add_drawing, lambda e: self._add_drawing())
        self.bind(self.order_btn, lambda e: self._order(e.client))
        self.bind(self.up, lambda e: self._move(-1))
        self.bind(self.down, lambda e: self._move(+1))
        self.bind(self.set_actions, lambda e: self.session.set_path_actions(
            self.pick.value, ACTIONS[self.before.value], ACTIONS[self.after.value]))
        self.bind(self.delete, lambda e: self.session.remove_path(self.pick.value))

    def _add(self) -> None:
        name = self.name.value.strip()
        self.session.add_path(name, KINDS[self.kind.value], parse_points(self.points.value),
                              before=ACTIONS[self.before.value], after=ACTIONS[self.after.value],
                              speed=float(self.speed.value) / 1000.0)
        # Added: what was typed served its purpose, the next path gets fresh defaults.
        self._auto_name, self._auto_points = self.name.value, self.points.value
        self.refresh()

    def _order(self, client: object) -> None:
        names = self.session.order_mission()
        self.app.notifier.success("Paths in the order the robot will run them: "
                                  + ", ".join(names), client=client)  # type: ignore[arg-type]

    def _add_drawing(self) -> None:
        at = tuple(v / 1000.0 for v in self.d_at.value)
        self.session.add_drawing(self.d_name.value.strip(), self.d_frame.value,
                                 int(self.d_number.value), at=at,  # type: ignore[arg-type]
                                 angle=float(np.radians(self.d_angle.value)),
                                 lift=float(self.d_lift.value) / 1000.0,
                                 before=ACTIONS[self.before.value],
                                 after=ACTIONS[self.after.value],
                                 speed=float(self.speed.value) / 1000.0)

    def _move(self, delta: int) -> None:
        names = [p.name for p in self.session.mission.paths]
        i = names.index(self.pick.value)
        self.session.move_path(self.pick.value, max(0, i + delta))

    def refresh(self) -> None:
        s = self.session
        m = s.mission
        lines = [f"**Start:** {m.start or '- (teach one in 4.1)'} &nbsp; "
                 f"**Goal:** {m.goal or '-'}"]
        if m.paths:
            lines += ["", "| # | path | kind | segments | before | after | mm/s |",
                      "|---|---|---|---|---|---|---|"]
            for i, p in enumerate(m.paths):
                kinds = {seg.kind.value for seg in p.segments}
                lines.append(f"| {i + 1} | {p.name} | {'/'.join(sorted(kinds))} | "
                             f"{len(p.segments)} | {action_label(p.actions_before)} | "
                             f"{action_label(p.actions_after)} | {p.speed * 1000:.0f} |")
        else:
            lines.append("\n*No application paths yet.*")
        self.table.content = "\n".join(lines)
        frames = tuple(s.cell.frames) or ("-",)
        if tuple(self.d_frame.options) != frames:
            self.d_frame.options = frames
        gate(self.add_drawing, "" if s.cell.frames else
             "Calibrate a frame first (step 3.1, Frames)")
        names = tuple(p.name for p in m.paths) or ("-",)
        if tuple(self.pick.options) != names:
            self.pick.options = names
        empty = not m.paths
        for btn in (self.up, self.down, self.delete, self.set_actions, self.order_btn):
            gate(btn, "Add a path first" if empty else "")
        self._defaults()

    def _defaults(self) -> None:
        """Name and Through follow the mission unless the operator typed in them."""
        s = self.session
        used = [p.name for p in s.mission.paths]
        name = self.name.value.strip()
        if name == self._auto_name or name.lower() in {n.lower() for n in used}:
            self._auto_name = free_path_name(used)
            if self.name.value != self._auto_name:
                set_value(self.name, self._auto_name)
        if self.points.value.strip() == self._auto_points.strip():
            self._auto_points = ", ".join(application_points(s.locations, s.mission))
            if self.points.value != self._auto_points:
                set_value(self.points, self._auto_points)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("mission", "locations", "frames",
                                                        "all") or \
                isinstance(ev, StateChanged):
            self.refresh()
