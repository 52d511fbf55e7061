"""Named cell frames (e.g. a pallet calibrated from three points) as large labelled axes."""

from __future__ import annotations

from assistant.session.events import Event, SceneChanged
from web.scene.base import Layer, node_key
from web.units import wxyz_position


class FramesLayer(Layer):
    root = "/frames"

    def refresh(self) -> None:
        self.clear()
        for name, T in self.session.cell.frames.items():
            key = f"{self.root}/{node_key(name)}"
            wxyz, pos = wxyz_position(T)
            self._nodes[name] = self.scene.add_frame(
                key, axes_length=0.08, axes_radius=0.003, origin_radius=0.006, wxyz=wxyz,
                position=pos)
            self._nodes[name + "/label"] = self.scene.add_label(
                f"{key}_label", f"frame {name}", position=pos + [0.0, 0.0, 0.025],
                font_screen_scale=0.85)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("frames", "all"):
            self.refresh()
