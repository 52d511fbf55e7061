"""Taught locations as labelled frames (start and goal say so), with their uncertainty."""

from __future__ import annotations

from assistant.session.events import Event, SceneChanged
from web.scene.base import Layer, node_key
from web.units import wxyz_position


class LocationsLayer(Layer):
    root = "/locations"

    def refresh(self) -> None:
        self.clear()
        s = self.session
        start, goal = s.mission.start, s.mission.goal  # location names
        for name, loc in s.locations.items():
            key = f"{self.root}/{node_key(name)}"
            wxyz, pos = wxyz_position(loc.T_world_tool)
            self._nodes[name] = self.scene.add_frame(
                key, axes_length=0.04, axes_radius=0.0025, origin_radius=0.005,
                wxyz=wxyz, position=pos)
            tag = " (start)" if name == start else " (goal)" if name == goal else ""
            self._nodes[name + "/label"] = self.scene.add_label(
                f"/labels/locations/{node_key(name)}", name + tag, position=pos + [0.0, 0.0, 0.02],
                font_screen_scale=0.9, anchor="bottom-center")
            if loc.uncertainty_m > 0:
                self._nodes[name + "/sigma"] = self.scene.add_icosphere(
                    f"{key}_sigma", radius=max(loc.uncertainty_m, 0.001), color=(255, 200, 0),
                    opacity=0.3, position=pos, cast_shadow=False, receive_shadow=False)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("locations", "mission", "all"):
            self.refresh()
