"""The last placement study on the table: a marker per candidate position coloured by its
best candidate (green best .. red worst, blue screened only, grey failed - the colours of the
study's PNG map), a tick per yaw, the best one labelled. Clicking a marker selects it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from assistant.session.events import Event, SceneChanged
from web.scene.base import Layer

#: Height of the markers above the subject's own plane (m): visible on the table top.
LIFT = 0.004


def _rgb(bgr: tuple[int, int, int]) -> tuple[int, int, int]:
    return (bgr[2], bgr[1], bgr[0])


class PlacementLayer(Layer):
    root = "/placement_study"

    def __init__(self, app):
        super().__init__(app)
        #: Called with a candidate index when its marker is clicked.
        self.on_pick: Callable[[int], None] | None = None
        self.shown = False

    def show(self, on: bool) -> None:
        if on != self.shown:
            self.shown = on
            self.refresh()

    def refresh(self) -> None:
        from assistant.study.picture import colours

        self.clear()
        study = self.session.placement_study
        if not self.shown or study is None or study.problem is None:
            return
        col = colours(study)
        z = float(study.problem.pose_at(study.candidates[0].candidate)[2, 3]) + LIFT \
            if study.candidates else 0.0
        order = {r.candidate.index: k for k, r in enumerate(study.ranked())}
        by_pos: dict[tuple[float, float], list] = {}
        for r in study.candidates:
            by_pos.setdefault((round(r.candidate.x, 6), round(r.candidate.y, 6)), []).append(r)
        tick = max(0.01, 0.35 * study.region.step)
        segs, seg_col = [], []
        for k, ((x, y), rs) in enumerate(by_pos.items()):
            best = min(rs, key=lambda r: (r.status == "failed", order[r.candidate.index]))
            h = self.scene.add_icosphere(
                f"{self.root}/p{k}", radius=max(0.004, 0.12 * study.region.step),
                color=_rgb(col[best.candidate.index]), position=(x, y, z),
                cast_shadow=False, receive_shadow=False)
            h.on_click(self._picking(best.candidate.index))
            self._nodes[f"p{k}"] = h
            for r in rs:
                yaw = r.candidate.yaw
                segs.append([(x, y, z), (x + tick * np.cos(yaw), y + tick * np.sin(yaw), z)])
                seg_col.append([_rgb(col[r.candidate.index])] * 2)
        if segs:
            self._nodes["ticks"] = self.scene.add_line_segments(
                f"{self.root}/ticks", np.array(segs, dtype=np.float32),
                np.array(seg_col, dtype=np.uint8), thickness=3.0, thickness_units="screen")
        top = study.best()
        if top is not None:
            self._nodes["best"] = self.scene.add_label(
                f"{self.root}/best", f"best #{top.candidate.index}",
                position=(top.candidate.x, top.candidate.y, z + 0.03),
                font_screen_scale=0.8, anchor="bottom-center")

    def _picking(self, index: int) -> Callable[[Any], None]:
        """The click callback of candidate `index`'s marker."""
        return lambda ev: self._picked(index)

    def _picked(self, index: int) -> None:
        if self.on_pick is not None:
            self.on_pick(index)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("study", "all"):
            self.refresh()
