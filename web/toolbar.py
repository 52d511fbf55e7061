"""The toolbar: where the operator is, Previous / Next / Exit, one button per allowed jump,
the mode buttons (Cancel, Collision!, Stop, Acknowledge, Reconnect), progress, undo/redo.

Buttons come from `session.transitions()`: a transition that is not allowed now is shown
greyed out with its reason, so the operator always sees what to do first (SPEC §1).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

import viser

from assistant.session.commands import PageCommand
from assistant.session.events import (
    CollisionRecorded,
    ErrorRaised,
    Event,
    PlanReady,
    ProgramReady,
    ProgressChanged,
    RobotHalted,
    SceneChanged,
    StateChanged,
)
from assistant.session.run_state import RunPhase, RunState
from web.gui_value import set_value
from web.panels.base import busy_reason, settled_view
from web.wording import progress_words
from workflow.states import NUMBER, STATES, leaves

if TYPE_CHECKING:
    from web.app import App

#: Colours of the mode buttons; Collision! is the big red one.
MODE_COLORS: dict[str, Literal["red", "orange", "yellow", "blue", "teal"]] = {
    "collision": "red", "stop": "orange", "cancel": "yellow", "acknowledge": "blue",
    "reconnect": "teal"}
MODE_ICONS: dict[str, Any] = {"collision": viser.Icon.ALERT_OCTAGON,
                              "stop": viser.Icon.PLAYER_STOP, "cancel": viser.Icon.X}
NAV = ("previous", "next", "exit")
MAIN_STEPS = [s for s in STATES if "." not in s]


def step_heading(state: str, mode: str, run: RunState) -> str:
    """The step, its help, and the one sentence of the run state while something runs."""
    n_main = len(MAIN_STEPS)
    spec = STATES[state]
    parent = STATES[state.split(".")[0]]
    where = spec.title if parent is spec else f"{parent.title} - {spec.title}"
    head = f"#### Step {NUMBER[state]} of {n_main}: {where}"
    if spec.help:
        head += f"\n\n{spec.help}"
    if mode == "error":
        head += "\n\n**Error:** acknowledge it or reconnect the robot."
    elif run.phase in (RunPhase.WORKING, RunPhase.MOVING, RunPhase.HALTED):
        head += f"\n\n{run.sentence}"
    return head


class Toolbar:
    def __init__(self, app: App):
        self.app = app
        gui = app.server.gui
        self._buttons: dict[str, viser.GuiButtonHandle] = {}
        self.folder = gui.add_folder("Workflow", order=0)
        with self.folder:
            self.heading = gui.add_markdown("")
            self.progress = gui.add_progress_bar(0.0, visible=False, animated=True)
            self.progress_text = gui.add_markdown("", visible=False)
            self.modes = gui.add_folder(None)
            self.prev = gui.add_button("Previous", icon=viser.Icon.ARROW_LEFT)
            self.next = gui.add_button("Next", icon=viser.Icon.ARROW_RIGHT, color="green")
            self.jumps = gui.add_folder(None)
            self.why = gui.add_markdown("")
            with gui.add_folder("More", expand_by_default=False):
                self.undo = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP)
                self.redo = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP)
                self.step_choice = gui.add_dropdown(
                    "Go to step", tuple(f"{NUMBER[s]} {STATES[s].title}" for s in leaves()))
                self.goto = gui.add_button("Go to that step")
                self.exit = gui.add_button("Exit", icon=viser.Icon.LOGOUT)
            self.status = gui.add_markdown("")
        #: Each page's own status line, under the shared one: what was said to it alone.
        self.my_status = app.pages.add(self._my_status)
        # Keyboard: Space is the Collision! button, Escape stops / cancels.
        self.key_collision = gui.add_command(
            "Collision!", description="The robot would hit something: stop and remember it",
            hotkey="space", disabled=True)
        self.key_stop = gui.add_command("Stop / Cancel", hotkey="escape", disabled=True)
        # Ctrl+K lists these too: moving through the steps and undoing without the mouse.
        self.key_next = gui.add_command("Next step", description="Go to the next step",
                                        hotkey="arrowright", modifier="alt",
                                        icon=viser.Icon.ARROW_RIGHT)
        self.key_prev = gui.add_command("Previous step", description="Go back one step",
                                        hotkey="arrowleft", modifier="alt",
                                        icon=viser.Icon.ARROW_LEFT)
        self.key_undo = gui.add_command("Undo", description="Take back the last change", hotkey="Z",
                                        modifier="cmd/ctrl", icon=viser.Icon.ARROW_BACK_UP)
        self.key_redo = gui.add_command("Redo", description="Do again what was undone", hotkey="Y",
                                        modifier="cmd/ctrl", icon=viser.Icon.ARROW_FORWARD_UP)

        acts = app.actions
        acts.bind(self.prev, lambda e: self.app.session.fire(PageCommand.PREVIOUS))
        acts.bind(self.next, lambda e: self.app.session.fire(PageCommand.NEXT))
        acts.bind(self.exit, lambda e: self._exit(e.client))
        acts.bind(self.undo, lambda e: self._undo(e.client, redo=False))
        acts.bind(self.redo, lambda e: self._undo(e.client, redo=True))
        acts.bind(self.goto, lambda e: self._goto())
        acts.bind(self.key_collision, lambda e: self.app.session.fire(PageCommand.COLLISION))
        acts.bind(self.key_stop, lambda e: self._stop_or_cancel())
        acts.bind(self.key_next, lambda e: self.app.session.fire(PageCommand.NEXT))
        acts.bind(self.key_prev, lambda e: self.app.session.fire(PageCommand.PREVIOUS))
        acts.bind(self.key_undo, lambda e: self._undo(e.client, redo=False))
        acts.bind(self.key_redo, lambda e: self._undo(e.client, redo=True))
        app.notifier.on_message = self._on_message

    # ------------------------------------------------------------------ actions
    def _fire(self, event: str) -> None:
        """A transition the machine listed (a mode's command, or a jump by its name)."""
        self.app.session.fire(_command(event))

    def _firing(self, event: str) -> Callable[[Any], None]:
        """A button's callback that fires `event`."""
        return lambda e: self._fire(event)

    def _goto(self) -> None:
        choice = self.step_choice.value.split(" ", 1)[0]
        step = next(s for s in leaves() if NUMBER[s] == choice)
        self.app.session.goto(step)

    def _stop_or_cancel(self) -> None:
        s = self.app.session
        s.fire(PageCommand.STOP if s.machine.mode.value == "moving" else PageCommand.CANCEL)

    def _undo(self, client: viser.ClientHandle | None, *, redo: bool) -> None:
        s = self.app.session
        label = s.redo() if redo else s.undo()
        self.app.notifier.notice(f"{'Redone' if redo else 'Undone'}: {label}", client=client)

    def _exit(self, client: viser.ClientHandle | None) -> None:
        s = self.app.session
        s.fire(PageCommand.EXIT)
        if s.folder is not None:
            s.save(s.folder)
            self.app.notifier.success(f"Session saved to {s.folder}. You can close this page; "
                                      "loading that folder later continues where you left.",
                                      client=client)
        else:
            self.app.notifier.notice("This session has no folder yet: save it under More > "
                                     "Session before closing the page.", client=client)

    def _my_status(self, client: viser.ClientHandle) -> viser.GuiMarkdownHandle:
        with self.folder:
            return client.gui.add_markdown("", order=self.status.order + 0.5)

    def _on_message(self, kind: str, text: str, client: viser.ClientHandle | None) -> None:
        """A message into the shared status line (client None) or that page's own."""
        if kind == "clear":
            if client is not None:
                mine = self.my_status.of(client)
                if mine is not None:
                    _set(mine, content="")
                return
            self.status.content = ""
            for mine in self.my_status.all():
                _set(mine, content="")
            return
        icon = {"error": "**Error:**", "notice": "Note:", "ok": "Done:"}.get(kind, "")
        line = f"<small>{icon} {_md_escape(text)}</small>"
        target = self.status if client is None else self.my_status.of(client)
        if target is not None:
            with contextlib.suppress(Exception):  # the page is closing
                target.content = line

    def saved(self, ok: bool, reason: str) -> None:
        """Autosave failed (the heading says "Not saved" until it works again) or works."""
        self.refresh()

    # ------------------------------------------------------------------ redraw
    def on_event(self, ev: Event) -> None:
        if isinstance(ev, RobotHalted):
            self.refresh()
        if isinstance(ev, ProgressChanged):
            self._progress(ev)
        elif isinstance(ev, (StateChanged, SceneChanged, PlanReady, ProgramReady,
                             CollisionRecorded, ErrorRaised)):
            self.refresh()

    def _progress(self, ev: ProgressChanged) -> None:
        if ev.done:
            self.progress.visible = False
            self.progress_text.visible = False
            return
        set_value(self.progress, max(0.0, min(100.0, 100.0 * ev.fraction)))
        words = progress_words(ev.message) or "working"
        self.progress_text.content = f"<small>{_md_escape(ev.task)}: " \
                                     f"{_md_escape(words)}</small>"
        self.progress.visible = True
        self.progress_text.visible = True

    @settled_view
    def refresh(self) -> None:
        s = self.app.session
        m = s.machine
        mode = m.mode.value
        run = s.run_state()
        # The keys first: a page that reads "the robot is moving" already has Space armed.
        moving = mode == "moving"
        if self.key_collision.disabled != (not moving):
            self.key_collision.disabled = not moving
        stop_ok = mode in ("moving", "busy")
        if self.key_stop.disabled != (not stop_ok):
            self.key_stop.disabled = not stop_ok
        heading = step_heading(m.state, mode, run)
        if s.save_error:
            heading += f"\n\n**Not saved:** {_md_escape(s.save_error)} - the last change is " \
                "only in memory; every change tries again."
        self.heading.content = heading
        transitions = s.transitions()
        by_event = {t.event: t for t in transitions}
        for name, btn in (("previous", self.prev), ("next", self.next), ("exit", self.exit)):
            t = by_event.get(name)
            _set(btn, disabled=t is None or not t.allowed,
                 hint=(t.reason or _target_hint(t.target)) if t is not None else "")
        nxt = by_event.get("next")
        # while a run has the robot, the heading's sentence says what to do: no second one
        self.why.content = "" if nxt is None or nxt.allowed or nxt.target is None or \
            run.robot_in_run else \
            f"<small>Next is not available yet: {_md_escape(nxt.reason)}</small>"
        extra = [t for t in transitions if t.event not in NAV]
        self._sync_extra(extra)
        idle = mode == "idle"
        wait = busy_reason(mode)
        h = s.history
        for btn, cmd, can, what, word in (
                (self.undo, self.key_undo, h.can_undo, h.undo_label(), "Undo"),
                (self.redo, self.key_redo, h.can_redo, h.redo_label(), "Redo")):
            why = wait or ("" if can else f"Nothing to {word.lower()}")
            label = f"{word}: {_short(what)}" if can else word
            _set(btn, label=label, disabled=bool(why), hint=why or f"{word} {what}")
            _set(cmd, label=label, disabled=bool(why))
        for cmd, event in ((self.key_next, "next"), (self.key_prev, "previous")):
            t = by_event.get(event)
            _set(cmd, disabled=t is None or not t.allowed)
        _set(self.goto, disabled=not idle, hint=wait or "Jump to the step chosen above")
        if idle:
            self.progress.visible = False
            self.progress_text.visible = False

    def _sync_extra(self, extra: list) -> None:
        """Jump and mode buttons: create the new ones, update or remove the rest."""
        wanted = {t.event: t for t in extra}
        for ev in list(self._buttons):
            if ev not in wanted:
                self._buttons.pop(ev).remove()
        for i, t in enumerate(extra):
            btn = self._buttons.get(t.event)
            if btn is None:
                is_mode = t.event in MODE_COLORS
                with self.modes if is_mode else self.jumps:
                    btn = self.app.server.gui.add_button(
                        t.label, color=MODE_COLORS.get(t.event), icon=MODE_ICONS.get(t.event),
                        order=float(i))
                self.app.actions.bind(btn, self._firing(t.event))
                self._buttons[t.event] = btn
            _set(btn, disabled=not t.allowed, hint=t.reason or _target_hint(t.target))

    def button(self, event: str) -> viser.GuiButtonHandle | None:
        """The toolbar button of a transition (tests)."""
        return {"previous": self.prev, "next": self.next, "exit": self.exit}.get(event) or \
            self._buttons.get(event)


def _command(event: str) -> PageCommand | str:
    """The machine's event as a `PageCommand` where it is one (a jump keeps its name)."""
    try:
        return PageCommand(event)
    except ValueError:
        return event


def _short(text: str, n: int = 36) -> str:
    return text if len(text) <= n else text[: n - 3] + "..."


def _target_hint(target: str | None) -> str:
    return "" if target is None else f"Go to {NUMBER[target]} {STATES[target].title}"


def _set(btn: Any, **props: Any) -> None:
    """Assign only what changed (every assignment is a message to every page)."""
    for k, v in props.items():
        if getattr(btn, k) != v:
            setattr(btn, k, v)


def _md_escape(text: str) -> str:
    return str(text).replace("<", "&lt;").replace(">", "&gt;").replace("*", "\\*") \
        .replace("_", "\\_")
