"""The motions of loaded RAPID modules, for the RWS emulator to execute.

Reads what our exporter and our link write: data declarations (``CONST|PERS|VAR [TASK]``
robtarget, jointtarget, speeddata, zonedata, tooldata, wobjdata), ``PROC name()`` bodies
with MoveAbsJ / MoveJ / MoveL / MoveC, SetDO, WaitTime, calls of other PROCs and ``!``
comments. Anything else is refused with its line, so a module the emulator cannot execute
is never silently run as something else (the controller's loadmod fails the same way on
an error). Lengths in mm and degrees as in RAPID; converted to metres/radians here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from assistant.links.abb_rws_protocol import pose_from

Array = np.ndarray

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:E[-+]?\d+)?"
_DECL = re.compile(r"(?:LOCAL\s+)?(?:TASK\s+)?(CONST|PERS|VAR)\s+(\w+)\s+(\w+)\s*:=\s*(.*);",
                   re.IGNORECASE)
_MOVE = re.compile(r"(MoveAbsJ|MoveJ|MoveL|MoveC)\s+(.*);", re.IGNORECASE)
PREDEFINED_TYPES = ("robtarget", "jointtarget", "speeddata", "zonedata", "tooldata",
                    "wobjdata", "num", "bool", "string", "loaddata")


class RapidError(ValueError):
    """Something in a module the emulator cannot load or execute; names module and line."""


@dataclass(frozen=True)
class RobTarget:
    T: Array  # pose of the tool in its work object (metres)
    conf: tuple[int, int, int, int]


@dataclass(frozen=True)
class Step:
    """One executable instruction of a flattened main."""

    kind: str  # MOVEABSJ | MOVEJ | MOVEL | MOVEC | SETDO | WAIT
    line: str
    where: str  # "MODULE:line"
    q: Array | None = None  # MoveAbsJ target (rad)
    target: RobTarget | None = None
    via: RobTarget | None = None
    speed_mm_s: float = 1000.0
    tool: Array = field(default_factory=lambda: np.eye(4))
    wobj: Array = field(default_factory=lambda: np.eye(4))
    signal: str = ""
    value: float = 0.0


@dataclass
class Module:
    name: str
    data: dict[str, tuple[str, str, str]]  # NAME -> (storage, type, value text)
    procs: dict[str, list[tuple[int, str]]]  # NAME -> [(line number, statement)]


def _nums(text: str) -> list[float]:
    text = re.sub(r'"[^"]*"', "", text)  # strings (a wobj's mechanical unit) hold no numbers
    return [float(v) for v in re.findall(_NUM, text, re.IGNORECASE)]


def parse_module(text: str) -> Module:
    """Declarations and PROC bodies of one module; RapidError on what we do not know."""
    name = None
    data: dict[str, tuple[str, str, str]] = {}
    procs: dict[str, list[tuple[int, str]]] = {}
    cur: str | None = None
    for no, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("!", 1)[0].strip()
        if not line:
            continue
        up = line.upper()
        if m := re.fullmatch(r"MODULE\s+([A-Za-z]\w*)(?:\s*\(.*\))?", line, re.IGNORECASE):
            name = m.group(1)
        elif up == "ENDMODULE":
            break
        elif m := re.fullmatch(r"(?:LOCAL\s+)?PROC\s+(\w+)\s*\(\s*\)", line, re.IGNORECASE):
            cur = m.group(1).upper()
            procs[cur] = []
        elif up == "ENDPROC":
            cur = None
        elif cur is not None:
            procs[cur].append((no, line))
        elif m := _DECL.fullmatch(line):
            typ = m.group(2).lower()
            if typ not in PREDEFINED_TYPES:
                raise RapidError(f"line {no}: unknown data type {m.group(2)}")
            data[m.group(3).upper()] = (m.group(1).upper(), typ, m.group(4).strip())
        else:
            raise RapidError(f"line {no}: cannot load {raw.strip()!r}")
    if name is None:
        raise RapidError("no MODULE line")
    if cur is not None:
        raise RapidError(f"PROC {cur} has no ENDPROC")
    return Module(name, data, procs)


class Program:
    """The loaded modules of a task, flattened from main into executable steps."""

    def __init__(self, modules: list[Module], dof: int):
        self.modules = modules
        self.dof = dof
        self.data: dict[str, tuple[str, str, str]] = {}
        self.procs: dict[str, tuple[str, list[tuple[int, str]]]] = {}
        for mod in modules:
            for k, v in mod.data.items():
                self.data[k] = v
            for k, body in mod.procs.items():
                if k in self.procs:
                    raise RapidError(f"ambiguous PROC {k}: in modules {self.procs[k][0]} and "
                                     f"{mod.name}")
                self.procs[k] = (mod.name, body)

    def steps(self, entry: str = "MAIN") -> list[Step]:
        """The instructions from routine `entry` (main unless the PP was set to another)."""
        entry = entry.upper()
        if entry not in self.procs:
            raise RapidError("no PROC main() in the loaded modules" if entry == "MAIN"
                             else f"no PROC {entry.lower()}() in the loaded modules")
        out: list[Step] = []
        self._flatten(entry, out, ())
        return out

    def _flatten(self, proc: str, out: list[Step], stack: tuple[str, ...]) -> None:
        if proc in stack:
            raise RapidError(f"PROC {proc} calls itself")
        mod, body = self.procs[proc]
        for no, line in body:
            where = f"{mod}:{no}"
            try:
                step = self._step(line, where)
            except (KeyError, IndexError, ValueError) as exc:
                raise RapidError(f"{where}: {line!r}: {exc}") from None
            if step is not None:
                out.append(step)
            elif (m := re.fullmatch(r"(\w+)\s*;", line)) and m.group(1).upper() in self.procs:
                self._flatten(m.group(1).upper(), out, stack + (proc,))
            else:
                raise RapidError(f"{where}: cannot execute {line!r}")

    def _value(self, name: str, typ: str) -> str:
        key = name.strip().upper()
        if key not in self.data:
            raise KeyError(f"{name.strip()} is not declared")
        storage, t, val = self.data[key]
        if t != typ:
            raise ValueError(f"{name.strip()} is a {t}, not a {typ}")
        return val

    def _step(self, line: str, where: str) -> Step | None:
        if m := _MOVE.fullmatch(line):
            kind = m.group(1).upper()
            args = [a.strip() for a in m.group(2).split(",")]
            npos = 2 if kind == "MOVEC" else 1
            names = [a.split("\\")[0] for a in args[:npos]]
            speed, tool_arg = args[npos], args[npos + 2]
            tool_name, _, wobj_name = tool_arg.partition("\\")
            wobj_name = wobj_name.split(":=")[-1] if wobj_name else "wobj0"
            kw = {"speed_mm_s": self._speed(speed), "tool": self.frame(tool_name, "tooldata"),
                  "wobj": self.frame(wobj_name, "wobjdata")}
            if kind == "MOVEABSJ":
                v = _nums(self._value(names[0], "jointtarget"))
                return Step(kind, line, where, q=np.radians(v[:self.dof]), **kw)
            tgts = [self._robtarget(n) for n in names]
            return Step(kind, line, where, target=tgts[-1],
                        via=tgts[0] if kind == "MOVEC" else None, **kw)
        if m := re.fullmatch(r"SetDO\s+(\w+)\s*,\s*(\d)\s*;", line, re.IGNORECASE):
            return Step("SETDO", line, where, signal=m.group(1), value=float(m.group(2)))
        if m := re.fullmatch(rf"WaitTime\s+({_NUM})\s*;", line, re.IGNORECASE):
            return Step("WAIT", line, where, value=float(m.group(1)))
        return None

    def _speed(self, name: str) -> float:
        key = name.upper()
        if m := re.fullmatch(r"V(\d+)", key):
            return float(m.group(1))
        if key == "VMAX":
            return 7000.0
        return _nums(self._value(name, "speeddata"))[0]

    def frame(self, name: str, typ: str) -> Array:
        """A declared tooldata (flange -> TCP) or wobjdata (base -> object frame)."""
        if name.strip().upper() in ("TOOL0", "WOBJ0"):
            return np.eye(4)
        v = _nums(self._value(name, typ))
        if typ == "tooldata":  # [robhold, [[x,y,z],[q]], load]: booleans carry no number
            return pose_from(v[0:3], v[3:7])
        # wobjdata [robhold, ufprog, ufmec, [uframe], [oframe]]: uframe x oframe
        return pose_from(v[0:3], v[3:7]) @ pose_from(v[7:10], v[10:14])

    def _robtarget(self, name: str) -> RobTarget:
        v = _nums(self._value(name, "robtarget"))
        if len(v) < 11:
            raise ValueError(f"robtarget {name} is incomplete")
        return RobTarget(pose_from(v[0:3], v[3:7]), tuple(int(c) for c in v[7:11]))
