"""Shown means saved: every accepted change is on disk before a page can show it.

Actions change the session under its lock and autosave before they let go of it (the action
wrapper in `session.py`, and each long task's result where it is stored); the page reads the
session only under the same lock (`settled`, used by `web.pump`). So whatever a page shows is
either from before an action or was saved with it, and a kill at any moment loses nothing a
page showed.

If the disk refuses a save, the change stays in memory (undoing the operator's work because a
disk is full would lose it for sure), `save_error` says why, and `SaveStateChanged` tells the
page to mark the session as not saved until a later save works; every change retries.

A part of the `Session`, composed (`Session.saving`): it owns why the last autosave failed; it
reaches the rest of the session only through the parts' contract (`PartContract`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator

from assistant.session.contract import PartContract
from assistant.session.events import ErrorRaised, SaveStateChanged

log = logging.getLogger(__name__)

NOT_SAVED = "Not saved: {reason}. The last change is only in memory; every change tries " \
    "again."
NOT_SAVED_HINT = "Free space on the disk or make the session folder writable, or save the " \
    "session to another folder (Session file)."


class SavingPart:
    """Autosave with its outcome kept (`save_error`) and the page's settled view."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: Why the last autosave failed ("" when the session on disk is up to date).
        self.save_error = ""

    def autosave(self) -> None:
        """Save to the session folder (when it has one); call under the session lock, after
        the change and before the lock is let go."""
        if not (self._core.autosave_enabled and self._core.folder is not None):
            return
        try:
            self._core.persistence.save(self._core.folder)
        except (OSError, ValueError) as exc:
            reason = _reason(exc)
            log.warning("autosave to %s failed: %s", self._core.folder, exc)
            if reason != self.save_error:
                self.save_error = reason
                self._core.bus.emit(SaveStateChanged(False, reason))
                self._core.bus.emit(ErrorRaised(NOT_SAVED.format(reason=reason), NOT_SAVED_HINT))
            return
        if self.save_error:
            self.save_error = ""
            self._core.bus.emit(SaveStateChanged(True, ""))

    @contextlib.contextmanager
    def settled(self) -> Iterator[None]:
        """Hold actions off while a page reads the session: what it reads is then either from
        before an action or saved with it (never an action's change in flight)."""
        with self._core.lock:
            yield


def _reason(exc: BaseException) -> str:
    """Why a save failed, without the folder's path (every page shows it)."""
    if isinstance(exc, OSError):
        return (exc.strerror or type(exc).__name__).lower()
    return str(exc).split(": ")[-1] or type(exc).__name__
