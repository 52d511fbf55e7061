"""Application paths (lines, arcs, Bezier chains) drawn from `session.path_polylines()`."""

from __future__ import annotations

import numpy as np

from assistant.session.events import Event, SceneChanged
from web.scene.base import Layer, node_key

PATH_COLOR = (30, 160, 60)


def segments(points: np.ndarray) -> np.ndarray:
    """A polyline (N, 3) as line segments (N-1, 2, 3) for `add_line_segments`."""
    p = np.asarray(points, np.float32)
    return np.stack([p[:-1], p[1:]], axis=1)


class PathsLayer(Layer):
    root = "/paths"

    def refresh(self) -> None:
        self.clear()
        for name, pts in self.session.path_polylines():
            if len(pts) < 2:
                continue
            key = f"{self.root}/{node_key(name)}"
            self._nodes[name] = self.scene.add_line_segments(
                key, segments(pts), PATH_COLOR, thickness=5.0, thickness_units="screen")
            mid = pts[len(pts) // 2]
            self._nodes[name + "/label"] = self.scene.add_label(
                f"{key}_label", name, position=mid + [0.0, 0.0, 0.03], font_screen_scale=0.8)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("mission", "locations", "all"):
            self.refresh()
