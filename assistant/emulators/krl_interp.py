"""A KRL interpreter for the emulated KUKA controller: enough of the language to run the KUKA
bridge's actuator program (`assistant/links/kuka_bridge/cellbridge.src`) as a KR C4 would.

What it reads (KSS 8 syntax, keywords case-insensitive): ``DEF``/``END``, ``DEFDAT`` data,
``DECL`` of INT, REAL, BOOL, CHAR arrays, E6POS, POS, FRAME, E6AXIS, AXIS, STATE_T, MODUS_T;
assignments (also to members and ``$`` system variables); ``IF/ELSE/ENDIF``,
``LOOP/ENDLOOP``, ``WHILE/ENDWHILE``, ``SWITCH/CASE/DEFAULT/ENDSWITCH``, ``WAIT SEC``;
``PTP``, ``LIN``, ``CIRC``; ``BAS`` (ignored); expressions with ``+ - * /``, comparisons,
``AND OR NOT B_AND B_OR``, aggregates ``{X 1, ...}``, the geometric operator ``:`` and the
functions ``INVERSE``; ``CWRITE($FCT_CALL, ...)`` with ``krl_fopen``, ``krl_fgets``,
``krl_fputs``, ``krl_fclose`` (KUKA's CREAD/CWRITE file functions, as source 002 uses them);
``SREAD``/``SWRITE`` with ``%d %f %s``. Anything else is a `KrlError` naming the line - the
program is refused before it runs, as the controller refuses to select a program it cannot
link. Units as in KRL: mm and degrees. The robot itself (motions, $POS_ACT, INVERSE) is the
`Machine` the interpreter is given.
"""

from __future__ import annotations

import math
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

_TOKEN = re.compile(r"""\s*(?:
    (?P<num>\d+\.\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?|\d+(?:[eE][-+]?\d+)?)
  | (?P<str>"[^"]*")
  | (?P<enum>\#[A-Za-z_]\w*)
  | (?P<name>\$?[A-Za-z_]\w*)
  | (?P<op><>|==|<=|>=|[-+*/:<>=(){}\[\],.])
)""", re.VERBOSE)
STRUCTS = {"E6POS": ("X", "Y", "Z", "A", "B", "C", "S", "T"),
           "POS": ("X", "Y", "Z", "A", "B", "C", "S", "T"),
           "FRAME": ("X", "Y", "Z", "A", "B", "C"),
           "E6AXIS": ("A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6"),
           "AXIS": ("A1", "A2", "A3", "A4", "A5", "A6"),
           "STATE_T": ("RET1", "HITS", "LENGTH", "MSG_NO"), "MODUS_T": ()}
SCALARS = {"INT": 0, "REAL": 0.0, "BOOL": False}


class KrlError(ValueError):
    """A statement the interpreter cannot read or execute; names the line."""


class KrlHalt(Exception):
    """The program stops here (a motion error, or the controller was stopped)."""


class Machine(Protocol):
    def sysvar(self, name: str) -> Any: ...
    def set_sysvar(self, name: str, value: Any) -> None: ...
    def motion(self, kind: str, targets: list[dict], line: int) -> None: ...
    def inverse(self, pos: dict, start: dict) -> tuple[dict, int]: ...
    def file_call(self, fn: str, args: list, out: Callable[[int, Any], None]) -> str: ...
    def wait(self, seconds: float) -> None: ...


@dataclass
class Stmt:
    kind: str
    line: int
    text: str
    body: list = field(default_factory=list)
    alt: list = field(default_factory=list)
    cases: list = field(default_factory=list)  # SWITCH: [(values | None, body)]


def tokens(text: str, line: int) -> list[tuple[str, str]]:
    out, i = [], 0
    text = text.rstrip()
    while i < len(text):
        m = _TOKEN.match(text, i)
        if not m or m.end() == i:
            raise KrlError(f"line {line}: cannot read {text[i:i + 20]!r}")
        kind = m.lastgroup
        assert kind is not None
        out.append((kind, m.group(kind)))
        i = m.end()
    return out


def _lines(text: str) -> list[tuple[int, str]]:
    out = []
    for no, raw in enumerate(text.replace("\r\n", "\n").split("\n"), start=1):
        line = raw.split(";", 1)[0].strip()
        if line and not line.startswith("&"):
            out.append((no, line))
    return out


