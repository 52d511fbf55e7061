"""Step 3.1 - place objects: pick a part, type its pose (mm, degrees) or drag its gizmo, or
measure 3+ of its points with the robot and fit (the residual tells how good the fit is).
"Find a placement" runs the placement study (`Session.start_study_placement`) over a typed
region, shows its ranking here and its map on the table (`web.scene.placement`), and moves
the robot to a chosen candidate (`Session.apply_placement`, undoable)."""

from __future__ import annotations

import numpy as np
import viser

from assistant.session.events import Event, ProgressChanged, SceneChanged, StateChanged
from assistant.transforms import inv_T
from web.gui_value import set_value
from web.panels.base import Panel
from web.scene.placement import PlacementLayer
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
        with g.add_folder("Find a placement", expand_by_default=False):
            g.add_markdown("Where should the robot base stand? Give a region on the table "
                           "(world, mm) and a grid step; every candidate is checked (reach "
                           "with 5 deg to the joint limits, collisions, transfers planned).")
            self.st_corner0 = g.add_vector2("From X, Y (mm)", (-200.0, -200.0), step=1.0)
            self.st_corner1 = g.add_vector2("To X, Y (mm)", (200.0, 200.0), step=1.0)
            self.st_step = g.add_number("Step (mm)", 50.0, min=5.0, step=5.0)
            self.st_yaws = g.add_number("Yaw steps", 4, min=1, max=36, step=1)
            self.st_start = g.add_button("Start study")
            self.st_cancel = g.add_button("Cancel study", disabled=True)
            self.st_progress = g.add_progress_bar(0.0, visible=False, animated=True)
            self.st_status = g.add_markdown("")
            self.st_choice = g.add_dropdown("Candidate", ("-",))
            self.st_reason = g.add_markdown("")
            self.st_apply = g.add_button("Move the robot here", disabled=True)
            self.st_list = g.add_markdown("")
        self.markers = PlacementLayer(self.app)
        self.markers.on_pick = self._study_picked
        self.bind(self.st_start, lambda e: self._study_start())
        self.bind(self.st_cancel, lambda e: self.session.cancel())
        self.bind(self.st_apply, lambda e: self._study_apply())
        self.st_choice.on_update(lambda e: self._study_show_choice())
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
            set_value(self.pick, name)

    def _measure(self) -> None:
        p = self.session.measure_with_robot()
        set_value(self.measured_pt, tuple(round(float(v) * 1000.0, 3) for v in p))

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

    # ------------------------------------------------------------------ placement study
    def _study_start(self) -> None:
        from assistant.study import Region

        (x0, y0), (x1, y1) = self.st_corner0.value, self.st_corner1.value
        region = Region.from_mm(f"{min(x0, x1)},{min(y0, y1)},{max(x0, x1)},{max(y0, y1)}",
                                float(self.st_step.value), int(self.st_yaws.value))
        self.st_status.content = f"<small>{region.count()} candidates...</small>"
        self.session.start_study_placement(region)

    def _study_apply(self) -> None:
        index = self._study_index()
        if index is None:
            raise ValueError("choose a candidate first")
        self.session.apply_placement(index)

    def _study_index(self) -> int | None:
        v = str(self.st_choice.value)
        return int(v.split()[0].lstrip("#")) if v.startswith("#") else None

    def _study_picked(self, index: int) -> None:
        for opt in self.st_choice.options:
            if opt.startswith(f"#{index} "):
                set_value(self.st_choice, opt)

    def _study_show_choice(self) -> None:
        study, index = self.session.placement_study, self._study_index()
        rows = [] if study is None else [r for r in study.candidates
                                         if r.candidate.index == index]
        if not rows:
            self.st_reason.content, self.st_apply.disabled = "", True
            return
        assert study is not None  # rows come from it
        r = rows[0]
        text = f"{r.status}" + (f", rank {r.rank}" if r.rank else "")
        if r.cost is not None:
            text += f", {r.cost * 1000:.0f} mm of TCP path" if study.unit == "m" else \
                f", {r.cost:.2f} s"
        if r.plan is not None and r.plan.ok and r.plan.min_clearance is not None:
            text += f", clearance {r.plan.min_clearance * 1000:.0f} mm"
        if r.reason:
            text += f" - {r.reason}"
        self.st_reason.content = f"<small>{text}</small>"
        self.st_apply.disabled = r.status == "failed"

    def _study_refresh(self) -> None:
        study = self.session.placement_study
        if study is None:
            return
        ranked = study.ranked()
        opts = tuple(f"#{r.candidate.index} ({r.candidate.x * 1000:.0f}, "
                     f"{r.candidate.y * 1000:.0f}) {np.degrees(r.candidate.yaw):.0f} deg"
                     for r in ranked) or ("-",)
        if tuple(self.st_choice.options) != opts:
            self.st_choice.options = opts
            set_value(self.st_choice, opts[0])
        c = study.counts
        self.st_status.content = (f"<small>{c['candidates']} candidates: {c['screened_ok']} "
                                  f"passed the screen, {c['planned_ok']} of {c['planned']} "
                                  f"planned ({study.timings['total_s']:.0f} s).</small>")
        lines = ["| rank | x, y (mm) | yaw | result |", "|---|---|---|---|"]
        for r in ranked[:10]:
            what = f"{r.cost * 1000:.0f} mm" if r.cost is not None and study.unit == "m" \
                else (f"{r.cost:.2f} s" if r.cost is not None else r.reason[:60])
            lines.append(f"| {r.rank or '-'} | {r.candidate.x * 1000:.0f}, "
                         f"{r.candidate.y * 1000:.0f} | {np.degrees(r.candidate.yaw):.0f} | "
                         f"{what} |")
        self.st_list.content = "\n".join(lines)
        self._study_show_choice()

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
            set_value(self.xyz, xyz)
            set_value(self.abc, abc)
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
        self.markers.show(self.visible)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("objects", "frames", "all") or \
                isinstance(ev, StateChanged):
            self.refresh()
        if isinstance(ev, StateChanged):
            busy = ev.mode == "busy"
            self.st_start.disabled, self.st_cancel.disabled = busy, not busy
        if isinstance(ev, ProgressChanged) and ev.task == "placement study":
            self.st_progress.visible = not ev.done
            set_value(self.st_progress, max(0.0, min(100.0, 100.0 * ev.fraction)))
            if ev.done and ev.message == "cancelled":
                self.st_status.content = "<small>Study cancelled.</small>"
        if isinstance(ev, SceneChanged) and ev.what in ("study", "all"):
            self.markers.refresh()
            self._study_refresh()

