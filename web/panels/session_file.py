"""Save and load the whole session (a folder: JSON + CAD files), at any step. Loading replaces
the session every open page shows; autosave keeps writing to the loaded folder."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from assistant.session import Session
from assistant.session.events import Event, StateChanged
from web.panels.base import Panel
from workflow.states import leaves

DEFAULT_FOLDER = "~/cellteach-session"


class SessionPanel(Panel):
    title = "Session file"
    order = 1000.0
    expand = False

    def __init__(self, app: Any):
        self.steps = tuple(leaves())
        super().__init__(app)

    def build(self) -> None:
        g = self.gui
        self.where = g.add_markdown("")
        self.folder_text = g.add_text("Folder", DEFAULT_FOLDER,
                                      hint="A folder on the computer running cellteach")
        self.save = g.add_button("Save session")
        self.load = g.add_button("Load session")
        self.bind(self.save, lambda e: self._save(e.client))
        self.bind(self.load, lambda e: self._load(e.client))

    def _path(self) -> Path:
        text = self.folder_text.value.strip()
        if not text:
            raise ValueError("type the folder to save to or load from")
        return Path(text).expanduser()

    def _save(self, client: Any) -> None:
        path = self.session.save(self._path())
        self.app.notifier.success(f"Session saved to {path}", client=client)
        self.refresh()

    def _load(self, client: Any) -> None:
        path = self._path()
        if self.session.machine.mode.value != "idle":
            raise ValueError("wait until the robot stands still and nothing is running")
        new = Session.load(path)
        self.app.replace_session(new)
        self.app.notifier.success(f"Session loaded from {path}", client=client)

    def refresh(self) -> None:
        s = self.session
        if s.folder is not None:
            auto = "autosaved after every change" if s.autosave_enabled else "not autosaved"
            self.where.content = f"<small>This session lives in {s.folder} ({auto}).</small>"
            if self.folder_text.value == DEFAULT_FOLDER:
                self.folder_text.value = str(s.folder)
        else:
            self.where.content = "<small>Not saved yet.</small>"
        self.load.disabled = self.save.disabled = s.machine.mode.value != "idle"

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, StateChanged):
            self.refresh()