def parse_program(src: str) -> tuple[str, list[Stmt]]:
    """(module name, statements) of a .src holding one ``DEF name( ) ... END``."""
    lines = _lines(src)
    if not lines or not re.match(r"(?i)(GLOBAL\s+)?DEF\s+\w+\s*\(\s*\)$", lines[0][1]):
        raise KrlError("the module does not start with DEF name( )")
    name = re.match(r"(?i)(?:GLOBAL\s+)?DEF\s+(\w+)", lines[0][1]).group(1)
    body, k = _block(lines, 1, ("END",))
    if k >= len(lines) or lines[k][1].upper() != "END":
        raise KrlError(f"DEF {name} has no END")
    return name, body


def _block(lines: list[tuple[int, str]], k: int, ends: tuple[str, ...]) -> tuple[list, int]:
    out: list[Stmt] = []
    while k < len(lines):
        no, text = lines[k]
        word = text.split()[0].upper().rstrip("(")
        if word in ends or text.upper() in ends:
            return out, k
        if word == "IF":
            if not text.upper().endswith("THEN"):
                raise KrlError(f"line {no}: IF without THEN")
            st = Stmt("IF", no, text[2:-4].strip())
            st.body, k = _block(lines, k + 1, ("ELSE", "ENDIF"))
            if k < len(lines) and lines[k][1].upper() == "ELSE":
                st.alt, k = _block(lines, k + 1, ("ENDIF",))
            _expect(lines, k, "ENDIF", no)
        elif word in ("LOOP", "WHILE"):
            st = Stmt(word, no, text[len(word):].strip())
            st.body, k = _block(lines, k + 1, (f"END{word}",))
            _expect(lines, k, f"END{word}", no)
        elif word == "SWITCH":
            st = Stmt("SWITCH", no, text[6:].strip())
            k += 1
            while k < len(lines) and lines[k][1].upper() != "ENDSWITCH":
                head = lines[k][1]
                if head.upper().startswith("CASE "):
                    values = head[5:]
                elif head.upper() == "DEFAULT":
                    values = None
                else:
                    raise KrlError(f"line {lines[k][0]}: CASE or DEFAULT expected")
                body, k = _block(lines, k + 1, ("CASE", "DEFAULT", "ENDSWITCH"))
                st.cases.append((values, body))
            _expect(lines, k, "ENDSWITCH", no)
        else:
            st = Stmt("SIMPLE", no, text)
        out.append(st)
        k += 1
    return out, k


def _expect(lines: list[tuple[int, str]], k: int, word: str, start: int) -> None:
    if k >= len(lines) or lines[k][1].upper() != word:
        raise KrlError(f"line {start}: no {word} for this block")


def parse_dat(text: str) -> list[tuple[int, str]]:
    """The DECL lines of a .dat (DEFDAT ... ENDDAT)."""
    return [(no, ln) for no, ln in _lines(text) if ln.upper().startswith("DECL")]


