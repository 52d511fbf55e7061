"""What every step panel shares: a folder shown only in its steps, redraws on the UI thread.

Every `refresh` reads the session settled (between actions, under its lock: what it shows is
saved, `Session.settled`), also when a page callback calls it directly."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

import viser

from assistant.session.events import Event

if TYPE_CHECKING:
    from assistant.session import Session
    from web.app import App

#: Panels sit below the toolbar (order 0) and above the session box (order 1000).
PANEL_ORDER = 10.0


class StepPanel(Protocol):
    """What the app asks of each panel: a `Panel`, or the session-file box (per page)."""

    @property
    def title(self) -> str: ...
    @property
    def steps(self) -> tuple[str, ...]: ...

    def show_for(self, state: str) -> None: ...
    def refresh(self) -> None: ...
    def on_event(self, ev: Event) -> None: ...
    def on_enter(self) -> None: ...


class Panel:
    """A folder of controls for one or more workflow steps (leaf ids)."""

    title: str = ""
    steps: tuple[str, ...] = ()
    order: float = PANEL_ORDER
    expand: bool = True

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if "refresh" in cls.__dict__:
            cls.refresh = settled_view(cls.__dict__["refresh"])  # type: ignore[method-assign]

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

    def on_enter(self) -> None:
        """The workflow has just moved to one of this panel's steps (UI thread); default:
        nothing. A step whose work is obvious starts it here, saving the operator a click."""


def settled_view(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Run a redraw between the session's actions (see the module docstring)."""

    @functools.wraps(fn)
    def redraw(self: Any, *args: Any, **kw: Any) -> Any:
        with self.app.session.settled():
            return fn(self, *args, **kw)

    return redraw


def busy_reason(mode: str) -> str:
    """Why a control that needs the robot and the assistant idle is greyed out ("" if idle)."""
    return {"busy": "Wait: the assistant is working (Cancel in the toolbar stops it)",
            "moving": "Wait: the robot is moving (Stop halts it)",
            "error": "Acknowledge the error in the toolbar first"}.get(mode, "")


def gate(handle: Any, why: str, hint: str = "") -> None:
    """Enable a control, or grey it out with `why` as its tooltip: a greyed control always
    says what to do first. `hint`: the tooltip while it is enabled."""
    disabled, tip = bool(why), (why or hint)
    if handle.disabled != disabled:
        handle.disabled = disabled
    if getattr(handle, "hint", None) != (tip or None):
        handle.hint = tip or None


def why_greyed(reasons: dict[str, str]) -> str:
    """One small line under a panel's buttons: what each greyed one waits for (viser shows no
    tooltip on a button, and none on a disabled control anywhere). Reasons shared by several
    buttons are said once."""
    by_reason: dict[str, list[str]] = {}
    for label, why in reasons.items():
        if why:
            by_reason.setdefault(why, []).append(label)
    if not by_reason:
        return ""
    parts = [f"{' / '.join(labels)}: {why[:1].lower() + why[1:]}"
             for why, labels in by_reason.items()]
    return "<small>Greyed out - " + "; ".join(parts) + ".</small>"
