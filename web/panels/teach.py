"""Step 4.1 - teach locations: by the robot's pose, typed numbers, the marker pointer (dwell)
or a click on a part; then choose the mission's start and goal."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from assistant.session.events import Event, Notice, SceneChanged, StateChanged
from web.panels.base import Panel
from web.scene.picking import pick
from web.units import fmt_mm, point_from_mm, pose_from_fields

#: Tool pointing down (A, B, C = 0, 0, 180 deg) - the usual pose over a table.
DOWN_ABC = (0.0, 0.0, 180.0)


def next_free_name(existing: set[str], prefix: str = "P") -> str:
    nums = [int(m.group(1)) for n in existing if (m := re.fullmatch(rf"{prefix}(\d+)", n))]
    return f"{prefix}{max(nums, default=0) + 1}"


class TeachPanel(Panel):
    title = "Teach locations"
    steps = ("teach.locations",)

    def build(self) -> None:
        g = self.gui
        self.name = g.add_text("Name", "P1", hint="A letter, then letters, digits or _")
        self.five_axis = g.add_markdown("")
        with g.add_folder("With the pointer"):
            g.add_markdown("Hold the ball still at the spot: the cameras measure it.")
            self.point = g.add_vector3("Point (mm)", (300.0, 0.0, 100.0), step=1.0,
                                       hint="Synthetic camera: where the simulated hand holds "
                                            "the ball")
            self.seed = g.add_number("Simulation seed", 0, min=0, max=2**31 - 1, step=1,
                                     hint="Synthetic camera only: seed of its image noise")
            self.dwell = g.add_button("Teach by pointer dwell")
            self.pending = g.add_button("Teach the point just held", disabled=True)
        with g.add_folder("From the robot or by numbers", expand_by_default=False):
            self.from_robot = g.add_button("Teach the robot's pose")
            self.xyz = g.add_vector3("Position (mm)", (300.0, 0.0, 100.0), step=0.1)
            self.abc = g.add_vector3("A, B, C (deg)", DOWN_ABC, step=0.1)
            self.typed = g.add_button("Teach this pose")
        with g.add_folder("By clicking a part", expand_by_default=False):
            self.click_mode = g.add_checkbox("Click on a part teaches a point", False)
            g.add_markdown("The tool points against the surface you click.")
        with g.add_folder("Locations"):
            self.table = g.add_markdown("")
            self.pick = g.add_dropdown("Location", ("-",))
            self.set_start = g.add_button("Make it the start")
            self.set_goal = g.add_button("Make it the goal")
            self.delete = g.add_button("Delete it", color="red")
        self.bind(self.dwell, lambda e: self._teach(lambda n: self.session.teach_by_pointer_dwell(
            n, point_from_mm(self.point.value), seed=int(self.seed.value))))
        self.bind(self.pending, lambda e: self._teach(self.session.teach_pending_point))
        self.bind(self.from_robot, lambda e: self._teach(self.session.teach_from_robot))
        self.bind(self.typed, lambda e: self._teach(lambda n: self.session.teach(
            n, pose_from_fields(self.xyz.value, self.abc.value))))
        self.bind(self.set_start, lambda e: self.session.set_start(self.pick.value))
        self.bind(self.set_goal, lambda e: self.session.set_goal(self.pick.value))
        self.bind(self.delete, lambda e: self.session.remove_location(self.pick.value))
        self.app.scene_layers.objects.click_handlers.append(self._clicked)

    def _teach(self, fn: Any) -> None:
        name = self.name.value.strip()
        loc = fn(name)
        self.pick.options = tuple(self.session.locations) or ("-",)
        self.pick.value = loc.name
        self.name.value = next_free_name(set(self.session.locations))

    def _clicked(self, obj_name: str, ev: Any) -> None:
        if not (self.visible and self.click_mode.value):
            return
        obj = self.session.cell.objects.get(obj_name)
        if obj is None:
            return
        hit = pick(obj.display_mesh, obj.T_world_object, np.array(ev.ray_origin),
                   np.array(ev.ray_direction))
        if hit is None:
            return
        self.app.actions.run(lambda: self._teach(lambda n: self.session.teach_from_cad_click(
            n, hit.point_world, hit.normal_world)), ev.client)

    def refresh(self) -> None:
        s = self.session
        r = s.robot
        self.five_axis.content = "" if r.dof >= 6 else \
            f"<small>The {r.name} has {r.dof} axes: an orientation outside the arm's plane " \
            "is turned into it (the page says by how much).</small>"
        m = s.mission
        start = m.start.name if m.start is not None else None
        goal = m.goal.name if m.goal is not None else None
        if not s.locations:
            self.table.content = "*No locations yet.*"
        else:
            rows = ["| name | position (mm) | from | +- mm | |", "|---|---|---|---|---|"]
            for n, loc in s.locations.items():
                role = "start" if n == start else "goal" if n == goal else ""
                rows.append(f"| {n} | {fmt_mm(loc.position)} | {loc.source.value} | "
                            f"{loc.uncertainty_m * 1000:.1f} | {role} |")
            self.table.content = "\n".join(rows)
        names = tuple(s.locations) or ("-",)
        if tuple(self.pick.options) != names:
            self.pick.options = names
        empty = not s.locations
        self.set_start.disabled = self.set_goal.disabled = self.delete.disabled = empty
        self.pending.disabled = s.pending_point is None
        if self.name.value in s.locations:
            self.name.value = next_free_name(set(s.locations))

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("locations", "mission", "all", "robot") \
                or isinstance(ev, StateChanged):
            self.refresh()
        elif isinstance(ev, Notice) and self.visible:
            self.pending.disabled = self.session.pending_point is None
