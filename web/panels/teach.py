"""Step 4.1 - teach locations: by the robot's pose, typed numbers, the marker pointer (dwell)
or a click on a part; then choose the mission's start and goal."""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from assistant.robots.model import UnreachableError
from assistant.robots.reach import arm_reach
from assistant.session.events import Event, Notice, PointerUpdated, SceneChanged, StateChanged
from web.gui_value import set_value
from web.panels.base import Panel, gate, why_greyed
from web.scene.picking import pick
from web.scene.reach import ReachLayer, RefusedTarget
from web.units import ABC_CONVENTION, abc_shown, fmt_mm, point_from_mm, pose_from_fields

log = logging.getLogger(__name__)

#: Tool pointing down (A, B, C = 0, 0, 180 deg) - the usual pose over a table.
DOWN_ABC = (0.0, 0.0, 180.0)
#: Where the tool points when the pointer teaches (down, `teach_from_pointer`'s default).
DOWN = np.array([0.0, 0.0, -1.0])


def next_free_name(existing: set[str], prefix: str = "P") -> str:
    nums = [int(m.group(1)) for n in existing if (m := re.fullmatch(rf"{prefix}(\d+)", n))]
    return f"{prefix}{max(nums, default=0) + 1}"


def name_after(taught: str, existing: Iterable[str]) -> str:
    """The name to suggest after `taught`: its trailing number + 1 (P7 -> P8, SEAM_3 ->
    SEAM_4, P09 -> P10), `_2`, `_3`, ... after a name without one (SEAM -> SEAM_2); names in
    `existing` are skipped, compared without case (a controller does not tell P8 from p8)."""
    taken = {n.lower() for n in existing}
    m = re.fullmatch(r"(.*?)(\d+)", taught)
    stem, num, width = (m.group(1), int(m.group(2)), len(m.group(2))) if m else \
        (f"{taught}_", 1, 1)
    while True:
        num += 1
        name = f"{stem}{num:0{width}d}"
        if name.lower() not in taken:
            return name


