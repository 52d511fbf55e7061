"""Step 5 - explore the workspace: build the world model (reachability, CAD, roads) with a
progress bar and Cancel, optionally move the robot around while pressing Collision! when it
would hit something. What the scene shows is the View panel's (`web.panels.view`)."""

from __future__ import annotations

import contextlib

import viser

from assistant.session.events import CollisionRecorded, Event, SceneChanged, StateChanged
from web.gui_value import set_value
from web.panels.base import Panel, busy_reason, gate, why_greyed

EXPLORE_MODES = {"random moves": "random", "along the roads": "roads", "replay the plan": "replay"}


class ExplorePanel(Panel):
    title = "Explore workspace"
    steps = ("explore",)

    def build(self) -> None:
        g = self.gui
        self.build_world = g.add_button("Build world model", icon=viser.Icon.CUBE)
        self.world_md = g.add_markdown("")
        with g.add_folder("Move the robot around", expand_by_default=False):
            self.mode = g.add_dropdown("How", tuple(EXPLORE_MODES))
            self.moves = g.add_number("Moves", 5, min=1, max=200, step=1)
            self.explore = g.add_button("Explore")
        # Collision! and Stop are the toolbar's (one of each on the page, and the Space key)
        self.why = g.add_markdown("")
        with g.add_folder("Advanced", expand_by_default=False):
            ws = self.session.world_settings
            self.resolution = g.add_number("Cell size (mm, 0 = auto)", ws.resolution_mm or 0.0,
                                           min=0.0, max=250.0, step=0.5,
                                           hint="Edge of an octree leaf; 0 sizes the cube to "
                                                "the arm with 32 leaves a side")
            self.samples = g.add_number("Joint samples", ws.joint_samples, min=10_000,
                                        max=50_000_000, step=10_000,
                                        hint="Joint positions sampled for 6- and 7-axis arms")
            self.memory = g.add_number("Memory budget (MB)", ws.memory_mb, min=64,
                                       max=65_536, step=64)
            self.clearance = g.add_number("Clearance (mm)", ws.clearance_mm, min=0.0,
                                          max=200.0, step=1.0)
            self.apply_settings = g.add_button("Apply settings",
                                               hint="The world model is rebuilt on the next "
                                                    "build or plan")
        self.bind(self.build_world, lambda e: self.session.start_build_world())
        self.bind(self.apply_settings, lambda e: self.session.set_world_settings(
            resolution_mm=float(self.resolution.value) or None,
            joint_samples=int(self.samples.value), memory_mb=int(self.memory.value),
            clearance_mm=float(self.clearance.value)))
        self.bind(self.explore, lambda e: self.session.start_explore(
            EXPLORE_MODES[self.mode.value], int(self.moves.value), seed=0), motion=True)

    def on_enter(self) -> None:
        """Entering the step builds the world model when there is none (progress and Cancel
        in the toolbar): it is what the step is for, and the operator saves a click."""
        s = self.session
        if not s.world_ready and s.machine.mode.value == "idle":
            with contextlib.suppress(Exception):  # the session has shown the reason
                s.start_build_world()

    def refresh(self) -> None:
        s = self.session
        mode = s.machine.mode.value
        wait = busy_reason(mode)
        gate(self.build_world, wait, "Map the parts and the robot's reach")
        gate(self.apply_settings, wait, "The world model is rebuilt on the next build or plan")
        ws = s.world_settings
        if ws != getattr(self, "_shown", None):  # changed (applied, loaded): show it; else
            self._shown = ws  # leave what the operator is typing alone
            for handle, value in ((self.resolution, ws.resolution_mm or 0.0),
                                  (self.samples, ws.joint_samples), (self.memory, ws.memory_mb),
                                  (self.clearance, ws.clearance_mm)):
                set_value(handle, value)
        reasons = {"Build world model": wait,
                   "Explore": wait or ("" if s.world_ready else "build the world model first")}
        gate(self.explore, reasons["Explore"])
        why = "" if mode == "moving" else why_greyed(reasons)  # the heading says it then
        if self.why.content != why:
            self.why.content = why
        if s.world_ready:
            n = s.counters.collision_indications
            learnt = "" if not n else f" {n} collision{'s' if n != 1 else ''} learnt so far."
            self.world_md.content = ("World model ready: the parts and the space the robot can "
                                     "reach are mapped, and the planner knows where it may "
                                     "move (Scene layers: Occupied cells, Roads)." + learnt)
        else:
            self.world_md.content = "*No world model for the current cell yet.*"

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, (StateChanged, CollisionRecorded)) or \
                isinstance(ev, SceneChanged) and ev.what in ("world", "objects", "all"):
            self.refresh()
