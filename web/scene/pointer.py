"""The live marker pointer: the ball where the cameras see it and a sphere of its uncertainty
(2 sigma); hidden while the pointer is lost or not measured. While it coasts (a prediction,
at most 0.2 s) or has a new track's first fix only a grey sphere is shown: never the red
ball, which means "measured"."""

from __future__ import annotations

from assistant.session.events import Event, PointerUpdated
from web.scene.base import Layer

BALL_RADIUS = 0.0125  # the thesis' 2.5 cm ball


class PointerLayer(Layer):
    root = "/pointer"

    def refresh(self) -> None:
        if self._nodes:
            return
        self._nodes["ball"] = self.scene.add_icosphere(
            f"{self.root}/ball", radius=BALL_RADIUS, color=(220, 20, 20), visible=False,
            cast_shadow=False, receive_shadow=False)
        self._nodes["sigma"] = self.scene.add_icosphere(
            f"{self.root}/sigma", radius=1.0, color=(255, 120, 120), opacity=0.25,
            visible=False, cast_shadow=False, receive_shadow=False, scale=0.01)

    def on_event(self, ev: Event) -> None:
        if not isinstance(ev, PointerUpdated):
            return
        self.refresh()
        ball, sigma = self._nodes["ball"], self._nodes["sigma"]
        if ev.position is None:
            if ball.visible:
                ball.visible = sigma.visible = False
            return
        coasting = ev.mode not in ("stereo", "mono", "single view")  # a prediction or unconfirmed
        with self.app.server.atomic():
            ball.position = sigma.position = ev.position
            sigma.scale = max(2.0 * ev.std_m, 0.002)
            sigma.color = (150, 150, 150) if coasting else (255, 120, 120)
            ball.visible = not coasting
            sigma.visible = True
