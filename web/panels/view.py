"""The scene-layer switches, on every step: which scene layers are drawn (parts, the planned path,
names, the world model's occupied cells, the learnt obstacle, the roads).

Each step starts with what it needs: the occupied cells in step 5 (building the world model)
only - elsewhere their shell around the table hides the path; roads never by default
(hundreds of dots); the learnt obstacle, parts, path and labels always. A switch the
operator flips holds until the step changes."""

from __future__ import annotations

from typing import Any

from assistant.session.events import Event, StateChanged
from web.gui_value import set_value
from web.panels.base import Panel
from workflow.states import leaves

#: Main steps that show the world model's occupied cells by default: none - over a whole
#: table they hide the cell; the layer is the operator's to turn on (Scene layers).
OCCUPANCY_STEPS: tuple[str, ...] = ()

#: Panels of the steps come first (10, 20), the layers before the session box (1000).
VIEW_ORDER = 900.0


class ViewPanel(Panel):
    title = "Scene layers"
    order = VIEW_ORDER
    expand = False

    def __init__(self, app: Any):
        self.steps = tuple(leaves())
        super().__init__(app)
        self._main = app.session.machine.state.split(".")[0]
        self._defaults_for(app.session.machine.state)

    def build(self) -> None:
        g = self.gui
        world = self.app.scene_layers.world
        self.parts = g.add_checkbox("Parts", True, hint="The cell's parts (CAD and shapes)")
        self.path = g.add_checkbox("Planned path", True)
        self.labels = g.add_checkbox("Labels", True, hint="Names of parts and locations")
        self.occupied = g.add_checkbox("Occupied cells", world.show_occupancy,
                                       hint="The world model: cells the robot must avoid")
        self.min_p = g.add_slider("From probability", 0.0, 1.0, 0.05, world.min_p,
                                  hint="Show cells at least this likely to be occupied")
        self.learnt = g.add_checkbox("Learnt obstacle", world.show_learnt,
                                     hint="What the collision indications taught: the cells "
                                          "no CAD part explains")
        self.roads = g.add_checkbox("Roads", world.show_roads,
                                    hint="The free corridors the planner searches along")
        layers = self.app.scene_layers
        self.parts.on_update(lambda e: layers.set_group_visible("objects", self.parts.value))
        self.path.on_update(lambda e: layers.set_group_visible("plan", self.path.value))
        self.labels.on_update(lambda e: self._labels())
        self.occupied.on_update(lambda e: world.set_visibility(occupancy=self.occupied.value))
        self.learnt.on_update(lambda e: world.set_visibility(learnt=self.learnt.value))
        self.roads.on_update(lambda e: world.set_visibility(roads=self.roads.value))
        self.min_p.on_update(self._min_p)

    def _labels(self) -> None:
        on = bool(self.labels.value)
        self.app.scene_layers.set_group_visible("labels", on)
        self.app.scene_layers.world.set_visibility(labels=on)

    def _min_p(self, e: Any) -> None:
        if e.client is None:
            return
        self.app.scene_layers.world.min_p = float(self.min_p.value)
        self.app.pump.post(self.app.scene_layers.world.refresh)

    def _defaults_for(self, state: str) -> None:
        on = state.split(".")[0] in OCCUPANCY_STEPS
        if self.occupied.value != on:
            set_value(self.occupied, on)
        self.app.scene_layers.world.set_visibility(occupancy=on)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, StateChanged) and ev.state.split(".")[0] != self._main:
            self._main = ev.state.split(".")[0]
            self._defaults_for(ev.state)
