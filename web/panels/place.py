"""Step 3.1 - place objects: pick a part, type its pose (mm, degrees) or drag its gizmo, or
measure 3+ of its points with the robot and fit (the residual tells how good the fit is)."""

from __future__ import annotations

import numpy as np
import viser

from assistant.session.events import Event, SceneChanged, StateChanged
from assistant.transforms import inv_T
from web.panels.base import Panel
from web.units import fmt_mm, point_or_name, pose_fields, pose_from_fields

WORLD = "world"


class PlacePanel(Panel):
    title = "Place objects"
    steps = ("place.objects",)

    def build(self) -> None:
        g = self.gui
        g.add_markdown("Choose a part, then type its pose or drag the gizmo in the scene.")
        self.pick = g.add_dropdown("Part", ("-",))
        self.relative = g.add_dropdown("Relative to", (WORLD,),
                                       hint="Type the pose in the world or in a named frame")
        self.where = g.add_markdown("")
        self.xyz = g.add_vector3("Position (mm)", (0.0, 0.0, 0.0), step=0.1)
        self.abc = g.add_vector3("A, B, C (deg)", (0.0, 0.0, 0.0), step=0.1,
                                 hint="Rotations about Z, Y', X'' (KUKA convention)")
        self.apply = g.add_button("Place part")
        self.gizmo = g.add_checkbox("Gizmo in the scene", True)
        with g.add_folder("Place by measured points", expand_by_default=False):
            g.add_markdown("Touch a point of the real part with the tool, enter the same point "
                           "in the part's own frame, add the pair; 3 or more pairs fit the pose.")
            self.model_pt = g.add_vector3("On the part (mm)", (0.0, 0.0, 0.0), step=0.1)
            self.measured_pt = g.add_vector3("Measured (mm)", (0.0, 0.0, 0.0), step=0.1)
            self.measure = g.add_button("Measure with the robot TCP")
            self.add_pair = g.add_button("Add pair")
            self.pairs_md = g.add_markdown("")
            self.clear_pairs = g.add_button("Clear pairs")
            self.fit = g.add_button("Fit pose")
            self.fit_report = g.add_markdown("")
        with g.add_folder("Frames (3-point calibration)", expand_by_default=False):
            g.add_markdown("Name a frame and give three measured points - taught locations "
                           "(e.g. the tool touched to the pallet) or x y z in mm: the origin, "
                           "a point on +x, a point in the XY plane on the +y side.")
            self.frame_name = g.add_text("Frame name", "pallet")
            self.f_origin = g.add_text("Origin", "")
            self.f_x = g.add_text("On +x", "")
            self.f_xy = g.add_text("In XY (+y side)", "")
            self.calibrate = g.add_button("Calibrate frame")
            self.frames_md = g.add_markdown("")
        self.pairs: list[tuple[np.ndarray, np.ndarray]] = []
        self.pick.on_update(lambda e: self._show_pose())
        self.relative.on_update(lambda e: self._show_pose())
        self.bind(self.calibrate, lambda e: self._calibrate())
        self.gizmo.on_update(lambda e: self._sync_gizmo())
        self.bind(self.apply, lambda e: self._place())
        self.bind(self.measure, lambda e: self._measure())
        self.bind(self.add_pair, lambda e: self._add_pair())
        self.bind(self.clear_pairs, lambda e: self._clear_pairs())
        self.bind(self.fit, lambda e: self._fit())
        self.app.scene_layers.objects.on_gizmo_release = self._gizmo_released
        self.app.scene_layers.objects.click_handlers.append(self._clicked)

    # ------------------------------------------------------------------ actions
    def _frame(self) -> str | None:
        v = self.relative.value
        return None if v == WORLD or v not in self.session.cell.frames else v

    def _place(self) -> None:
        T = pose_from_fields(self.xyz.value, self.abc.value)
        frame = self._frame()
        if frame is None:
            self.session.place_object(self.pick.value, T)
        else:
            self.session.place_object_in_frame(self.pick.value, frame, T)

    def _calibrate(self) -> None:
        pts = [point_or_name(box.value, set(self.session.locations))
               for box in (self.f_origin, self.f_x, self.f_xy)]
        self.session.calibrate_frame(self.frame_name.value.strip(), *pts)

    def _gizmo_released(self, name: str, T: np.ndarray, ev: viser.TransformControlsEvent
                        ) -> None:
        if not self.visible:
            return
        self.app.actions.run(lambda: self.session.place_object(name, T), ev.client)

    def _clicked(self, name: str, ev: object) -> None:
        if self.visible and name in self.pick.options:
            self.pick.value = name

    def _measure(self) -> None:
        p = self.session.measure_with_robot()
        self.measured_pt.value = tuple(round(float(v) * 1000.0, 3) for v in p)

    def _add_pair(self) -> None:
        self.pairs.append((np.array(self.model_pt.value) / 1000.0,
                           np.array(self.measured_pt.value) / 1000.0))
        self._show_pairs()

    def _clear_pairs(self) -> None:
        self.pairs.clear()
        self.fit_report.content = ""
        self._show_pairs()

    def _fit(self) -> None:
        if len(self.pairs) < 3:
            raise ValueError(f"{len(self.pairs)} pair(s): measure at least 3 points that are "
                             "not on one line")
        model = np.array([a for a, _ in self.pairs])
        measured = np.array([b for _, b in self.pairs])
        fit = self.session.fit_object_pose(self.pick.value, model, measured)
        self.fit_report.content = "**Fit:** " + fit.summary().replace("\n", "\n\n")

    # ------------------------------------------------------------------ redraw
    def _show_pairs(self) -> None:
        if not self.pairs:
            self.pairs_md.content = "*No pairs yet.*"
            return
        rows = ["| # | on the part | measured |", "|---|---|---|"]
        rows += [f"| {i + 1} | {fmt_mm(a)} | {fmt_mm(b)} |" for i, (a, b) in
                 enumerate(self.pairs)]
        self.pairs_md.content = "\n".join(rows)

    def _show_pose(self) -> None:
        obj = self.session.cell.objects.get(self.pick.value)
        frame = self._frame()
        if obj is not None:
            T = obj.T_world_object if frame is None else \
                inv_T(np.asarray(self.session.cell.frames[frame])) @ obj.T_world_object
            xyz, abc = pose_fields(T)
            self.xyz.value, self.abc.value = xyz, abc
            # Written after the fields: once this line shows, the fields are the part's.
            rel = "" if frame is None else f" in {frame}"
            self.where.content = (f"<small>{obj.name} is at ({xyz[0]:g}, {xyz[1]:g}, "
                                  f"{xyz[2]:g}) mm, A B C ({abc[0]:g}, {abc[1]:g}, "
                                  f"{abc[2]:g}) deg{rel}</small>")
        else:
            self.where.content = ""
        self._sync_gizmo()

    def _sync_gizmo(self) -> None:
        on = self.visible and bool(self.gizmo.value) and self.pick.value in \
            self.session.cell.objects
        self.app.scene_layers.objects.show_gizmo(self.pick.value if on else None)

    def refresh(self) -> None:
        frames = (WORLD, *self.session.cell.frames)
        if tuple(self.relative.options) != frames:
            self.relative.options = frames
        self.frames_md.content = "" if len(frames) == 1 else \
            "<small>Frames: " + ", ".join(frames[1:]) + "</small>"
        names = tuple(self.session.cell.objects) or ("-",)
        if tuple(self.pick.options) != names:
            self.pick.options = names
        self.apply.disabled = self.fit.disabled = names == ("-",)
        self._show_pose()
        self._show_pairs()

    def show_for(self, state: str) -> None:
        super().show_for(state)
        self._sync_gizmo()

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("objects", "frames", "all") or \
                isinstance(ev, StateChanged):
            self.refresh()

