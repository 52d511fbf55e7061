"""What FANUC TP and Yaskawa INFORM programs tell the operator in comments, and reading it back.

Both controllers keep the tool and user frames as controller data that a program selects by
number, and both hold comments of 32 characters. The programs therefore give the frames'
values in short comment lines to set on the teach pendant (`frame_comments`); step labels and
gripper actions are comments too. `CommentState` reads all of that back while a reader walks
the program: the step a line belongs to, the frames, and whether an output and a wait are a
gripper action (``close gripper 1``, the output, the wait for the fingers).
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass, field

import numpy as np

from assistant.export.dialect import (
    ascii_text,
    parse_step_comment,
    xyz_fixed_angles,
    xyz_fixed_matrix,
)
from assistant.export.program import Frame, Gripper, Instruction, SetOutput, Wait
from assistant.export.rules import format_fixed, parse_number

#: Comment instructions hold at most this many characters (FANUC ``!``, INFORM ``'``).
COMMENT_LENGTH = 32


def short_comments(lead: str, text: str) -> list[str]:
    """Free text as comment lines of at most `COMMENT_LENGTH` characters after `lead`
    (ASCII; ";" ends a FANUC line, so it becomes ",")."""
    clean = ascii_text(text).replace(";", ",")
    return [lead + part for part in textwrap.wrap(clean, COMMENT_LENGTH) or [""]]


def frame_comments(lead: str, label: str, frame: Frame, angles: tuple[str, str, str],
                   angle_decimals: int) -> list[str]:
    """``label name`` and the frame's X, Y, Z (mm) and rotations about the fixed X, Y, Z
    (deg, named `angles`: FANUC W, P, R; Yaskawa Rx, Ry, Rz), two values a line."""
    T = np.asarray(frame.T, dtype=float)
    x, y, z = (format_fixed(v, 3, what=label) for v in T[:3, 3] * 1000.0)
    a, b, c = (format_fixed(v, angle_decimals, what=label)
               for v in np.degrees(xyz_fixed_angles(T)))
    head = f"{label} {ascii_text(frame.name).replace(';', ',')}"[:COMMENT_LENGTH]
    return [f"{lead}{head}", f"{lead}X {x} Y {y}", f"{lead}Z {z} {angles[0]} {a}",
            f"{lead}{angles[1]} {b} {angles[2]} {c}"]


@dataclass
class CommentState:
    """The comments read so far: the step, a gripper action announced, the frames given.

    `frame_head` matches a frame's first comment line with groups (kind, number, name)."""

    frame_head: re.Pattern[str]
    step: str = ""
    hand: tuple[int, bool] | None = None
    frames: dict[tuple[str, int], Frame] = field(default_factory=dict)
    _head: tuple[str, int, str] | None = None
    _values: list[float] = field(default_factory=list)

    def feed(self, note: str) -> None:
        """One comment's text (other comments - the header, free text - change nothing)."""
        note = note.strip()
        step = parse_step_comment(note)
        grip = re.fullmatch(r"(open|close) gripper (\d+)", note)
        head = self.frame_head.fullmatch(note)
        pair = re.fullmatch(r"(\w+) (\S+) (\w+) (\S+)", note)
        if step is not None:
            self.step = step
        elif grip:
            self.hand = (int(grip.group(2)), grip.group(1) == "close")
        elif head:
            self._head, self._values = (head.group(1), int(head.group(2)), head.group(3)), []
        elif pair and self._head is not None:
            self._values += [parse_number(pair.group(2)), parse_number(pair.group(4))]
            if len(self._values) == 6:
                T = np.eye(4)
                T[:3, :3] = xyz_fixed_matrix(*np.radians(self._values[3:]))
                T[:3, 3] = np.asarray(self._values[:3]) / 1000.0
                kind, n, name = self._head
                self.frames[(kind, n)] = Frame(name or kind.lower(), T)
                self._head = None

    def output(self, channel: int, on: bool) -> Instruction:
        """An output: the gripper action just announced, else a plain output."""
        if self.hand is not None:
            return Gripper(self.hand[0], self.hand[1], self.step)
        return SetOutput(channel, on, self.step)

    def wait(self, seconds: float) -> Instruction | None:
        """A wait: None when it is the announced gripper action's own wait."""
        if self.hand is not None:
            self.hand = None
            return None
        return Wait(seconds, self.step)
