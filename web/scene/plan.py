"""The planned path, each motion coloured by kind so lines and arcs are told apart."""

from __future__ import annotations

from assistant.session.events import Event, PlanReady, SceneChanged, StateChanged
from web.scene.base import Layer
from web.scene.paths import segments

#: Motion kind -> colour (the plan panel shows the same legend).
KIND_COLORS: dict[str, tuple[int, int, int]] = {
    "joint": (150, 150, 150),  # PTP / MOV: the TCP curve is incidental
    "linear": (20, 110, 230),  # MVS / LIN
    "circular": (235, 120, 0),  # MVR / CIRC
    "spline": (160, 60, 200),  # Bezier / SPLINE
}
KIND_WIDTH = {"joint": 2.0, "linear": 5.0, "circular": 5.0, "spline": 5.0}


class PlanLayer(Layer):
    root = "/plan"

    def __init__(self, app) -> None:  # noqa: ANN001
        super().__init__(app)
        self.motions_drawn = 0
        self._drawn_for: int | None = None

    def refresh(self) -> None:
        traj = self.session.trajectory
        if traj is not None and id(traj) == self._drawn_for:
            return
        self.clear()
        self._drawn_for = None if traj is None else id(traj)
        polylines = self.session.plan_polylines()
        self.motions_drawn = 0
        for i, (kind, pts) in enumerate(polylines):
            if len(pts) < 2:
                continue
            self._nodes[str(i)] = self.scene.add_line_segments(
                f"{self.root}/m{i:03d}_{kind}", segments(pts), KIND_COLORS.get(kind, (0, 0, 0)),
                thickness=KIND_WIDTH.get(kind, 3.0), thickness_units="screen")
            self.motions_drawn += 1

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, (PlanReady, StateChanged)) or \
                isinstance(ev, SceneChanged) and ev.what in ("all", "mission", "locations",
                                                              "objects", "plan"):
            self.refresh()
