"""Step 3.2 - cameras and pointer colour: the live views with the detected blobs overlaid, the
colour-calibration ellipse drawn over the ball, and (synthetic camera) where the simulated
hand holds the ball."""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from assistant.session.events import Event, PointerUpdated
from web.panels.base import Panel
from web.units import fmt_mm, point_from_mm

#: Camera images are re-sent at most this often (each is a JPEG to every page).
IMAGE_PERIOD_S = 0.25
PREVIEW_WIDTH = 320


def _pair(value: Any) -> tuple[float, float]:
    """A two-number input's value (pixels) as the pair the calibration takes."""
    return (float(value[0]), float(value[1]))


def overlay(view: Any, ellipse: tuple[tuple[float, float], tuple[float, float], float] | None
            ) -> np.ndarray | None:
    """RGB preview of one camera with detections (green), the tracked blob (red), the
    prediction (blue cross) and the calibration ellipse (yellow)."""
    frame = getattr(view, "frame", None)
    if frame is None:
        return None
    img = frame.image.copy()
    for d in view.detections:
        c = tuple(int(round(v)) for v in d.center_px)
        cv2.circle(img, c, max(int(round(d.radius_px)), 2), (0, 200, 0), 2)
    if view.pointer is not None:
        c = tuple(int(round(v)) for v in view.pointer.center_px)
        cv2.circle(img, c, max(int(round(view.pointer.radius_px)) + 4, 4), (0, 0, 255), 2)
    if view.predicted_px is not None and np.all(np.isfinite(view.predicted_px)):
        c = tuple(int(round(v)) for v in view.predicted_px)
        cv2.drawMarker(img, c, (255, 80, 0), cv2.MARKER_CROSS, 14, 2)
    if ellipse is not None:
        (cx, cy), (ax, ay), ang = ellipse
        cv2.ellipse(img, (int(cx), int(cy)), (max(int(ax), 1), max(int(ay), 1)), ang, 0, 360,
                    (0, 220, 255), 2)
    h, w = img.shape[:2]
    scale = PREVIEW_WIDTH / w
    img = cv2.resize(img, (PREVIEW_WIDTH, int(round(h * scale))), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


class CamerasPanel(Panel):
    title = "Cameras & pointer"
    steps = ("place.cameras",)

    def build(self) -> None:
        g = self.gui
        g.add_markdown("Start the cameras, hold the coloured ball in view; green circles are "
                       "blobs, red is the tracked pointer.")
        self.start = g.add_button("Start cameras")
        self.stop = g.add_button("Stop cameras", disabled=True)
        self.status = g.add_markdown("")
        blank = np.zeros((240, PREVIEW_WIDTH, 3), np.uint8)
        self.images = [g.add_image(blank, label=f"Camera {i + 1}", format="jpeg",
                                   jpeg_quality=70) for i in range(2)]
        with g.add_folder("Colour calibration", expand_by_default=False):
            g.add_markdown("Draw the ellipse over the ball (full-image pixels), then calibrate.")
            self.cam = g.add_dropdown("Camera", ("1", "2"))
            self.centre = g.add_vector2("Centre (px)", (320.0, 240.0), step=1.0)
            self.axes = g.add_vector2("Half axes (px)", (12.0, 12.0), step=0.5)
            self.angle = g.add_number("Angle (deg)", 0.0, step=1.0)
            self.show_ellipse = g.add_checkbox("Show the ellipse", True)
            self.calibrate = g.add_button("Calibrate colour")
        with g.add_folder("Simulated hand (synthetic camera)", expand_by_default=False):
            self.hand = g.add_vector3("Ball at (mm)", (300.0, 0.0, 150.0), step=1.0)
            self.move_hand = g.add_button("Bring the ball there")
            self.hide_hand = g.add_button("Take the ball away")
        self._last_image = 0.0
        self.bind(self.start, lambda e: self._start())
        self.bind(self.stop, lambda e: self._stop())
        self.bind(self.calibrate, lambda e: self._calibrate(e.client))
        self.bind(self.move_hand, lambda e: self.session.pointer_move_to(
            point_from_mm(self.hand.value)))
        self.bind(self.hide_hand, lambda e: self.session.pointer_move_to(None))

    def _start(self) -> None:
        self.session.start_pointer()
        self.start.disabled, self.stop.disabled = True, False

    def _stop(self) -> None:
        self.session.stop_pointer()
        self.start.disabled, self.stop.disabled = False, True

    def _calibrate(self, client: Any) -> None:
        prof = self.session.calibrate_pointer_color(
            int(self.cam.value) - 1, _pair(self.centre.value), _pair(self.axes.value),
            float(self.angle.value))
        self.app.notifier.success(f"Pointer colour calibrated: {prof}", client=client)

    def _ellipse(self, index: int) -> Any:
        if not self.show_ellipse.value or int(self.cam.value) - 1 != index:
            return None
        return tuple(self.centre.value), tuple(self.axes.value), float(self.angle.value)

    def draw(self, state: Any) -> None:
        """Camera previews and the pointer line (UI thread, throttled)."""
        if state is None:
            return
        for i, view in enumerate(list(state.cameras.values())[:len(self.images)]):
            img = overlay(view, self._ellipse(i))
            if img is not None:
                self.images[i].image = img
        self._last_image = time.monotonic()

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, PointerUpdated):
            if ev.position is None:
                self.status.content = "Pointer: **not seen**"
            else:
                self.status.content = f"Pointer ({ev.mode}): {fmt_mm(ev.position)} mm " \
                                      f"+- {ev.std_m * 1000:.1f} mm"
            if self.visible and time.monotonic() - self._last_image >= IMAGE_PERIOD_S:
                self.draw(self.session.pointer_state())

    def refresh(self) -> None:
        self.status.content = "Pointer: cameras not started"
