"""A small MELFA BASIC IV interpreter, enough to run what the assistant uploads.

Covers the streaming program (OPEN / INPUT / MOV with CNT / PRINT / GOTO / IF) and generated
programs (MOV, MVS, MVR, OVRD, SPD, CNT, HOPEN/HCLOSE, DLY, END and the position lines
``P1=(x,y,z,a,b,c)(fl1,fl2)`` / ``J1=(...)``). Anything else is a syntax error at upload
time, as a real controller's EMDAT check would report it (our error 3100 + the line).
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from assistant.links import melfa_protocol as mp
from assistant.links.melfa_protocol import MelfaPose

Array = np.ndarray

KEYWORDS = {
    "MOV", "MVS", "MVR", "OVRD", "SPD", "CNT", "SERVO", "OPEN", "CLOSE", "DEF", "INPUT",
    "PRINT", "GOTO", "IF", "END", "HLT", "HOPEN", "HCLOSE", "DLY", "REM", "ACCEL", "TOOL",
}


class ProgramError(Exception):
    """A run-time error of the program: its MELFA-style error number and message."""

    def __init__(self, code: int, message: str, line: int | None = None):
        super().__init__(message)
        self.code = code
        self.line = line


class ProgramSyntaxError(ProgramError):
    def __init__(self, message: str, line: int | None = None, pos: int = 1):
        super().__init__(mp.ERR_SYNTAX, message, line)
        self.pos = pos


@dataclass
class MelfaProgram:
    """Stored program: numbered statements and position variables."""

    name: str
    code: dict[int, str] = field(default_factory=dict)
    positions: dict[str, str] = field(default_factory=dict)

    def add_line(self, raw: str) -> None:
        """Add one EMDAT line; raises `ProgramSyntaxError` for what we cannot run."""
        text = raw.strip()
        if not text:
            return
        m = re.match(r"(\d+)\s*(.*)$", text)
        if m:
            no, stmt = int(m.group(1)), m.group(2).strip()
            check_statement(stmt, no)
            self.code[no] = stmt
            return
        m = re.match(r"([A-Za-z][A-Za-z0-9_]*)\s*=\s*(\(.*)$", text)
        if m:
            self.positions[m.group(1).upper()] = m.group(2)
            return
        raise ProgramSyntaxError(f"line without a number: {text[:40]!r}")

    @property
    def line_count(self) -> int:
        return len(self.code)


def statement_keyword(stmt: str) -> str:
    s = stmt.strip()
    if s.startswith("'"):
        return "REM"
    m = re.match(r"([A-Za-z_][A-Za-z0-9_]*)", s)
    return m.group(1).upper() if m else ""


def check_statement(stmt: str, line: int | None = None) -> None:
    kw = statement_keyword(stmt)
    if kw in KEYWORDS:
        return
    if re.match(r"[A-Za-z][A-Za-z0-9_]*\s*=", stmt):
        return  # assignment
    raise ProgramSyntaxError(f"unsupported statement {stmt[:40]!r}", line)


def split_top_level(text: str) -> list[str]:
    """Split on commas outside parentheses: 'M1,(1,2)' -> ['M1', '(1,2)']."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    if cur or out:
        out.append("".join(cur).strip())
    return out


class Machine(Protocol):
    """What the interpreter needs of the emulated controller."""

    joint_names: list[str]

    def current_q(self) -> Array: ...

    def current_pose(self) -> MelfaPose: ...

    def move(self, targets: list[object], kind: str, speed: float, blend: bool,
             abort: threading.Event) -> None: ...

    def set_servo(self, on: bool) -> None: ...

    def set_hand(self, n: int, closed: bool) -> None: ...

    def datalink_open(self, com: int, abort: threading.Event) -> None: ...

    def datalink_readline(self, com: int, abort: threading.Event) -> str: ...

    def datalink_write(self, com: int, text: str, abort: threading.Event) -> None: ...

    def sleep(self, robot_seconds: float, abort: threading.Event) -> None: ...

    def panel_override(self) -> float: ...