class TeachPanel(Panel):
    title = "Teach locations"
    steps = ("teach.locations",)

    def build(self) -> None:
        g = self.gui
        self.name = g.add_text("Name", "P1", hint="A letter, then letters, digits or _")
        self.five_axis = g.add_markdown("")
        self.refused_md = g.add_markdown("", visible=False)
        with g.add_folder("With the pointer"):
            g.add_markdown("Hold the ball still at the spot: the cameras measure it.")
            self.point = g.add_vector3("Point (mm)", (300.0, 0.0, 100.0), step=1.0,
                                       hint="Synthetic camera: where the simulated hand holds "
                                            "the ball")
            self.dwell = g.add_button("Teach by pointer dwell")
            self.dwell_bar = g.add_progress_bar(0.0, visible=False, animated=False)
            self.dwell_md = g.add_markdown("", visible=False)
            self.pending = g.add_button("Teach the point just held", disabled=True)
            with g.add_folder("Synthetic camera (advanced)", expand_by_default=False):
                self.seed = g.add_number(
                    "Image noise seed", 0, min=0, max=2**31 - 1, step=1,
                    hint="Follows the location's number (P7: 7), so the same point taught "
                         "under the same name measures the same")
        with g.add_folder("From the robot or by numbers", expand_by_default=False):
            self.from_robot = g.add_button("Teach the robot's pose")
            self.xyz = g.add_vector3("Position (mm)", (300.0, 0.0, 100.0), step=0.1)
            self.abc = g.add_vector3("A, B, C (deg)", DOWN_ABC, step=0.1, hint=ABC_CONVENTION)
            g.add_markdown(f"<small>{ABC_CONVENTION}</small>")
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
            self.why = g.add_markdown("")
        #: The refused target and the arm's reach, drawn after an out-of-reach teach.
        self.reach = ReachLayer(self.app)
        #: The last location taught from this page: the Name field suggests the one after it.
        self._last_taught: str | None = None
        self._state_seen = ""
        self.bind(self.dwell, lambda e: self._dwell(e.client))
        self.name.on_update(lambda e: self._seed_from_name())
        self.seed.on_update(lambda e: self._seed_typed(e))
        self._seed_manual = False
        #: A, B, C as typed per location, to show them back as typed (see `abc_shown`).
        self._typed_abc: dict[str, tuple[float, ...]] = {}
        self.bind(self.pending, lambda e: self._teach(
            self.session.teach_pending_point, self._pending_position(), client=e.client))
        self.bind(self.from_robot, lambda e: self._teach(self.session.teach_from_robot))
        self.bind(self.typed, lambda e: self._teach_typed(e.client))
        self.bind(self.set_start, lambda e: self.session.set_start(self.pick.value))
        self.bind(self.set_goal, lambda e: self.session.set_goal(self.pick.value))
        self.bind(self.delete, lambda e: self.session.remove_location(self.pick.value))
        self.app.scene_layers.objects.click_handlers.append(self._clicked)

    def _name_seed(self) -> int:
        m = re.search(r"(\d+)$", self.name.value.strip())
        return int(m.group(1)) % 2**31 if m else 0

    def _seed_from_name(self) -> None:
        self._seed_manual = False
        if int(self.seed.value) != self._name_seed():
            set_value(self.seed, self._name_seed())

    def _seed_typed(self, e: Any) -> None:
        if e.client is not None:  # the operator chose a seed: it holds until the next name
            self._seed_manual = True

    def _dwell(self, client: Any = None) -> None:
        """The synthetic hand holds the ball still: the ball and the dwell's progress show
        while the cameras measure it (`PointerUpdated`); the button waits meanwhile."""
        gate(self.dwell, "Wait: the cameras are measuring the ball")
        set_value(self.dwell_bar, 0.0)
        self.dwell_md.content = "<small>Bringing the ball to the point...</small>"
        self.dwell_bar.visible = self.dwell_md.visible = True
        try:
            seed = int(self.seed.value) if self._seed_manual else self._name_seed()
            point = point_from_mm(self.point.value)
            self._teach(lambda n: self.session.teach_by_pointer_dwell(n, point, seed=seed),
                        point, DOWN, client=client)
        finally:
            gate(self.dwell, "")
            self.dwell_bar.visible = self.dwell_md.visible = False

    def _teach_typed(self, client: Any = None) -> None:
        abc = tuple(float(v) for v in self.abc.value)
        T = pose_from_fields(self.xyz.value, abc)
        loc = self._teach(lambda n: self.session.teach(n, T), T[:3, 3], T[:3, 2],
                          client=client)
        self._typed_abc[loc.name] = abc
        self.refresh()

    def _pending_position(self) -> np.ndarray | None:
        tp = self.session.pending_point
        return None if tp is None else np.asarray(tp.position_world, float)

    def _teach(self, fn: Callable[[str], Any], target: np.ndarray | None = None,
               tool_axis: np.ndarray | None = None, *, client: Any = None) -> Any:
        """Teach under the Name field's name. `target` (world, m) and `tool_axis` (world,
        unit: where the tool points): what to draw, with the arm's reach, if it is refused
        (and `client`'s camera turned onto it)."""
        self._hide_refused()  # the operator acts again: the last refusal is stale
        name = self.name.value.strip()
        try:
            loc = fn(name)
        except UnreachableError:
            # The session has said why (one error toast); the panel shows where and how far.
            if target is not None:
                try:
                    self._show_refused(name, target, tool_axis)
                    if client is not None:
                        self.reach.frame(client)
                except Exception:  # noqa: BLE001 - the drawing must not hide the refusal
                    log.exception("drawing the refused target failed")
            raise
        with self.session.settled():  # what it shows is saved (another page may teach too)
            self.pick.options = tuple(self.session.locations) or ("-",)
            set_value(self.pick, loc.name)
            self._typed_abc.pop(loc.name, None)  # taught again: its typed angles are gone
            self._last_taught = loc.name
            set_value(self.name, name_after(loc.name, self.session.locations))
        self._seed_from_name()
        return loc

    def _show_refused(self, name: str, target: np.ndarray, tool_axis: np.ndarray | None
                      ) -> None:
        """Draw the refused target and the arm's reach; say how far beyond it the target is."""
        s = self.session
        T_world_base = s.T_world_base()
        reach = arm_reach(s.robot)
        beyond = reach.beyond_world(target, T_world_base)
        shown = RefusedTarget(name or "?", np.asarray(target, float), tool_axis,
                              reach.centre_world(T_world_base), reach.radius, beyond)
        self.reach.show(shown)
        if beyond > 0:
            text = f"**{name}: {beyond * 1000:.0f} mm beyond the arm's reach** " \
                   f"({reach.radius * 1000:.0f} mm from the shoulder): the red ball and the " \
                   "blue sphere in the scene."
        else:
            text = f"**{shown.label}**: the point is within the arm's reach " \
                   f"({-beyond * 1000:.0f} mm inside the blue sphere), the tool's " \
                   "orientation or a joint limit is the problem."
        self.refused_md.content = f"<small>{text}</small>"
        self.refused_md.visible = True

    def _hide_refused(self) -> None:
        self.reach.hide()
        if self.refused_md.visible:
            self.refused_md.visible = False

    def _clicked(self, obj_name: str, ev: Any) -> None:
        if not (self.visible and self.click_mode.value):
            return
        obj = self.session.cell.objects.get(obj_name)
        if obj is None:
            return
        hit = pick(obj.part_mesh, obj.T_world_object, np.array(ev.ray_origin),
                   np.array(ev.ray_direction))
        if hit is None:
            return
        axis = -np.asarray(hit.normal_world, float)  # the tool points against the surface
        self.app.actions.run(lambda: self._teach(lambda n: self.session.teach_from_cad_click(
            n, hit.point_world, hit.normal_world), np.asarray(hit.point_world, float),
            axis / np.linalg.norm(axis), client=ev.client), ev.client)

    def refresh(self) -> None:
        s = self.session
        r = s.robot
        self.five_axis.content = "" if r.dof >= 6 else \
            f"<small>The {r.name} has {r.dof} axes: an orientation outside the arm's plane " \
            "is turned into it (the page says by how much).</small>"
        start, goal = s.mission.start, s.mission.goal  # location names
        if not s.locations:
            self.table.content = "*No locations yet.*"
        else:
            rows = ["| name | position (mm) | A, B, C (deg) | from | +- mm | |",
                    "|---|---|---|---|---|---|"]
            for n, loc in s.locations.items():
                role = "start" if n == start else "goal" if n == goal else ""
                abc = abc_shown(loc.T_world_tool, self._typed_abc.get(n))
                rows.append(f"| {n} | {fmt_mm(loc.position)} | "
                            f"({abc[0]:g}, {abc[1]:g}, {abc[2]:g}) | {loc.source.value} | "
                            f"{loc.uncertainty_m * 1000:.1f} | {role} |")
            self.table.content = "\n".join(rows)
        names = tuple(s.locations) or ("-",)
        if tuple(self.pick.options) != names:
            self.pick.options = names
        empty = not s.locations
        none = "teach a location first" if empty else ""
        for btn in (self.set_start, self.set_goal, self.delete):
            gate(btn, none)
        why = why_greyed({"Make it the start / goal, Delete": none})
        if self.why.content != why:
            self.why.content = why
        gate(self.pending, "" if s.pending_point is not None else
             "Hold the ball still first (step 3.2 starts the cameras)")
        if self.name.value.strip().lower() in {n.lower() for n in s.locations}:
            set_value(self.name, self._suggested_name())

    def _suggested_name(self) -> str:
        """After a teach from this page: the name after it; before: P1 or the next free P<k>."""
        s = self.session
        if self._last_taught is None:
            return next_free_name(set(s.locations))
        return name_after(self._last_taught, s.locations)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, StateChanged) and ev.state != self._state_seen or \
                isinstance(ev, SceneChanged) and ev.what in ("all", "robot"):
            self._hide_refused()  # another step or another robot: the refusal is history
        if isinstance(ev, StateChanged):
            self._state_seen = ev.state
        if isinstance(ev, SceneChanged) and ev.what in ("locations", "mission", "all", "robot") \
                or isinstance(ev, StateChanged):
            self.refresh()
        elif isinstance(ev, Notice) and self.visible:
            gate(self.pending, "" if self.session.pending_point is not None else
                 "Hold the ball still first (step 3.2 starts the cameras)")
        elif isinstance(ev, PointerUpdated) and self.visible:
            self._dwell_feedback(ev)

    def _dwell_feedback(self, ev: PointerUpdated) -> None:
        """The dwell's progress under the pointer buttons: while the synthetic hand holds the
        ball (the button runs) or while the live pointer is being held still."""
        running = self.dwell.disabled and self.dwell_bar.visible
        holding = ev.position is not None and ev.dwell_s > 0
        if not running:
            holding = holding and ev.dwell_progress > 0
            if self.dwell_bar.visible != holding:
                self.dwell_bar.visible = self.dwell_md.visible = holding
        if not holding:
            return
        held = ev.dwell_progress * ev.dwell_s
        set_value(self.dwell_bar, max(0.0, min(100.0, 100.0 * ev.dwell_progress)))
        self.dwell_md.content = f"<small>Hold still... {held:.1f} / {ev.dwell_s:.1f} s</small>"
