"""The operator's Collision! button for controller links: stop now, report the posture.

The simulated robot has its own `indicate_collision`; the MELFA and KUKA links share this
mixin. While a move runs, the press stops it and the move ends with COLLISION_INDICATED
(source "operator") instead of STOPPED; when idle the event is emitted at once with the last
known joints.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from assistant.links.link import LinkEvent, LinkEventKind


class OperatorButton:
    """Mixin for links with `_moving` (a Lock held while moving), `_last_q`, `stop`, `_emit`."""

    _moving: threading.Lock
    _last_q: np.ndarray
    _pressed: str | None = None

    def indicate_collision(self, message: str = "operator pressed Collision!") -> None:
        if self._moving.locked():
            self._pressed = message
            self.stop()  # type: ignore[attr-defined]  (the link's)
            return
        ev = LinkEvent(LinkEventKind.COLLISION_INDICATED, self._last_q.copy(),
                       time.monotonic(), message, None, {"source": "operator"})
        self._emit(ev)  # type: ignore[attr-defined]  (RobotLink's)

    def _stopped_as(self, details: dict | None = None) -> tuple[LinkEventKind, str, dict]:
        """What a requested stop is reported as: STOPPED, or the operator's indication."""
        details = dict(details or {})
        pressed, self._pressed = self._pressed, None
        if pressed is not None:
            details["source"] = "operator"
            return LinkEventKind.COLLISION_INDICATED, pressed, details
        return LinkEventKind.STOPPED, "stopped on request", details
