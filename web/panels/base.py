"""What every step panel shares: a folder shown only in its steps, redraws on the UI thread."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import viser

from assistant.session.events import Event

if TYPE_CHECKING:
    from assistant.session import Session
    from web.app import App

#: Panels sit below the toolbar (order 0) and above the session box (order 1000).
PANEL_ORDER = 10.0


class Panel:
    """A folder of controls for one or more workflow steps (leaf ids)."""

    title: str = ""
    steps: tuple[str, ...] = ()
    order: float = PANEL_ORDER
    expand: bool = True

    def __init__(self, app: App):
        self.app = app
        self.gui: viser.GuiApi = app.server.gui
        self.folder = self.gui.add_folder(self.title, order=self.order, visible=False,
                                          expand_by_default=self.expand)
        with self.folder:
            self.build()

    @property
    def session(self) -> Session:
        return self.app.session

    @property
    def visible(self) -> bool:
        return bool(self.folder.visible)

    def show_for(self, state: str) -> None:
        visible = state in self.steps
        if self.folder.visible != visible:
            self.folder.visible = visible

    def bind(self, handle: Any, fn: Any, *, motion: bool = False) -> None:
        """A control of this panel: acts only while the panel is on screen (`motion`: it
        starts robot motion - behind the gate only the holder of motion authority may)."""
        self.app.actions.bind(handle, fn, when=lambda: self.visible, motion=motion)

    # -- to override -----------------------------------------------------------------------
    def build(self) -> None:
        """Create the controls (inside the panel's folder)."""

    def refresh(self) -> None:
        """Redraw everything from the session's queries (UI thread)."""

    def on_event(self, ev: Event) -> None:
        """React to one session event (UI thread); default: nothing."""
