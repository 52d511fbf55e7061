"""A refused target and the arm's reach: a red ball where the operator asked the tool to go
(with the tool's direction when known), labelled with how far beyond the reach it lies, a red
line across the gap, and the reach itself as a faint sphere with three blue great circles
around the shoulder. Shown after an out-of-reach teach; gone at the operator's next action."""

from __future__ import annotations

import contextlib
import threading
from dataclasses import dataclass

import numpy as np
import viser

from web.scene.base import Layer

Array = np.ndarray

RED = (220, 30, 30)
BLUE = (70, 130, 230)
#: Radius (m) of the ball at the refused target: visible at the scene's usual zoom.
TARGET_RADIUS = 0.015
#: Length (m) of the red stroke along the tool axis at the target.
AXIS_LENGTH = 0.06
#: The share of the page's width the control panel covers (on the right).
PANEL_SHARE = 0.28


@dataclass(frozen=True)
class RefusedTarget:
    """What the teach panel drew: the location's name, the target (world, m), the tool axis
    (world, unit; None when the tool direction was not the operator's), the reach sphere's
    centre (world, m) and radius (m) and the distance beyond it (m; <= 0 inside)."""

    name: str
    position: Array
    tool_axis: Array | None
    centre: Array
    radius: float
    beyond: float

    @property
    def label(self) -> str:
        if self.beyond > 0:
            return f"{self.name}: out of reach, {self.beyond * 1000:.0f} mm beyond"
        return f"{self.name}: not reachable in this orientation"


def _circle(centre: Array, radius: float, u: Array, v: Array, n: int = 96) -> Array:
    """Segments (n, 2, 3) of the circle centre + radius (cos t u + sin t v)."""
    t = np.linspace(0.0, 2.0 * np.pi, n + 1)
    pts = centre + radius * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))
    return np.stack([pts[:-1], pts[1:]], axis=1)


class ReachLayer(Layer):
    root = "/reach"

    def __init__(self, app):
        super().__init__(app)
        self.shown: RefusedTarget | None = None
        self._lock = threading.Lock()  # teach callbacks and session events both clear it

    def show(self, target: RefusedTarget) -> None:
        with self._lock:
            self.clear()
            self.shown = target
            self._draw(target)

    def hide(self) -> None:
        with self._lock:
            if self.shown is not None or self._nodes:
                self.clear()
            self.shown = None

    def frame(self, client: viser.ClientHandle) -> None:
        """Turn that page's camera, from the side it looks from, onto the target and the
        reach together: a target off screen (or behind the panel) is no help."""
        t = self.shown
        if t is None:
            return
        lo = np.minimum(t.centre - t.radius, t.position)
        hi = np.maximum(t.centre + t.radius, t.position)
        mid, half = (lo + hi) / 2.0, float(np.linalg.norm(hi - lo)) / 2.0
        with contextlib.suppress(AssertionError, ValueError):  # no camera state from it yet
            cam = client.camera
            back = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
            n = float(np.linalg.norm(back))
            back = back / n if n > 1e-9 else np.array([0.6, -0.6, 0.5])
            fov = float(cam.fov)
            dist = 1.1 * half / np.sin(fov / 2.0)
            # The control panel covers about the right quarter of the page: look a little to
            # the right of the middle, so the drawing sits in the free part on the left.
            right = np.cross(-back, [0.0, 0.0, 1.0])
            rn = float(np.linalg.norm(right))
            width = 2.0 * dist * np.tan(fov / 2.0) * float(getattr(cam, "aspect", 1.5))
            aim = mid + (right / rn * PANEL_SHARE / 2.0 * width if rn > 1e-9 else 0.0)
            with client.atomic():
                cam.position = aim + back * dist  # moves look_at along; set it after
                cam.look_at = aim

    def _draw(self, t: RefusedTarget) -> None:
        sc, r = self.scene, self.root
        self._nodes["sphere"] = sc.add_icosphere(
            f"{r}/sphere", radius=t.radius, subdivisions=4, color=BLUE, opacity=0.12,
            position=tuple(t.centre), cast_shadow=False, receive_shadow=False)
        ex, ey, ez = np.eye(3)
        rings = np.concatenate([_circle(t.centre, t.radius, a, b)
                                for a, b in ((ex, ey), (ex, ez), (ey, ez))])
        self._nodes["rings"] = sc.add_line_segments(
            f"{r}/rings", rings.astype(np.float32), BLUE, thickness=1.5,
            thickness_units="screen")
        self._nodes["reach_label"] = sc.add_label(
            f"{r}/reach_label", f"arm's reach {t.radius * 1000:.0f} mm",
            position=tuple(t.centre + [0.0, 0.0, t.radius + 0.02]), font_screen_scale=0.8,
            anchor="bottom-center")
        self._nodes["target"] = sc.add_icosphere(
            f"{r}/target", radius=TARGET_RADIUS, color=RED, position=tuple(t.position),
            cast_shadow=False, receive_shadow=False)
        segs = []
        if t.tool_axis is not None:
            segs.append([t.position - AXIS_LENGTH * t.tool_axis, t.position])
        d = t.position - t.centre
        dist = float(np.linalg.norm(d))
        if t.beyond > 0 and dist > 1e-9:  # the gap: from the reach's edge to the target
            segs.append([t.centre + d / dist * t.radius, t.position])
        if segs:
            self._nodes["lines"] = sc.add_line_segments(
                f"{r}/lines", np.array(segs, dtype=np.float32), RED, thickness=4.0,
                thickness_units="screen")
        self._nodes["label"] = sc.add_label(
            f"{r}/label", t.label, position=tuple(t.position + [0.0, 0.0, 0.03]),
            font_screen_scale=1.0, anchor="bottom-center")
