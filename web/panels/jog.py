"""Jogging: a slider per joint and a gizmo on the TCP that moves the robot by IK. On a 5-axis
arm the gizmo snaps back into the arm's plane after the move, and the page says by how much
the orientation was turned - the constraint is visible, not hidden."""

from __future__ import annotations

from typing import Any

import numpy as np
import viser

from assistant.session.events import Event, RobotMoved, SceneChanged, StateChanged
from web.gui_value import set_value
from web.panels.base import Panel
from web.units import T_from_wxyz_position, fmt_mm, pose_fields, wxyz_position


class JogPanel(Panel):
    title = "Jog the robot"
    steps = ("setup", "place.objects", "teach.locations", "explore")
    order = 20.0
    expand = False

    def build(self) -> None:
        self.readout = self.gui.add_markdown("")
        self.sliders_box = self.gui.add_folder(None)
        self.sliders: list[viser.GuiSliderHandle] = []
        self.move = self.gui.add_button("Move to the slider values")
        self.home = self.gui.add_button("Sliders to where the robot is")
        self.tcp_gizmo = self.gui.add_checkbox("TCP gizmo in the scene", False)
        self.touching = self.gui.add_markdown("", visible=False)
        self.free = self.gui.add_button("Move to a free posture", visible=False,
                                        hint="Out of what the robot's posture touches, to "
                                             "the nearest free posture, touching nothing new")
        self._gizmo: viser.TransformControlsHandle | None = None
        self._robot_key: Any = None
        self.bind(self.move, lambda e: self._move(), motion=True)
        self.bind(self.home, lambda e: self._sliders_to_robot())
        self.tcp_gizmo.on_update(lambda e: self._sync_gizmo())
        self.bind(self.free, lambda e: self.session.move_to_free_posture(wait=False),
                  motion=True)

    # ------------------------------------------------------------------ sliders
    def _build_sliders(self) -> None:
        r = self.session.robot
        key = (r.name, tuple(r.joint_names), tuple(r.limits.lower), tuple(r.limits.upper))
        if key == self._robot_key:
            return
        self._robot_key = key
        for s in self.sliders:
            s.remove()
        self.sliders = []
        q = self.session.current_joints()
        with self.sliders_box:
            for i, name in enumerate(r.joint_names):
                lo, hi = np.degrees(r.limits.lower[i]), np.degrees(r.limits.upper[i])
                self.sliders.append(self.gui.add_slider(
                    f"{name} (deg)", float(np.floor(lo)), float(np.ceil(hi)), 0.5,
                    float(np.clip(round(np.degrees(q[i]), 1), lo, hi))))

    def _sliders_to_robot(self) -> None:
        q = np.degrees(self.session.current_joints())
        for s, v in zip(self.sliders, q, strict=False):
            set_value(s, float(np.clip(round(float(v), 1), s.min, s.max)))

    def _move(self) -> None:
        q = np.radians([s.value for s in self.sliders])
        self.session.jog_joints(q, wait=False)

    # ------------------------------------------------------------------ TCP gizmo
    def _sync_gizmo(self) -> None:
        on = self.visible and bool(self.tcp_gizmo.value)
        if not on:
            if self._gizmo is not None:
                self._gizmo.remove()
                self._gizmo = None
            return
        wxyz, pos = wxyz_position(self.session.tcp_world())
        if self._gizmo is None:
            self._gizmo = self.app.server.scene.add_transform_controls(
                "/gizmo/tcp", scale=0.12, line_width=3.0, depth_test=False, wxyz=wxyz,
                position=pos)
            self._gizmo.on_update(self._gizmo_moved)
        else:
            self._gizmo.wxyz, self._gizmo.position = wxyz, pos

    def _gizmo_moved(self, ev: Any) -> None:
        if ev.phase != "end" or ev.client is None or self._gizmo is None:
            return
        T = T_from_wxyz_position(self._gizmo.wxyz, self._gizmo.position)
        self.app.actions.run(lambda: self.session.jog_tcp(T, wait=False), ev.client,
                             motion=True)

    # ------------------------------------------------------------------ redraw
    def _readout(self, q: np.ndarray) -> None:
        s = self.session
        deg = ", ".join(f"{n} {np.degrees(v):.1f}" for n, v in zip(s.robot.joint_names, q,
                                                                   strict=False))
        xyz, abc = pose_fields(s.tcp_world(q))
        self.readout.content = f"<small>Joints (deg): {deg}<br>TCP (mm): " \
                               f"{fmt_mm(np.array(xyz) / 1000.0)}, A, B, C (deg) " \
                               f"({_deg(abc[0])}, {_deg(abc[1])}, {_deg(abc[2])})</small>"

    def refresh(self) -> None:
        self._build_sliders()
        self._readout(self.session.current_joints())
        idle = self.session.machine.mode.value == "idle"
        self.move.disabled = not idle
        self._sync_gizmo()
        self._start_touching()

    def _start_touching(self) -> None:
        """The start posture's contacts (checked when the cell changes) and the way out."""
        s = self.session
        links = s.start_posture_links()
        self.touching.visible = self.free.visible = bool(links)
        self.free.disabled = s.machine.mode.value != "idle"
        if links:
            self.touching.content = (f"**The robot's posture touches something:** "
                                     f"{s.start_posture_text()}. Move it to a free posture "
                                     "before planning.")

    def show_for(self, state: str) -> None:
        super().show_for(state)
        self._sync_gizmo()

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, RobotMoved):
            if self.visible:
                self._readout(ev.q)
        elif isinstance(ev, StateChanged):
            self.refresh()
            if ev.mode == "idle":
                self._sliders_to_robot()
        elif isinstance(ev, SceneChanged) and ev.what in ("robot", "all"):
            self.refresh()
        elif isinstance(ev, SceneChanged) and ev.what == "start":
            self._start_touching()


def _deg(v: float) -> str:
    """One decimal, and never "-0.0" for a tiny negative angle."""
    return f"{(v if abs(v) >= 0.05 else 0.0):.1f}"
