"""Notifications in every open page: errors say what to do next, notices inform.

The session announces failures itself (`ErrorRaised`) and a page callback also sees the
exception it raised; the notifier remembers recent messages so the operator reads each once.
An error stays on screen until the operator acts again or the step changes (`clear_errors`):
a failure that later actions have moved past is stale, and a stale error beside a success
reads as a contradiction.

Who reads what (behind the gate a page is an operator's or a viewer's, `audience`):
- a message for one page (`client=`: a refusal, "Session saved to ...") shows on that page
  only - as its notification and in its own status line, never in the shared one;
- a message for everyone (what the session announced) shows on every operator page and in
  the shared status line; viewers get its notices and successes but no error notification
  (they cannot act on one; the status line tells them what happened);
- text every page sees goes through `redact` first (the app takes the session folder's path
  out: viewers get what watching needs, not paths).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Literal

import viser

log = logging.getLogger(__name__)

#: How long an error message counts as "already shown" for the same failure.
DEDUP_S = 5.0


OPERATOR, VIEWER = "operator", "viewer"


class Notifier:
    def __init__(self, server: viser.ViserServer, *,
                 audience: Callable[[viser.ClientHandle], str] | None = None,
                 redact: Callable[[str], str] | None = None):
        self._server = server
        self._audience = audience or (lambda c: OPERATOR)
        self._redact = redact or (lambda text: text)
        self._lock = threading.Lock()
        self._recent: deque[tuple[float, str]] = deque(maxlen=32)
        #: The notice on screen per (key, client): a burst (26 collisions) replaces it
        #: instead of stacking up and pushing errors out of view.
        self._keyed: dict[tuple[str, int], viser.NotificationHandle] = {}
        #: Error notifications on screen, until superseded (`clear_errors`).
        self._errors: list[viser.NotificationHandle] = []
        #: "Done" notifications on screen, until a new phase begins (`clear_done`).
        self._done: list[viser.NotificationHandle] = []
        self._status_kind = ""
        #: Pages whose own status line shows a "Done" (the action was theirs).
        self._done_pages: dict[int, viser.ClientHandle] = {}
        #: Called with (kind, text, client) for every message (the toolbar's status lines:
        #: client None is the shared one); kind "clear" with "" when shown messages are
        #: superseded (client None: every status line forgets them; else that page's own).
        self.on_message: Callable[[str, str, viser.ClientHandle | None], None] | None = None

    # ------------------------------------------------------------------ dedup
    def remember(self, message: str) -> None:
        """Record an error as shown (called on the emitting thread, before it returns)."""
        with self._lock:
            self._recent.append((time.monotonic(), message))

    def clear_errors(self) -> None:
        """The operator acted again or the step changed: earlier errors are stale. Their
        notifications close, the status line forgets them, and the same message may be
        shown again (a repeated failure is news)."""
        with self._lock:
            errors, self._errors = self._errors, []
            self._recent.clear()
            was_error = self._status_kind == "error"
            if was_error:  # a "Done" line stays until its phase ends (`clear_done`)
                self._status_kind = ""
        _remove(errors)
        if was_error and self.on_message is not None:
            self.on_message("clear", "", None)

    def already_shown(self, message: str) -> bool:
        now = time.monotonic()
        with self._lock:
            return any(now - t < DEDUP_S and message and message in m for t, m in self._recent)

    # ------------------------------------------------------------------ output
    def error(self, message: str, hint: str = "", *, client: viser.ClientHandle | None = None
              ) -> None:
        """A failure: red, stays until closed, with the next step to take."""
        parts = [_sentence(message)] + ([f"What to do: {_sentence(hint)}"] if hint else [])
        body = " ".join(parts + ["Nothing you did was lost."])
        shown = self._show("Could not do that", body, color="red", auto_close=None,
                           client=client, viewers=False)
        with self._lock:
            self._errors.extend(shown)
        self._status("error", message + (f" - {hint}" if hint else ""), client)

    def notice(self, message: str, *, client: viser.ClientHandle | None = None,
               key: str | None = None) -> None:
        """Information; with a `key`, it replaces the previous notice of that key."""
        self._show("Note", message, color="blue", auto_close=10.0, client=client, key=key)
        self._status("notice", message, client)

    def success(self, message: str, *, client: viser.ClientHandle | None = None) -> None:
        shown = self._show("Done", message, color="green", auto_close=6.0, client=client)
        with self._lock:
            self._done.extend(shown)
        self._status("ok", message, client)
        if client is not None:
            with self._lock:
                self._done_pages[id(client)] = client

    def clear_done(self) -> None:
        """A new phase begins (a run starts): what the last one finished is history - its
        "Done" notifications close and the status line forgets it."""
        with self._lock:
            done, self._done = self._done, []
            was_ok = self._status_kind == "ok"
            if was_ok:
                self._status_kind = ""
            pages, self._done_pages = list(self._done_pages.values()), {}
        _remove(done)
        if self.on_message is not None:
            if was_ok:
                self.on_message("clear", "", None)
            for page in pages:  # the page's own "Done" line (its own action's outcome)
                self.on_message("clear", "", page)

    def _status(self, kind: str, text: str, client: viser.ClientHandle | None) -> None:
        if client is not None and kind != "ok":
            with self._lock:  # the page's line shows something newer than its "Done"
                self._done_pages.pop(id(client), None)
        if client is None:
            self._status_kind = kind
            text = self._redact(text)
        if self.on_message is not None:
            self.on_message(kind, text, client)

    def _show(self, title: str, body: str, *, color: Literal["red", "blue", "green"],
              auto_close: float | None,
              client: viser.ClientHandle | None, key: str | None = None,
              viewers: bool = True) -> list[viser.NotificationHandle]:
        if client is not None:
            clients = [client]
        else:  # for everyone: redacted, and errors to operators only
            body = self._redact(body)
            clients = [c for c in self._server.get_clients().values()
                       if viewers or self._audience(c) == OPERATOR]
        shown = []
        for c in clients:
            try:
                if key is not None:
                    old = self._keyed.pop((key, c.client_id), None)
                    if old is not None and not old._impl.removed:  # noqa: SLF001
                        old.remove()
                h = c.add_notification(title, body, color=color,
                                       auto_close_seconds=auto_close, with_close_button=True)
                if key is not None:
                    self._keyed[(key, c.client_id)] = h
                shown.append(h)
            except Exception:  # noqa: BLE001 - a closing tab must not break the others
                log.debug("notification to a closing client failed", exc_info=True)
        return shown


def _sentence(text: str) -> str:
    text = str(text).strip()
    return text if text.endswith((".", "!", "?")) else text + "."


def _remove(handles: list[viser.NotificationHandle]) -> None:
    for h in handles:
        try:
            if not h._impl.removed:  # noqa: SLF001
                h.remove()
        except Exception:  # noqa: BLE001 - a closed tab's notification is gone anyway
            log.debug("closing a stale notification failed", exc_info=True)
