"""Page callbacks that call the session: guarded, one at a time, errors shown with a hint.

viser only greys a disabled button out in the browser; a stale or hostile page can still
send the click. So every callback re-checks that its control is enabled and visible before it
acts, and the session's workflow machine refuses anything the step does not allow.
Behind the gate (`web.gate`) every callback also asks whether its page may act: a viewer never,
a control marked `motion` only from the page that holds motion authority.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from assistant.session import hint_for
from assistant.session.motion_hold import MotionHold
from workflow.machine import TransitionRefused

if TYPE_CHECKING:
    from web.app import App

log = logging.getLogger(__name__)

NOT_AVAILABLE = "That action is not available now (the page may be out of date; it is now " \
    "refreshed)."


class Actions:
    """Binds page controls to session calls."""

    def __init__(self, app: App):
        self._app = app
        self._running: set[int] = set()
        self._lock = threading.Lock()

    def bind(self, handle: Any, fn: Callable[[viser.GuiEvent], Any], *,
             when: Callable[[], bool] | None = None, motion: bool = False) -> None:
        """Run fn on a click (buttons, commands) or an operator edit (inputs, uploads);
        `motion`: the control starts robot motion (needs motion authority behind the gate)."""
        cb = self.guarded(handle, fn, when, motion)
        if hasattr(handle, "on_upload"):
            handle.on_upload(cb)
        elif hasattr(handle, "on_click"):
            handle.on_click(cb)
        elif hasattr(handle, "on_trigger"):
            handle.on_trigger(cb)
        else:
            handle.on_update(cb)

    def guarded(self, handle: Any, fn: Callable[[Any], Any],
                 when: Callable[[], bool] | None, motion: bool = False
                 ) -> Callable[[Any], None]:
        def cb(event: Any) -> None:
            client = getattr(event, "client", None)
            if client is None:
                return  # the server set the value itself: not an operator action
            if not self.permitted(client, motion=motion):
                return
            if getattr(handle, "disabled", False) or not getattr(handle, "visible", True) or \
                    (when is not None and not when()):
                self._app.notifier.error(NOT_AVAILABLE, client=client)
                self._app.refresh()
                return
            key = id(handle)
            with self._lock:
                if key in self._running:
                    return  # a double click while the first one still runs
                self._running.add(key)
            try:
                self.run(lambda: fn(event), client)
            finally:
                with self._lock:
                    self._running.discard(key)

        return cb

    def permitted(self, client: viser.ClientHandle, *, motion: bool = False) -> bool:
        """May this page act (always, unless the gate says why not - shown to that page)?"""
        access = getattr(self._app, "access", None)
        why = "" if access is None else access.refusal(client, motion=motion)
        if why:
            self._app.notifier.error(why, client=client)
            self._app.refresh()  # e.g. a refused jog gizmo goes back to the robot
        return not why

    def run(self, fn: Callable[[], Any], client: viser.ClientHandle | None = None, *,
            motion: bool = False) -> Any:
        """Call fn; any failure becomes a notification (once), never a broken page.
        `motion` (with a client): only from the page that may move the robot."""
        notifier = self._app.notifier
        if motion and client is not None and not self.permitted(client, motion=True):
            return None
        notifier.clear_errors()  # acting again: what failed before is stale
        try:
            # The session checks who starts motion (`MotionHold`): this page acts.
            with MotionHold.acting(getattr(client, "client_id", None)):
                return fn()
        except TransitionRefused as exc:
            if not notifier.already_shown(str(exc)):
                notifier.error(str(exc), client=client)
        except Exception as exc:  # noqa: BLE001 - everything the operator triggers is caught
            msg = str(exc) or type(exc).__name__
            if isinstance(exc, (ValueError, KeyError, OSError, RuntimeError)) or \
                    type(exc).__module__.startswith(("assistant", "vision", "workflow")):
                if not notifier.already_shown(msg):
                    notifier.error(msg, hint_for(exc), client=client)
            else:
                log.exception("page action failed")
                notifier.error(f"internal error: {type(exc).__name__}: {msg}",
                               "Try again; if it repeats, save the session and report it.",
                               client=client)
        return None
