"""The robot: one mesh per link, posed from the joints on every `RobotMoved`, and its TCP; the
links a start posture touches the cell with are red."""

from __future__ import annotations

import numpy as np

from assistant.session.events import Event, RobotMoved, SceneChanged
from web.scene.base import Layer, node_key
from web.units import wxyz_position

#: Links of a start posture that touches the cell (`Session.start_posture_links`).
TOUCHING = (220, 40, 40)


class RobotLayer(Layer):
    root = "/robot"

    def refresh(self) -> None:
        self.clear()
        touching = set(self.session.start_posture_links())
        for name, mesh, color in self.session.robot_visuals():
            if name in touching:  # the start posture touches the cell here: red
                color = TOUCHING
            self._nodes[name] = self.scene.add_mesh_simple(
                f"{self.root}/{node_key(name)}", np.asarray(mesh.vertices, np.float32),
                np.asarray(mesh.faces, np.uint32),
                color=(int(color[0]), int(color[1]), int(color[2])),
                flat_shading=False, cast_shadow=False, receive_shadow=False)
        self._nodes["__tcp__"] = self.scene.add_frame(
            f"{self.root}/tcp", axes_length=0.05, axes_radius=0.003, origin_radius=0.006)
        self.pose(self.session.current_joints())

    def pose(self, q: np.ndarray) -> None:
        s = self.session
        T_links = s.link_poses_world(q)
        names = [n for n, _, _ in s.robot_visuals()]
        all_names = [lk.name for lk in s.robot.links]
        with self.app.server.atomic():
            for name in names:
                h = self._nodes.get(name)
                if h is None or name not in all_names:
                    continue
                wxyz, pos = wxyz_position(T_links[all_names.index(name)])
                h.wxyz, h.position = wxyz, pos
            tcp = self._nodes.get("__tcp__")
            if tcp is not None:
                tcp.wxyz, tcp.position = wxyz_position(s.tcp_world(q))

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, RobotMoved):
            self.pose(ev.q)
        elif isinstance(ev, SceneChanged) and ev.what in ("robot", "all", "link", "start"):
            self.refresh()
