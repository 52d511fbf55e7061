"""FANUC TP (.LS): what `fanuc.lark` cannot say, checked on its parse trees.

From the R-30iA/R-30iB operator's manuals and the .LS files controllers write: /PROG names
the program as its file (a letter, then letters, digits, _; at most 36 characters on
R-30iB, 8 on older controllers - the stricter limit is the writer's business); /ATTR's
LINE_COUNT is the number of /MN lines, numbered 1, 2, ... without gaps; comments hold at
most 32 characters, position comments 16; every P[n] a motion uses is in /POS once, with
the same comment; a joint motion's speed is in %, sec or msec (1..100 %), a linear or
circular one's in mm/sec (1..2000), cm/min, inch/min, deg/sec, sec or msec; CNT is 0..100,
ACC 0..150; a circular motion names two points; digital outputs are numbered from 1; a
Cartesian position has X, Y, Z, W, P, R (W, P, R within +-180 deg) and a CONFIG 'F|N [L|R]
U|D T|B, t, t, t', a joint position J1..Jn and no CONFIG; a position's UF is the user frame
selected (UFRAME_NUM) when the motion runs; a called program is among the files.
"""

from __future__ import annotations

import re
from pathlib import PurePath

from lark import Token, Tree

from grammars._base import Report, check_lines, line_of, normalise, parse

MAX_PROGRAM = 36
MAX_COMMENT = 32
MAX_POSITION_COMMENT = 16
JOINT_UNITS = {"%", "sec", "msec"}
PATH_UNITS = {"mm/sec", "cm/min", "inch/min", "deg/sec", "sec", "msec"}
CONFIG = re.compile(r"[NF]( [LR])? [UD] [TB], -?\d+, -?\d+, -?\d+")
CARTESIAN = ("X", "Y", "Z", "W", "P", "R")


def check(files: dict[str, str]) -> Report:
    rep = Report()
    programs = {PurePath(n).stem.upper(): n for n in files if n.upper().endswith(".LS")}
    if not programs:
        rep.add("(files)", None, "no FANUC TP program (.LS) among " + ", ".join(files))
    for n in files:
        if not n.upper().endswith(".LS"):
            rep.add(n, None, "not a FANUC TP program (.LS)")
    for stem, n in programs.items():
        text = normalise(files[n])
        check_lines(rep, n, text, None)
        tree = parse("fanuc", "ls", n, text, rep)
        if tree is not None:
            _check_program(stem, n, tree, set(programs), rep)
    return rep


def _check_program(stem: str, fname: str, tree: Tree, programs: set[str], rep: Report) -> None:
    prog = next(tree.find_data("prog"))
    name = prog.children[0]
    if str(name).upper() != stem:
        rep.add(fname, name.line, f"/PROG {name} but the file is {stem}: the program is named "
                "as its file")
    if len(str(name)) > MAX_PROGRAM or not str(name)[0].isalpha():
        rep.add(fname, name.line, f"program name {name}: a letter first, at most "
                f"{MAX_PROGRAM} characters")
    lines = list(tree.find_data("mn_line"))
    for k, ln in enumerate(lines, start=1):
        if int(ln.children[0]) != k:
            rep.add(fname, line_of(ln), f"line number {ln.children[0]}, expected {k}")
    count = [a for a in tree.find_data("attr_value") if str(a.children[0]) == "LINE_COUNT"]
    if not count:
        rep.add(fname, line_of(prog), "/ATTR has no LINE_COUNT")
    else:
        got = [t for t in count[0].children[1:] if isinstance(t, Token)]
        if len(got) != 1 or int(got[0]) != len(lines):
            rep.add(fname, line_of(count[0]), f"LINE_COUNT = {' '.join(map(str, got))} but "
                    f"/MN has {len(lines)} lines")
    positions = _positions(fname, tree, rep)
    rep.positions += len(positions)
    uframe: int | None = None
    for ln in lines:
        ins = ln.children[1] if len(ln.children) > 1 else None
        if isinstance(ins, Token) and ins.type == "COMMENT":
            text = str(ins)[1:].rstrip()
            if len(text) > MAX_COMMENT:
                rep.add(fname, ins.line, f"a comment of {len(text)} characters; the "
                        f"controller takes {MAX_COMMENT}")
        elif isinstance(ins, Tree) and ins.data == "motion":
            rep.motions += 1
            _check_motion(fname, ins, positions, uframe, rep)
        elif isinstance(ins, Tree) and ins.data == "io_assign":
            ref = str(ins.children[0])
            if re.match(r"\w+\[0\b", ref):
                rep.add(fname, line_of(ins), f"{ref}: I/O are numbered from 1")
        elif isinstance(ins, Tree) and ins.data == "frame_select":
            which, value = str(ins.children[0]), ins.children[1]
            if which == "UFRAME_NUM" and isinstance(value, Token) and value.type == "INT":
                uframe = int(value)
        elif isinstance(ins, Tree) and ins.data in ("call", "run"):
            callee = str(ins.children[0]).upper()
            if callee not in programs:
                rep.add(fname, line_of(ins), f"{callee} is called but no {callee}.LS is here")
            if callee == stem:
                rep.add(fname, line_of(ins), f"{callee} calls itself")


