"""Typed events the session emits for the UI (and for tests that watch a session).

The web layer subscribes and redraws; nothing in the domain polls the UI. Events are small
immutable dataclasses; payloads that are large (meshes, occupancy) are fetched from the
session by the subscriber when it sees the event.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Event:
    pass


@dataclass(frozen=True)
class StateChanged(Event):
    state: str
    number: str
    title: str
    mode: str


@dataclass(frozen=True)
class SceneChanged(Event):
    """Objects, frames, locations, paths or the robot changed; `what` says which."""

    what: str
    names: tuple[str, ...] = ()


@dataclass(frozen=True)
class ProgressChanged(Event):
    task: str
    fraction: float
    message: str
    done: bool = False


@dataclass(frozen=True)
class RobotMoved(Event):
    q: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class CollisionRecorded(Event):
    q: np.ndarray = field(repr=False)
    count: int = 0
    source: str = "operator"


@dataclass(frozen=True)
class PlanReady(Event):
    summary: dict = field(default_factory=dict)


@dataclass(frozen=True)
class ProgramReady(Event):
    dialect: str
    files: tuple[str, ...]


@dataclass(frozen=True)
class ExecutionFinished(Event):
    """A robot run (execute, resume, explore) ended; `resumable` after a lost link or stop."""

    ok: bool
    summary: dict = field(default_factory=dict)
    resumable: bool = False


@dataclass(frozen=True)
class ErrorRaised(Event):
    """Something the operator asked for failed; `hint` says what to do next."""

    message: str
    hint: str = ""


@dataclass(frozen=True)
class RobotHalted(Event):
    """The simulated robot stands against something the model does not know and waits for
    the operator's Collision! (`Session.set_operator_confirms_contacts`)."""

    what: str


@dataclass(frozen=True)
class Notice(Event):
    """Information worth a notification (e.g. 'orientation projected into the arm plane')."""

    message: str


@dataclass(frozen=True)
class SaveStateChanged(Event):
    """Autosave started failing (`saved` False, `reason` says why without a path) or works
    again: until it does, the page marks the session as not saved."""

    saved: bool
    reason: str = ""


@dataclass(frozen=True)
class PointerUpdated(Event):
    position: np.ndarray | None = field(repr=False, default=None)
    std_m: float = 0.0
    mode: str = "lost"
    #: How far the ball has been held still (0..1 of `dwell_s` seconds; 0: not holding).
    dwell_progress: float = 0.0
    dwell_s: float = 0.0


class EventBus:
    """Thread-safe fan-out; a failing subscriber never breaks the session."""

    def __init__(self) -> None:
        self._subs: list[Callable[[Event], None]] = []
        self._lock = threading.Lock()
        self.errors: list[str] = []

    def subscribe(self, fn: Callable[[Event], None]) -> Callable[[], None]:
        with self._lock:
            self._subs.append(fn)

        def unsubscribe() -> None:
            with self._lock:
                if fn in self._subs:
                    self._subs.remove(fn)

        return unsubscribe

    def emit(self, ev: Event) -> None:
        with self._lock:
            subs = list(self._subs)
        for fn in subs:
            try:
                fn(ev)
            except Exception as exc:  # a UI bug must not break the domain
                self.errors.append(f"{type(ev).__name__}: {exc!r}")
