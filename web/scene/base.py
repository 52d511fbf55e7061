"""What every scene layer shares: its own subtree of scene nodes and a redraw on events."""

from __future__ import annotations

import hashlib
import re
from typing import TYPE_CHECKING, Any

import viser

from assistant.session.events import Event

if TYPE_CHECKING:
    from assistant.session import Session
    from web.app import App


def node_key(name: str) -> str:
    """A scene-tree name for an operator-chosen name (which may hold '/', spaces, ...)."""
    safe = re.sub(r"[^A-Za-z0-9_-]+", "_", name)[:40] or "x"
    if safe == name:
        return safe
    return f"{safe}-{hashlib.sha1(name.encode()).hexdigest()[:6]}"


class Layer:
    root: str = "/"

    def __init__(self, app: App):
        self.app = app
        self.scene: viser.SceneApi = app.server.scene
        self._nodes: dict[str, Any] = {}

    @property
    def session(self) -> Session:
        return self.app.session

    def clear(self) -> None:
        for h in self._nodes.values():
            h.remove()
        self._nodes.clear()

    def refresh(self) -> None:
        """Redraw the layer from the session (UI thread)."""

    def on_event(self, ev: Event) -> None:
        """React to an event (UI thread)."""