class Expr:
    """A recursive-descent reader of one KRL expression from tokens."""

    def __init__(self, toks: list[tuple[str, str]], interp: Interpreter, line: int):
        self.t, self.i, self.ip, self.line = toks, 0, interp, line

    def peek(self, k: int = 0) -> tuple[str, str]:
        return self.t[self.i + k] if self.i + k < len(self.t) else ("end", "")

    def take(self, value: str | None = None) -> tuple[str, str]:
        tok = self.peek()
        if value is not None and tok[1].upper() != value:
            raise KrlError(f"line {self.line}: expected {value!r}, got {tok[1]!r}")
        self.i += 1
        return tok

    def word(self) -> str:
        return self.peek()[1].upper()

    def parse(self) -> Any:
        v = self.or_()
        return v

    def or_(self) -> Any:
        v = self.and_()
        while self.word() in ("OR", "EXOR", "B_OR"):
            op = self.take()[1].upper()
            w = self.and_()
            v = (bool(v) or bool(w)) if op == "OR" else (bool(v) != bool(w)) if op == "EXOR" \
                else int(v) | int(w)
        return v

    def and_(self) -> Any:
        v = self.not_()
        while self.word() in ("AND", "B_AND"):
            op = self.take()[1].upper()
            w = self.not_()
            v = (bool(v) and bool(w)) if op == "AND" else int(v) & int(w)
        return v

    def not_(self) -> Any:
        if self.word() == "NOT":
            self.take()
            return not self.not_()
        return self.cmp()

    def cmp(self) -> Any:
        v = self.add()
        ops = {"==": lambda a, b: a == b, "<>": lambda a, b: a != b, "<": lambda a, b: a < b,
               ">": lambda a, b: a > b, "<=": lambda a, b: a <= b, ">=": lambda a, b: a >= b}
        while self.peek()[1] in ops:
            op = self.take()[1]
            v = ops[op](v, self.add())
        return v

    def add(self) -> Any:
        v = self.mul()
        while self.peek()[1] in ("+", "-"):
            op = self.take()[1]
            w = self.mul()
            v = v + w if op == "+" else v - w
        return v

    def mul(self) -> Any:
        v = self.geo()
        while self.peek()[1] in ("*", "/"):
            op = self.take()[1]
            w = self.geo()
            v = v * w if op == "*" else v / w
        return v

    def geo(self) -> Any:
        v = self.unary()
        while self.peek()[1] == ":":
            self.take()
            v = self.ip.machine.compose(v, self.unary())  # type: ignore[attr-defined]
        return v

    def unary(self) -> Any:
        if self.peek()[1] == "-":
            self.take()
            return -self.unary()
        if self.peek()[1] == "+":
            self.take()
        return self.primary()

    def primary(self) -> Any:
        kind, val = self.take()
        if kind == "num":
            return float(val) if re.search(r"[.eE]", val) else int(val)
        if kind == "str":
            return val[1:-1]
        if kind == "enum":
            return val.upper()
        if val == "(":
            v = self.parse()
            self.take(")")
            return v
        if val == "{":
            return self.aggregate()
        if kind != "name":
            raise KrlError(f"line {self.line}: unexpected {val!r}")
        up = val.upper()
        if up in ("TRUE", "FALSE"):
            return up == "TRUE"
        if up == "INVERSE":
            self.take("(")
            pos = self.parse()
            self.take(",")
            start = self.parse()
            self.take(",")
            target = self.ref()
            self.take(")")
            axes, err = self.ip.machine.inverse(pos, start)
            self.ip.store(target, err, self.line)
            return axes
        v = self.ip.load(up, self.line)
        while self.peek()[1] in (".", "["):
            if self.take()[1] == ".":
                v = v[self.take()[1].upper()]
            elif self.peek()[1] == "]":
                self.take()
            else:
                idx = int(self.parse())
                self.take("]")
                v = v[idx - 1] if isinstance(v, list) else v
        return v

    def ref(self) -> tuple:
        """A variable reference (name, member | index ...) for OUT arguments."""
        kind, val = self.take()
        if kind != "name":
            raise KrlError(f"line {self.line}: a variable is needed, got {val!r}")
        path: list = [val.upper()]
        while self.peek()[1] in (".", "["):
            if self.take()[1] == ".":
                path.append(self.take()[1].upper())
            elif self.peek()[1] == "]":
                self.take()
            else:
                path.append(int(self.parse()) - 1)
                self.take("]")
        return tuple(path)

    def aggregate(self) -> dict:
        out: dict = {}
        while self.peek()[1] != "}":
            key = self.take()[1].upper()
            out[key] = self.parse()
            if self.peek()[1] == ",":
                self.take()
        self.take("}")
        return out