class Interpreter:
    """Runs statements against a `Machine`; variables persist across calls (direct mode)."""

    def __init__(self, machine: Machine, program: MelfaProgram | None = None):
        self.m = machine
        self.program = program or MelfaProgram("DIRECT")
        self.numbers: dict[str, float] = {}
        self.values: dict[str, object] = {}
        self.jnt_vars: set[str] = set()
        self.channels: dict[int, int] = {}
        self.ovrd = 100.0
        self.cnt = False
        self.line: int | None = None
        for name, lit in self.program.positions.items():
            self.values[name] = self._literal(lit, name.startswith("J"))

    # ------------------------------------------------------------------ running
    def run(self, abort: threading.Event, on_line: Callable[[int], None] | None = None) -> None:
        lines = sorted(self.program.code)
        if not lines:
            return
        idx = {no: i for i, no in enumerate(lines)}
        i = 0
        while i < len(lines) and not abort.is_set():
            self.line = lines[i]
            if on_line:
                on_line(self.line)
            jump = self.execute(self.program.code[self.line], abort)
            if jump == -1:
                return
            if jump is None:
                i += 1
            elif jump in idx:
                i = idx[jump]
            else:
                raise ProgramError(mp.ERR_ILLEGAL_DATA, f"no line {jump}", self.line)

    def execute(self, stmt: str, abort: threading.Event) -> int | None:
        """Run one statement; returns a line to jump to, -1 to end, or None to go on."""
        kw = statement_keyword(stmt)
        rest = stmt.strip()[len(kw):].strip() if kw != "REM" else ""
        if kw in ("REM", "SPD", "ACCEL", "TOOL"):
            return None
        if kw in ("END", "HLT"):
            return -1
        if kw == "GOTO":
            return int(rest)
        if kw == "IF":
            return self._if(rest)
        if kw == "OVRD":
            self.ovrd = float(np.clip(self._number(rest), 1.0, 100.0))
            return None
        if kw == "CNT":
            self.cnt = self._number(split_top_level(rest)[0]) != 0
            return None
        if kw == "SERVO":
            self.m.set_servo(rest.upper() == "ON")
            return None
        if kw in ("HOPEN", "HCLOSE"):
            self.m.set_hand(int(self._number(rest or "1")), kw == "HCLOSE")
            return None
        if kw == "DLY":
            self.m.sleep(self._number(rest), abort)
            return None
        if kw == "DEF":
            return self._def(rest)
        if kw == "OPEN":
            m = re.fullmatch(r'"COM(\d+):"\s+AS\s+#(\d+)', rest, re.IGNORECASE)
            if not m:
                raise ProgramSyntaxError(f"OPEN {rest!r}", self.line)
            com, ch = int(m.group(1)), int(m.group(2))
            self.m.datalink_open(com, abort)
            self.channels[ch] = com
            return None
        if kw == "CLOSE":
            self.channels.clear()
            return None
        if kw == "INPUT":
            return self._input(rest, abort)
        if kw == "PRINT":
            return self._print(rest, abort)
        if kw in ("MOV", "MVS", "MVR"):
            return self._move(kw, rest, abort)
        m = re.fullmatch(r"([A-Za-z][A-Za-z0-9_]*)\s*=\s*(.+)", stmt.strip())
        if m:
            self._assign(m.group(1).upper(), m.group(2).strip())
            return None
        raise ProgramSyntaxError(f"unsupported statement {stmt[:40]!r}", self.line)

    # ------------------------------------------------------------------ statements
    def _def(self, rest: str) -> None:
        m = re.fullmatch(r"(JNT|POS)\s+([A-Za-z][A-Za-z0-9_]*)", rest, re.IGNORECASE)
        if not m:
            raise ProgramSyntaxError(f"DEF {rest!r}", self.line)
        if m.group(1).upper() == "JNT":
            self.jnt_vars.add(m.group(2).upper())
        return None

    def _is_jnt(self, name: str) -> bool:
        return name in self.jnt_vars or (name.startswith("J") and name != "J_CURR"
                                         and not name.startswith("J_"))

    def _if(self, rest: str) -> int | None:
        m = re.fullmatch(r"(.+?)\s*(<=|>=|<>|=|<|>)\s*(.+?)\s+THEN\s+(\d+)", rest,
                         re.IGNORECASE)
        if not m:
            raise ProgramSyntaxError(f"IF {rest!r}", self.line)
        a, op, b = self._number(m.group(1)), m.group(2), self._number(m.group(3))
        ok = {"<": a < b, ">": a > b, "=": a == b, "<=": a <= b, ">=": a >= b,
              "<>": a != b}[op]
        return int(m.group(4)) if ok else None

    def _channel(self, ch: str) -> int:
        n = int(ch.strip().lstrip("#"))
        if n not in self.channels:
            raise ProgramError(mp.ERR_ILLEGAL_DATA, f"file #{n} is not open", self.line)
        return self.channels[n]

    def _input(self, rest: str, abort: threading.Event) -> None:
        parts = split_top_level(rest)
        com = self._channel(parts[0])
        names = [p.upper() for p in parts[1:]]
        line = self.m.datalink_readline(com, abort)
        if abort.is_set():
            return None
        values = split_top_level(line.strip())
        if len(values) < len(names):
            raise ProgramError(mp.ERR_ILLEGAL_DATA, f"INPUT got {line!r}", self.line)
        for name, text in zip(names, values, strict=False):
            try:
                self._assign(name, text)
            except (ValueError, ProgramError) as exc:
                raise ProgramError(mp.ERR_ILLEGAL_DATA, f"INPUT {name}: {exc}",
                                   self.line) from None
        return None

    def _print(self, rest: str, abort: threading.Event) -> None:
        parts = split_top_level(rest)
        com = self._channel(parts[0])
        out = []
        for p in parts[1:]:
            v = self._value(p.strip())
            if isinstance(v, float):
                out.append(str(int(v)) if v.is_integer() else f"{v:.6g}")
            elif isinstance(v, MelfaPose):
                out.append(mp.format_pose_literal(v))
            elif isinstance(v, str):
                out.append(v)
            else:
                out.append(mp.format_joint_literal(np.asarray(v), self.m.joint_names))
        self.m.datalink_write(com, ",".join(out), abort)
        return None

    def _move(self, kw: str, rest: str, abort: threading.Event) -> None:
        args = [self._value(a) for a in split_top_level(rest)]
        if kw == "MVR" and len(args) != 3:
            raise ProgramSyntaxError("MVR needs start, via and end positions", self.line)
        if kw != "MVR" and len(args) != 1:
            raise ProgramSyntaxError(f"{kw} takes one target", self.line)
        speed = self.ovrd / 100.0 * self.m.panel_override() / 100.0
        self.m.move(args, kw, speed, self.cnt, abort)
        return None

    def _assign(self, name: str, text: str) -> None:
        if name.startswith("M") and not name.startswith("M_"):
            self.numbers[name] = self._number(text)
            return
        v = self._value(text, jnt=self._is_jnt(name))
        if isinstance(v, float):
            raise ProgramError(mp.ERR_ILLEGAL_DATA, f"{name} needs a position", self.line)
        self.values[name] = v

    # ------------------------------------------------------------------ values
    def _literal(self, text: str, jnt: bool) -> object:
        if jnt:
            return mp.parse_joint_literal(text, self.m.joint_names)
        return mp.parse_pose_literal(text)

    def _value(self, text: str, jnt: bool | None = None) -> object:
        t = text.strip()
        up = t.upper()
        if t.startswith("("):
            is_pose = bool(re.fullmatch(r"\([^()]*\)\s*\([^()]*\)", t))
            try:
                return self._literal(t, jnt if jnt is not None else not is_pose)
            except ValueError as exc:
                raise ProgramError(mp.ERR_ILLEGAL_DATA, str(exc), self.line) from None
        if t.startswith('"') and t.endswith('"'):
            return t[1:-1]
        if up == "J_CURR":
            return self.m.current_q()
        if up == "P_CURR":
            return self.m.current_pose()
        if up in self.values:
            return self.values[up]
        return self._number(t)

    def _number(self, text: str) -> float:
        t = text.strip().upper()
        m = re.fullmatch(r"(.+?)\s*([-+*/])\s*(.+)", t)
        if m and not re.fullmatch(mp._NUM, t):
            a, b = self._number(m.group(1)), self._number(m.group(3))
            return {"+": a + b, "-": a - b, "*": a * b, "/": a / b if b else float("inf")}[
                m.group(2)]
        if re.fullmatch(mp._NUM, t):
            return float(t)
        if t in self.numbers:
            return self.numbers[t]
        if re.fullmatch(r"M[A-Z0-9_]*", t):
            return 0.0  # MELFA numeric variables start at 0
        raise ProgramError(mp.ERR_ILLEGAL_DATA, f"not a number: {text!r}", self.line)
