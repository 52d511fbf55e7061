"""Save and load the whole session (a folder: JSON + CAD files), at any step. Loading replaces
the session every open page shows; autosave keeps writing to the loaded folder.

The box is each operator page's own (`web.pages`): the folder's path is where the files are on
the cell computer, which a viewer's page has no need of, and a folder one operator types is
not typed into every other page. What loading changed or ignored (`Session.load_notes`) is
told to the page that loaded."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import viser

from assistant.session import Session
from assistant.session.events import Event, StateChanged
from web.gui_value import set_value
from web.panels.base import settled_view
from workflow.states import leaves

DEFAULT_FOLDER = "~/cellteach-session"
ORDER = 1000.0


@dataclass
class SessionBox:
    """One operator page's "Session file" folder."""

    folder: viser.GuiFolderHandle
    where: viser.GuiMarkdownHandle
    folder_text: viser.GuiTextHandle
    save: viser.GuiButtonHandle
    load: viser.GuiButtonHandle


class SessionPanel:
    title = "Session file"
    order = ORDER

    def __init__(self, app: Any):
        self.app = app
        self.steps = tuple(leaves())
        self.boxes = app.pages.add(self._box, operators_only=True)

    @property
    def session(self) -> Session:
        return self.app.session

    @property
    def visible(self) -> bool:
        return True  # in every step

    def _box(self, client: viser.ClientHandle) -> SessionBox:
        g = client.gui
        with g.add_folder(self.title, order=self.order, expand_by_default=False) as folder:
            box = SessionBox(
                folder, g.add_markdown(""),
                g.add_text("Folder", DEFAULT_FOLDER,
                           hint="A folder on the computer running cellteach"),
                g.add_button("Save session"), g.add_button("Load session"))
        self.app.actions.bind(box.save, lambda e: self._save(e.client))
        self.app.actions.bind(box.load, lambda e: self._load(e.client))
        self._show(box)
        return box

    def _path(self, client: Any) -> Path:
        box = self.boxes.of(client)
        text = box.folder_text.value.strip() if box is not None else ""
        if not text:
            raise ValueError("type the folder to save to or load from")
        return Path(text).expanduser()

    def _save(self, client: Any) -> None:
        path = self.session.save(self._path(client))
        self.app.notifier.success(f"Session saved to {path}", client=client)
        self.refresh()

    def _load(self, client: Any) -> None:
        path = self._path(client)
        if self.session.machine.mode.value != "idle":
            raise ValueError("wait until the robot stands still and nothing is running")
        new = Session.load(path)
        self.app.replace_session(new)
        self.app.notifier.success(f"Session loaded from {path}", client=client)
        for note in new.load_notes:
            self.app.notifier.notice(note, client=client)

    # -- as a panel ------------------------------------------------------------------------
    def show_for(self, state: str) -> None:
        """In every step (each page's box is its own)."""

    def on_enter(self) -> None:
        """Nothing starts on entering a step."""

    @settled_view
    def refresh(self) -> None:
        for box in self.boxes.all():
            self._show(box)

    def _show(self, box: SessionBox) -> None:
        s = self.session
        try:
            if s.folder is not None:
                auto = "autosaved after every change" if s.autosave_enabled else \
                    "not autosaved"
                box.where.content = f"<small>This session lives in {s.folder} ({auto}).</small>"
                if box.folder_text.value == DEFAULT_FOLDER:
                    set_value(box.folder_text, str(s.folder))
            else:
                box.where.content = "<small>Not saved yet.</small>"
            busy = s.machine.mode.value != "idle"
            if box.load.disabled != busy:
                box.load.disabled = box.save.disabled = busy
        except Exception:  # noqa: BLE001 - a page closing while it is drawn
            pass

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, StateChanged):
            self.refresh()
