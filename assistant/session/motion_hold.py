"""The enabling switch: who may start the robot, and what happens when they go.

A session served to pages has one holder of motion authority (an operator page). Motion - jog,
execute, resume, explore, driving the final program - starts only from the holder, runs only
while the holder is present, and stops (the link's own stop; the run is left resumable) the
moment the holder goes: a page that closes, reloads, releases authority or stops answering the
heartbeat is a let-go enabling switch. Collision! and Stop need no authority and never start
motion. Authority never passes to someone by itself (the next person may not be watching the
robot): the holder hands it over, or it lapses and someone takes it.

Headless sessions (scripts, tests) have no pages: the hold is not enforced there and the caller
holds the robot. The page turns it on (`enforce`) when it serves the session.

The actor of a call is a context variable (`acting`), set by the page around each operator
action, so the check sits in the session where every motion passes, not in the page.

Imports: the session's types only.
"""

from __future__ import annotations

import contextlib
import contextvars
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from assistant.session.types import SessionError

_ACTOR: contextvars.ContextVar[int | None] = contextvars.ContextVar("cellteach_actor",
                                                                    default=None)


class MotionRefused(SessionError):
    """A motion was asked for by someone who does not hold motion authority."""


@dataclass(frozen=True)
class HoldState:
    holder: int | None
    requests: tuple[int, ...]
    #: The holder's page answers (False while its heartbeat is late).
    present: bool


class MotionHold:
    """One holder of motion authority among the pages (module docstring). Thread-safe;
    listeners hear every change, `on_lost` callbacks hear the holder go."""

    def __init__(self) -> None:
        self.enforced = False
        self._holder: int | None = None
        self._present = False
        self._requests: list[int] = []
        self._lock = threading.Lock()
        self._listeners: list[Callable[[HoldState], None]] = []
        self._lost: Callable[[str], None] | None = None

    # ------------------------------------------------------------------ reading
    @property
    def state(self) -> HoldState:
        with self._lock:
            return HoldState(self._holder, tuple(self._requests), self._present)

    def holds(self, who: int | None) -> bool:
        return who is not None and self._holder == who

    def subscribe(self, fn: Callable[[HoldState], None]) -> None:
        self._listeners.append(fn)

    def on_lost(self, fn: Callable[[str], None]) -> None:
        """`fn(why)` runs when the holder goes or falls silent (the robot must stop); one
        session at a time (a loaded session takes the page's hold over)."""
        self._lost = fn

    def enforce(self) -> None:
        """Pages serve this session: from now on only a present holder moves the robot."""
        self.enforced = True

    # ------------------------------------------------------------------ the check
    @staticmethod
    @contextlib.contextmanager
    def acting(who: int | None) -> Iterator[None]:
        """Calls inside are made by `who` (a page's id)."""
        token = _ACTOR.set(who)
        try:
            yield
        finally:
            _ACTOR.reset(token)

    @staticmethod
    def actor() -> int | None:
        return _ACTOR.get()

    def refusal(self) -> str:
        """Why the current actor may not start motion ('' if it may)."""
        if not self.enforced:
            return ""
        who = _ACTOR.get()
        with self._lock:
            holder, present = self._holder, self._present
        if who is None or holder != who:
            return "Only the page that holds motion authority can move the robot: take it " \
                "(or ask for it) under Motion authority. Collision! and Stop work from " \
                "every operator page."
        if not present:
            return "This page's connection is not answering: the robot does not move until " \
                "it does."
        return ""

    def check_start(self) -> None:
        """Raise `MotionRefused` unless the current actor may start motion now."""
        why = self.refusal()
        if why:
            raise MotionRefused(why)

    def may_move(self) -> bool:
        """Is there a present holder (or no pages at all)? Motion in progress asks this."""
        if not self.enforced:
            return True
        with self._lock:
            return self._holder is not None and self._present

    # ------------------------------------------------------------------ changes
    def _changed(self, lost: str = "") -> None:
        if lost and self._lost is not None:
            self._lost(lost)  # the robot stops first; the pages hear of it after
        st = self.state
        for fn in list(self._listeners):
            fn(st)

    def _set(self, holder: int | None) -> None:
        self._holder = holder
        self._present = holder is not None
        if holder in self._requests:
            self._requests.remove(holder)

    def joined(self, who: int) -> bool:
        """A page arrived: it gets authority if nobody holds it."""
        return self.take(who)

    def take(self, who: int) -> bool:
        with self._lock:
            if self._holder is not None:
                return self._holder == who
            self._set(who)
        self._changed()
        return True

    def request(self, who: int) -> None:
        with self._lock:
            if self._holder == who or who in self._requests:
                return
            self._requests.append(who)
        self._changed()

    def hand_over(self, who: int) -> int | None:
        """The holder passes it to the first who asked; returns the new holder."""
        with self._lock:
            if self._holder != who or not self._requests:
                return None
            self._set(self._requests[0])
            new = self._holder
        self._changed()
        return new

    def release(self, who: int) -> None:
        with self._lock:
            if self._holder != who:
                return
            self._set(None)
        self._changed("the page that held motion authority released it")

    def left(self, who: int) -> None:
        """A page closed (or reloaded): its authority lapses, its request is withdrawn."""
        with self._lock:
            was_holder = self._holder == who
            if not was_holder and who not in self._requests:
                return
            if was_holder:
                self._set(None)
            if who in self._requests:
                self._requests.remove(who)
        self._changed("the page that held motion authority closed" if was_holder else "")

    def heard(self, who: int, answering: bool) -> None:
        """The heartbeat: the page `who` answers (or has fallen silent)."""
        with self._lock:
            if self._holder != who or self._present == answering:
                return
            self._present = answering
        self._changed("" if answering else
                      "the page that holds motion authority stopped answering")
