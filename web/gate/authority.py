"""One holder of motion authority among the operator connections.

Only the holder may start motion (jog, execute, resume, explore). The first operator to arrive
while nobody holds it gets it; others ask for it and the holder hands it over (to the first
who asked) or releases it; it lapses when the holder's connection closes - it never passes to
someone by itself, since the next person may not be watching the robot. Collision! and Stop
need no authority. Thread-safe; listeners hear every change.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class AuthorityState:
    holder: int | None
    requests: tuple[int, ...]


class MotionAuthority:
    def __init__(self) -> None:
        self._holder: int | None = None
        self._requests: list[int] = []
        self._lock = threading.Lock()
        self._listeners: list[Callable[[AuthorityState], None]] = []

    @property
    def state(self) -> AuthorityState:
        with self._lock:
            return AuthorityState(self._holder, tuple(self._requests))

    def holds(self, who: int) -> bool:
        return self._holder == who

    def subscribe(self, fn: Callable[[AuthorityState], None]) -> None:
        self._listeners.append(fn)

    def _changed(self) -> None:
        st = self.state
        for fn in list(self._listeners):
            fn(st)

    def _set(self, holder: int | None) -> None:
        self._holder = holder
        if holder in self._requests:
            self._requests.remove(holder)

    # ------------------------------------------------------------------ changes
    def joined(self, who: int) -> bool:
        """An operator connection arrived: it gets authority if nobody holds it."""
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
            self._holder = None
        self._changed()

    def left(self, who: int) -> None:
        """A connection closed: its authority lapses, its request is withdrawn."""
        with self._lock:
            if self._holder != who and who not in self._requests:
                return
            if self._holder == who:
                self._holder = None
            if who in self._requests:
                self._requests.remove(who)
        self._changed()
