"""The robot as the assistant drives it: simulated, a MELFA controller, or a KUKA REST bridge.

A `RobotLink` moves along joint paths in real time, can be stopped at any moment, reports
where it is, and emits events. The operator's Collision! button arrives as a
`collision_indicated` event; a lost connection as `link_lost`. Implementations must never
block the caller for longer than their timeout and must refuse out-of-limit targets before
anything is sent.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

Array = np.ndarray


class LinkEventKind(str, Enum):
    MOVED = "moved"  # periodic joint update while moving
    REACHED = "reached"  # the requested motion finished
    STOPPED = "stopped"  # stopped on request before the end
    COLLISION_INDICATED = "collision_indicated"  # the operator (or a sensor) flagged a collision
    LINK_LOST = "link_lost"  # connection dropped or timed out; robot treated as stopped
    ERROR = "error"  # the controller refused or failed (message has the raw reply)


@dataclass(frozen=True)
class Halt:
    """The robot has just halted against something and stands there, waiting for the
    operator's Collision! or Stop (the simulated robot on the page: `wait_for_operator`)."""

    #: What it touches, in the operator's words ("link J3 touches hidden_box").
    touching: str


@dataclass(frozen=True)
class LinkEvent:
    kind: LinkEventKind
    q: Array | None = None
    time_s: float = 0.0
    message: str = ""
    #: Index into the joint path the motion was executing when the event happened.
    path_index: int | None = None
    details: dict = field(default_factory=dict)
    #: Set on the event that announces a halt (once per halt; the events while it stands
    #: there carry `details["halted"]` only).
    halt: Halt | None = None


class LinkError(RuntimeError):
    """A link operation failed; the message says what and, for controllers, quotes the reply."""


class LinkLost(LinkError):
    """The connection dropped or timed out; the robot must be treated as stopped."""


class RobotLink(abc.ABC):
    """Drive a robot. Methods are blocking unless named `start_*`; events go to listeners."""

    def __init__(self) -> None:
        self._listeners: list[Callable[[LinkEvent], None]] = []

    def subscribe(self, fn: Callable[[LinkEvent], None]) -> None:
        self._listeners.append(fn)

    def unsubscribe(self, fn: Callable[[LinkEvent], None]) -> None:
        """Stop sending events to `fn` (a no-op if it was not subscribed)."""
        if fn in self._listeners:
            self._listeners.remove(fn)

    def _emit(self, ev: LinkEvent) -> None:
        for fn in list(self._listeners):
            fn(ev)

    @abc.abstractmethod
    def connect(self) -> None: ...

    @abc.abstractmethod
    def close(self) -> None: ...

    @property
    @abc.abstractmethod
    def connected(self) -> bool: ...

    @abc.abstractmethod
    def current_joints(self) -> Array: ...

    @abc.abstractmethod
    def move_path(self, joint_path: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        """Move through the joint configurations in order; return the final event.

        Returns REACHED at the end, or STOPPED / COLLISION_INDICATED / LINK_LOST / ERROR with
        the configuration and path index where the robot stopped.
        """

    def move_paced(self, joint_path: Array, t: Array, hold: Array, *,
                   speed_scale: float = 1.0) -> LinkEvent:
        """Move through the joint configurations at the program's pace: reach sample i at
        `t[i]` s and stand there `hold[i]` s (a gripper action, a wait), as the controller
        will run the program (`export.pace`).

        The simulated robot follows the pace, so at 1x a run lasts the predicted cycle time.
        A controller's own interpolator times its motions, so a controller link runs
        `move_path` at `speed_scale` (the default here).
        """
        return self.move_path(joint_path, speed_scale=speed_scale)

    @abc.abstractmethod
    def stop(self) -> None:
        """Stop as soon as possible (from any thread)."""

    @abc.abstractmethod
    def indicate_collision(self, message: str = "operator pressed Collision!") -> None:
        """The operator's Collision! button: stop now and report COLLISION_INDICATED."""

    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Send a program to the controller; returns the name it is stored under."""
        raise LinkError(f"{type(self).__name__} cannot store programs")