def _check_motion(fname: str, m: Tree, positions: dict[int, dict], uframe: int | None,
                  rep: Report) -> None:
    kind = str(m.children[0])
    targets = [t for t in m.children if isinstance(t, Token) and t.type in ("POSREF", "PRREF")]
    line = m.children[0].line
    if (kind == "C") != (len(targets) == 2):
        rep.add(fname, line, f"{kind}: a circular motion names two points, the others one")
    for t in targets:
        if t.type != "POSREF":
            continue
        mm = re.fullmatch(r"P\[(\d+)(?::([^\]]*))?\]", str(t))
        assert mm
        n, comment = int(mm.group(1)), mm.group(2)
        where = positions.get(n)
        if where is None:
            rep.add(fname, t.line, f"P[{n}] is used but not in /POS")
            continue
        if comment is not None and where["name"] and comment != where["name"]:
            rep.add(fname, t.line, f"P[{n}:{comment}] but /POS calls it {where['name']!r}")
        if uframe is not None and where["uf"] != uframe:
            rep.add(fname, t.line, f"P[{n}] is taught in UF {where['uf']} but UFRAME_NUM is "
                    f"{uframe}")
    speed = next(m.find_data("speed")).children[0]
    mm = re.fullmatch(r"(?:R\[[^\]]*\]|([\d.]+))(.*)", str(speed))
    if mm and speed.type != "WELD_SPEED":
        value, unit = mm.group(1), mm.group(2)
        allowed = JOINT_UNITS if kind == "J" else PATH_UNITS
        if unit not in allowed:
            rep.add(fname, speed.line, f"{kind} with a speed in {unit}: it takes "
                    f"{', '.join(sorted(allowed))}")
        elif value is not None:
            v = float(value)
            if unit == "%" and not 1 <= v <= 100 or unit == "mm/sec" and not 1 <= v <= 2000:
                rep.add(fname, speed.line, f"speed {speed} outside "
                        f"{'1..100 %' if unit == '%' else '1..2000 mm/sec'}")
    term = next(m.find_data("term")).children[0]
    if term.type == "CNT" and (mm := re.fullmatch(r"CNT\s*(\d+)", str(term))) and \
            int(mm.group(1)) > 100:
        rep.add(fname, term.line, f"{term}: CNT is 0..100")
    for opt in m.find_data("option"):
        tok = opt.children[0]
        if tok.type == "ACC" and int(re.sub(r"\D", "", str(tok))) > 150:
            rep.add(fname, tok.line, f"{tok}: ACC is 0..150")


def _positions(fname: str, tree: Tree, rep: Report) -> dict[int, dict]:
    out: dict[int, dict] = {}
    for p in tree.find_data("position"):
        head = p.children[0]
        mm = re.fullmatch(r'P\[(\d+)(?::"([^"]*)")?\]', str(head))
        assert mm
        n, name = int(mm.group(1)), mm.group(2) or ""
        if n in out:
            rep.add(fname, head.line, f"P[{n}] is defined again")
            continue
        if len(name) > MAX_POSITION_COMMENT:
            rep.add(fname, head.line, f"position comment {name!r} has {len(name)} characters; "
                    f"the controller takes {MAX_POSITION_COMMENT}")
        groups = list(p.find_data("group"))
        if not groups or str(groups[0].children[0]) != "GP1":
            rep.add(fname, head.line, f"P[{n}] has no GP1 (the robot's group)")
            continue
        g = groups[0]
        ints = [t for t in g.children if isinstance(t, Token) and t.type == "INT"]
        uf, ut = int(ints[0]), int(ints[1])
        config = [c.children[0] for c in g.find_data("config")]
        values: dict[str, float] = {}
        for v in g.find_data("value"):
            axis, num, unit = (str(c) for c in v.children)
            if axis in values:
                rep.add(fname, line_of(v), f"P[{n}]: {axis} given twice")
            values[axis] = float(num)
            want = "mm" if axis in ("X", "Y", "Z") or axis.startswith("E") else "deg"
            if axis[0] in "XYZWPR" and unit != want:
                rep.add(fname, line_of(v), f"P[{n}]: {axis} is in {want}, not {unit}")
        joints = sorted(k for k in values if k.startswith("J"))
        cart = [k for k in values if k in CARTESIAN]
        target = {"number": n, "name": name, "uf": uf, "ut": ut, "line": head.line,
                  "file": fname}
        if cart:
            if joints:
                rep.add(fname, head.line, f"P[{n}] mixes X..R and joint values")
            if missing := [k for k in CARTESIAN if k not in values]:
                rep.add(fname, head.line, f"P[{n}] lacks {', '.join(missing)}")
            if not config:
                rep.add(fname, head.line, f"P[{n}]: a Cartesian position needs a CONFIG")
            elif not CONFIG.fullmatch(str(config[0]).strip("'")):
                rep.add(fname, config[0].line, f"P[{n}]: CONFIG {config[0]} is not "
                        "'F|N [L|R] U|D T|B, turn, turn, turn'")
            for k in ("W", "P", "R"):
                if k in values and abs(values[k]) > 180.0:
                    rep.add(fname, head.line, f"P[{n}]: {k} {values[k]} outside -180..180 deg")
            target |= {"kind": "cartesian", "values": [values.get(k, 0.0) for k in CARTESIAN],
                       "config": str(config[0]).strip("'") if config else ""}
        else:
            if config:
                rep.add(fname, config[0].line, f"P[{n}]: joint values take no CONFIG")
            expect = [f"J{i}" for i in range(1, len(joints) + 1)]
            if joints != expect:
                rep.add(fname, head.line, f"P[{n}]: joints {', '.join(joints)}, expected "
                        f"{', '.join(expect)}")
            target |= {"kind": "joint", "values": [values[k] for k in joints]}
        out[n] = {"name": name, "uf": uf}
        rep.targets.append(target)
    return out