class Interpreter:
    """Runs one parsed DEF against a `Machine`; `stop()` ends it at the next statement."""

    def __init__(self, src: str, dat: str, machine: Machine):
        self.machine = machine
        self.name, self.body = parse_program(src)
        self.vars: dict[str, Any] = {}
        self.types: dict[str, str] = {}
        for no, ln in parse_dat(dat):
            self._decl(ln, no)
        self._stop = threading.Event()
        self.line = 0
        self._check(self.body)

    def _check(self, body: list[Stmt]) -> None:
        """Declarations are read now (a program with a bad one is refused before it runs)."""
        for st in body:
            if st.kind == "SIMPLE" and st.text.upper().startswith("DECL"):
                self._decl(st.text, st.line)
            self._check(st.body)
            self._check(st.alt)
            for _, b in st.cases:
                self._check(b)

    def _decl(self, text: str, line: int) -> None:
        m = re.match(r"(?i)DECL\s+(?:GLOBAL\s+)?(\w+)\s+(.*)$", text)
        if not m:
            raise KrlError(f"line {line}: cannot read {text!r}")
        typ, rest = m.group(1).upper(), m.group(2)
        init = None
        if "=" in rest:
            rest, init = rest.split("=", 1)
        for item in rest.split(","):
            item = item.strip()
            am = re.fullmatch(r"(\w+)\s*\[\s*(\d+)\s*\]", item)
            name = (am.group(1) if am else item).upper()
            if not re.fullmatch(r"[A-Z_]\w*", name):
                raise KrlError(f"line {line}: {item!r} is not a name")
            if typ == "CHAR" and am:
                value: Any = ""
            elif typ in SCALARS:
                value = SCALARS[typ]
            elif typ in STRUCTS:
                value = {k: 0.0 for k in STRUCTS[typ]}
            else:
                raise KrlError(f"line {line}: unknown type {typ}")
            self.types[name] = typ
            self.vars[name] = value
            if init is not None:
                self.vars[name] = self.eval(init, line)

    # ------------------------------------------------------------------ values
    def load(self, name: str, line: int) -> Any:
        if name.startswith("$"):
            return self.machine.sysvar(name)
        if name not in self.vars:
            raise KrlError(f"line {line}: {name} is not declared")
        return self.vars[name]

    def store(self, path: tuple, value: Any, line: int) -> None:
        name = path[0]
        if name.startswith("$"):
            if len(path) == 1:
                self.machine.set_sysvar(name, value)
                return
            whole = dict(self.machine.sysvar(name))
            whole[path[1]] = value
            self.machine.set_sysvar(name, whole)
            return
        if name not in self.vars:
            raise KrlError(f"line {line}: {name} is not declared")
        if len(path) == 1:
            typ = self.types.get(name)
            if isinstance(value, dict) and isinstance(self.vars[name], dict):
                merged = dict(self.vars[name])
                merged.update({k: v for k, v in value.items()
                               if typ not in STRUCTS or k in STRUCTS[typ]})
                value = merged
            elif typ == "INT":
                value = int(value)
            elif typ == "REAL":
                value = float(value)
            self.vars[name] = value
            return
        target = self.vars[name]
        for key in path[1:-1]:
            target = target[key]
        target[path[-1]] = value

    def eval(self, text: str, line: int) -> Any:
        e = Expr(tokens(text, line), self, line)
        v = e.parse()
        if e.i != len(e.t):
            raise KrlError(f"line {line}: cannot read {text!r}")
        return v

    # ------------------------------------------------------------------ execution
    def stop(self) -> None:
        self._stop.set()

    def run(self) -> None:
        self._run(self.body)

    def _run(self, body: list[Stmt]) -> None:
        for st in body:
            if self._stop.is_set():
                raise KrlHalt("stopped")
            self.line = st.line
            if st.kind == "IF":
                self._run(st.body if self.eval(st.text, st.line) else st.alt)
            elif st.kind == "LOOP":
                while True:
                    self._run(st.body)
                    if self._stop.is_set():
                        raise KrlHalt("stopped")
            elif st.kind == "WHILE":
                while self.eval(st.text, st.line):
                    self._run(st.body)
            elif st.kind == "SWITCH":
                v = self.eval(st.text, st.line)
                for values, case in st.cases:
                    if values is None or v in self._case_values(values, st.line):
                        self._run(case)
                        break
            else:
                self._simple(st.text, st.line)

    def _case_values(self, text: str, line: int) -> list:
        return [self.eval(p, line) for p in text.split(",")]

    def _simple(self, text: str, line: int) -> None:
        up = text.upper()
        word = re.match(r"[\w$]+", up)
        head = word.group(0) if word else ""
        if head == "DECL":
            return  # read before the run
        if head == "BAS":
            return
        if head == "WAIT":
            m = re.fullmatch(r"(?i)WAIT\s+SEC\s+(.+)", text)
            if not m:
                raise KrlError(f"line {line}: only WAIT SEC is emulated")
            self.machine.wait(float(self.eval(m.group(1), line)))
            return
        if head in ("PTP", "LIN", "CIRC", "SPTP", "SLIN"):
            args = self._args(text[len(head):], line, bare=True)
            kind = {"SPTP": "PTP", "SLIN": "LIN"}.get(head, head)
            self.machine.motion(kind, args, line)
            return
        if head == "CWRITE":
            self._cwrite(text, line)
            return
        if head in ("SREAD", "SWRITE"):
            self._sread_swrite(head, text, line)
            return
        if "=" in text:
            left, right = text.split("=", 1)
            e = Expr(tokens(left, line), self, line)
            path = e.ref()
            if e.i != len(e.t):
                raise KrlError(f"line {line}: cannot assign to {left.strip()!r}")
            self.store(path, self.eval(right, line), line)
            return
        raise KrlError(f"line {line}: cannot execute {text!r}")

    def _args(self, text: str, line: int, bare: bool = False) -> list:
        text = text.strip()
        if not bare:
            if not (text.startswith("(") and text.endswith(")")):
                raise KrlError(f"line {line}: arguments in ( ) expected")
            text = text[1:-1]
        e = Expr(tokens(text, line), self, line)
        out = []
        while e.i < len(e.t):
            if e.peek()[0] == "name" and e.word() in ("C_PTP", "C_DIS", "C_VEL", "C_ORI"):
                e.take()
                continue
            out.append(e.parse())
            if e.peek()[1] == ",":
                e.take()
        return out

    def _split(self, text: str, line: int) -> list[list[tuple[str, str]]]:
        toks = tokens(text.strip()[1:-1], line)
        parts, depth, cur = [], 0, []
        for tok in toks:
            if tok[1] in "([{" and tok[0] == "op":
                depth += 1
            elif tok[1] in ")]}" and tok[0] == "op":
                depth -= 1
            if tok == ("op", ",") and depth == 0:
                parts.append(cur)
                cur = []
            else:
                cur.append(tok)
        parts.append(cur)
        return parts

    def _cwrite(self, text: str, line: int) -> None:
        parts = self._split(text[6:], line)
        if len(parts) < 4 or parts[0][0][1].upper() != "$FCT_CALL":
            raise KrlError(f"line {line}: only CWRITE($FCT_CALL, ...) is emulated")
        state = Expr(parts[1], self, line).ref()
        fn = str(Expr(parts[3], self, line).parse())
        vals, refs = [], []
        for p in parts[4:]:
            e = Expr(p, self, line)
            if p and p[0][0] == "name" and not p[0][1].startswith("$"):
                refs.append(Expr(p, self, line).ref())
            else:
                refs.append(None)
            vals.append(e.parse())

        def out(k: int, value: Any) -> None:
            if refs[k] is None:
                raise KrlError(f"line {line}: argument {k + 5} of {fn} must be a variable")
            self.store(refs[k], value, line)

        ret = self.machine.file_call(fn, vals, out)
        self.store(state + ("RET1",), ret, line)

    def _sread_swrite(self, head: str, text: str, line: int) -> None:
        parts = self._split(text[len(head):], line)
        if len(parts) < 4:
            raise KrlError(f"line {line}: {head}(string[], state, offset, format, ...)")
        buf_ref = Expr(parts[0], self, line).ref()
        state = Expr(parts[1], self, line).ref()
        off_ref = Expr(parts[2], self, line).ref()
        fmt = str(Expr(parts[3], self, line).parse())
        codes = re.findall(r"%([dfs])", fmt)
        if head == "SWRITE":
            vals = [Expr(p, self, line).parse() for p in parts[4:]]
            if len(vals) != len(codes):
                raise KrlError(f"line {line}: {len(codes)} formats, {len(vals)} values")
            text_out = re.sub(r"%([dfs])", lambda m: "{}", fmt).format(
                *[int(v) if c == "d" else f"{float(v):.6f}" if c == "f" else str(v)
                  for c, v in zip(codes, vals, strict=True)])
            self.store(buf_ref, text_out, line)
            self.store(off_ref, len(text_out), line)
            self.store(state + ("RET1",), "#CMD_OK", line)
            return
        source = str(self.load(buf_ref[0], line)).split()
        ok = len(source) >= len(codes)
        for k, (c, p) in enumerate(zip(codes, parts[4:], strict=False)):
            ref = Expr(p, self, line).ref()
            if k >= len(source):
                break
            try:
                v: Any = int(float(source[k])) if c == "d" else float(source[k]) if c == "f" \
                    else source[k]
            except ValueError:
                ok = False
                break
            self.store(ref, v, line)
        self.store(state + ("RET1",), "#CMD_OK" if ok else "#DATA_END", line)


def frame_T(f: dict) -> Any:
    """A KRL frame/position (mm, deg; A about z, B about y, C about x) as a 4x4 (m)."""
    import numpy as np

    a, b, c = (math.radians(float(f.get(k, 0.0))) for k in "ABC")
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), \
        math.cos(c), math.sin(c)
    T = np.eye(4)
    T[:3, :3] = [[ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
                 [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
                 [-sb, cb * sc, cb * cc]]
    T[:3, 3] = [float(f.get(k, 0.0)) / 1000.0 for k in "XYZ"]
    return T


def T_frame(T: Any) -> dict:
    b = math.atan2(-T[2, 0], math.hypot(T[0, 0], T[1, 0]))
    a = math.atan2(T[1, 0], T[0, 0])
    c = math.atan2(T[2, 1], T[2, 2])
    return {"X": T[0, 3] * 1000.0, "Y": T[1, 3] * 1000.0, "Z": T[2, 3] * 1000.0,
            "A": math.degrees(a), "B": math.degrees(b), "C": math.degrees(c)}
