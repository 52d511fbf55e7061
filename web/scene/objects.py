"""Cell objects coloured by role, clickable (CAD-click teaching, selection), labelled with their
names, and the placement gizmo of the selected object."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from assistant.session.events import Event, SceneChanged
from web.scene.base import Layer, node_key
from web.units import T_from_wxyz_position, wxyz_position

#: Called with (object name, click event) when the operator clicks a part.
ClickHandler = Callable[[str, Any], None]


def _rgb(color: tuple[int, int, int] | None) -> tuple[int, int, int]:
    assert color is not None  # a CellObject's colour is set when it is made (its role's)
    return (int(color[0]), int(color[1]), int(color[2]))


def label_position(bounds: Any, T_world_object: Any) -> tuple[float, float, float]:
    """Just above the middle of a part's top, in the world (its bounding box turned)."""
    lo, hi = np.asarray(bounds, dtype=float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    T = np.asarray(T_world_object, dtype=float)
    w = corners @ T[:3, :3].T + T[:3, 3]
    mid = (w.min(axis=0) + w.max(axis=0)) / 2.0
    return float(mid[0]), float(mid[1]), float(w[:, 2].max() + 0.01)


class ObjectsLayer(Layer):
    root = "/objects"

    def __init__(self, app: Any):
        super().__init__(app)
        self.click_handlers: list[ClickHandler] = []
        self._gizmo: viser.TransformControlsHandle | None = None
        self._gizmo_object: str | None = None
        #: Called with (object name, T_world_object) when the operator releases the gizmo.
        self.on_gizmo_release: Callable[[str, np.ndarray, Any], None] | None = None

    def refresh(self) -> None:
        """Parts are drawn with toon shading: their role colour is what matters, and without a
        GPU the default PBR material makes the parts (a table fills much of the view) cost
        about half of every frame (software WebGL)."""
        self.clear()
        for obj in self.session.scene_objects():
            wxyz, pos = wxyz_position(obj.T_world_object)
            mesh = obj.display_mesh
            h = self.scene.add_mesh_simple(
                f"{self.root}/{node_key(obj.name)}", np.asarray(mesh.vertices, np.float32),
                np.asarray(mesh.faces, np.uint32), color=_rgb(obj.color),
                wxyz=wxyz, position=pos, side="double", material="toon3", cast_shadow=False,
                receive_shadow=False)
            h.on_click(self._clicking(obj.name))
            self._nodes[obj.name] = h
            self._nodes[obj.name + "/label"] = self.scene.add_label(
                f"/labels/objects/{node_key(obj.name)}", obj.name,
                position=label_position(mesh.bounds, obj.T_world_object),
                font_screen_scale=0.9, anchor="bottom-center")
        self._sync_gizmo()

    def _clicking(self, name: str) -> Callable[[Any], None]:
        """The click callback of object `name`'s mesh."""
        return lambda ev: self._clicked(name, ev)

    def _clicked(self, name: str, ev: Any) -> None:
        for fn in list(self.click_handlers):
            fn(name, ev)

    # ------------------------------------------------------------------ gizmo
    def show_gizmo(self, name: str | None) -> None:
        """Put the placement gizmo on one object (None: no gizmo)."""
        self._gizmo_object = name
        self._sync_gizmo()

    def _sync_gizmo(self) -> None:
        objs = {o.name: o for o in self.session.scene_objects()}
        name = self._gizmo_object
        if name is None or name not in objs:
            if self._gizmo is not None:
                self._gizmo.remove()
                self._gizmo = None
            return
        wxyz, pos = wxyz_position(objs[name].T_world_object)
        if self._gizmo is None:
            self._gizmo = self.scene.add_transform_controls(
                "/gizmo/object", scale=0.18, line_width=3.0, depth_test=False,
                wxyz=wxyz, position=pos)
            self._gizmo.on_update(self._released)
        else:
            self._gizmo.wxyz, self._gizmo.position = wxyz, pos

    def _released(self, ev: Any) -> None:
        if getattr(ev, "phase", "end") != "end" or ev.client is None:
            return  # only the operator's release places the part
        if self._gizmo is None or self._gizmo_object is None or self.on_gizmo_release is None:
            return
        T = T_from_wxyz_position(self._gizmo.wxyz, self._gizmo.position)
        self.on_gizmo_release(self._gizmo_object, T, ev)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("objects", "all"):
            self.refresh()
