"""The page's toolbar commands as a type: `session.fire(PageCommand.COLLISION)`.

The first five act on the robot or the task (they are not workflow transitions); the rest are
the workflow machine's own transitions (`workflow.machine`: the step arrows and Exit; its
jumps such as "edit_mission" come from its table, by name). `Session.fire` still takes the
name as a string, as scripts and older callers give it.
"""

from __future__ import annotations

from enum import Enum


class PageCommand(str, Enum):
    """A toolbar command; its value is the workflow event's name."""

    CANCEL = "cancel"  # the long task under way
    STOP = "stop"  # the robot, now
    COLLISION = "collision"  # the operator's Collision!: stop and record the posture
    ACKNOWLEDGE = "acknowledge"  # the error shown
    RECONNECT = "reconnect"  # the lost robot link
    NEXT = "next"
    PREVIOUS = "previous"
    EXIT = "exit"
