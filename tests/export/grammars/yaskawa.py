"""Yaskawa INFORM (.JBI): what `yaskawa.lark` cannot say, checked on its parse trees.

From the NX100/DX100 job data format and the YRC1000 header fields: //NAME names the job as
its file (at most 32 characters on a YRC1000, 8 on an NX100); ///NPOS counts the teaching
positions (C, BC, EC) and position variables (P, BP, EX) that follow, each defined once,
after a ///POSTYPE and ///PULSE or ///RECTAN - Cartesian data after a ///RCONF, as X, Y, Z,
Rx, Ry, Rz (and Re for a 7-axis arm) with Rx..Rz within +-180 deg, pulse data as whole
numbers; ///COMM and comments hold at most 32 characters; every position a move uses is
defined; MOVJ takes VJ= (0.01..100.00 %), MOVL, MOVC and MOVS take V= (> 0) or VR=; PL= is
0..8, ACC= and DEC= 20..100; TIMER T= 0.01..655.35 s; outputs are numbered from 1; a
circular arc is three MOVC steps - consecutive arcs share their end point, marked FPT, so a
run of MOVC steps (other instructions between them do not end it, a MOVJ or MOVL does) has
1 + 2 per arc points; a called job is among the files. An arc counts as one motion.
"""

from __future__ import annotations

from pathlib import PurePath

from lark import Token, Tree

from grammars._base import Report, check_lines, line_of, normalise, parse

MAX_NAME = 32
MAX_COMMENT = 32
KINDS = ("C", "BC", "EC", "P", "BP", "EX")


def check(files: dict[str, str]) -> Report:
    rep = Report()
    jobs = {PurePath(n).stem.upper(): n for n in files if n.upper().endswith(".JBI")}
    if not jobs:
        rep.add("(files)", None, "no INFORM job (.JBI) among " + ", ".join(files))
    for n in files:
        if not n.upper().endswith(".JBI"):
            rep.add(n, None, "not an INFORM job (.JBI)")
    for stem, n in jobs.items():
        text = normalise(files[n])
        check_lines(rep, n, text, None)
        tree = parse("yaskawa", "jbi", n, text, rep)
        if tree is not None:
            _check_job(stem, n, tree, set(jobs), rep)
    return rep


def _check_job(stem: str, fname: str, tree: Tree, jobs: set[str], rep: Report) -> None:
    name = next(tree.find_data("name")).children[0]
    if str(name).upper() != stem:
        rep.add(fname, name.line, f"//NAME {name} but the file is {stem}: a job is named as "
                "its file")
    if len(str(name)) > MAX_NAME:
        rep.add(fname, name.line, f"job name {name} has {len(str(name))} characters; a "
                f"YRC1000 takes {MAX_NAME}")
    defined = _positions(fname, tree, rep)
    for c in tree.find_data("comm"):
        text = str(c.children[0])[len("///COMM"):].strip()
        if len(text) > MAX_COMMENT:
            rep.add(fname, line_of(c), f"///COMM of {len(text)} characters; the controller "
                    f"takes {MAX_COMMENT}")
    inst = next(tree.find_data("inst"))
    run: list[Tree] = []  # consecutive MOVC steps
    for stmt in inst.children:
        if isinstance(stmt, Token) and stmt.type == "COMMENT":
            text = str(stmt)[1:].rstrip()
            if len(text) > MAX_COMMENT:
                rep.add(fname, stmt.line, f"a comment of {len(text)} characters; the "
                        f"controller takes {MAX_COMMENT}")
            continue
        if not isinstance(stmt, Tree):
            continue
        if stmt.data == "move":
            word = str(stmt.children[0])
            _check_move(fname, stmt, defined, rep)
            if word == "MOVC":
                run.append(stmt)
                continue
            _close_run(fname, run, rep)
            run = []
            rep.motions += 1
        elif stmt.data == "dout":
            ref = str(stmt.children[0])
            if ref.endswith("(0)"):
                rep.add(fname, line_of(stmt), f"{ref}: outputs are numbered from 1")
        elif stmt.data == "timer":
            t = stmt.children[0]
            if not 0.01 <= float(t) <= 655.35:
                rep.add(fname, line_of(stmt), f"TIMER T={t}: 0.01..655.35 s")
        elif stmt.data == "call":
            callee = str(stmt.children[0]).upper()
            if callee not in jobs:
                rep.add(fname, line_of(stmt), f"{callee} is called but no {callee}.JBI is here")
            if callee == stem:
                rep.add(fname, line_of(stmt), f"{callee} calls itself")
    _close_run(fname, run, rep)


def _close_run(fname: str, run: list[Tree], rep: Report) -> None:
    """A run of MOVC steps: a start, then a via and an end per arc; arcs after the first
    start at an end marked FPT."""
    if not run:
        return
    fpt = [k for k, m in enumerate(run) if any(
        isinstance(t, Tree) and t.data == "flag" and str(t.children[0]) == "FPT"
        for t in m.children)]
    arcs = (len(run) - 1) // 2
    if len(run) < 3 or (len(run) - 1) % 2 or any(k % 2 or k == 0 for k in fpt) or \
            len([k for k in fpt if k < len(run) - 1]) != arcs - 1:
        rep.add(fname, line_of(run[0]), f"{len(run)} MOVC steps ({len(fpt)} FPT) are not "
                "whole arcs: three points each, consecutive arcs joined at an FPT end point")
        return
    rep.motions += arcs


def _check_move(fname: str, m: Tree, defined: set[str], rep: Report) -> None:
    word = str(m.children[0])
    line = m.children[0].line
    refs = [t for t in m.children if isinstance(t, Token) and t.type == "POSVAR"]
    if not refs:
        rep.add(fname, line, f"{word} without a position")
    for r in refs:
        if str(r) not in defined:
            rep.add(fname, r.line, f"{r} is used but not defined in //POS")
    raw = {str(t.children[0]): str(t.children[1]) for t in m.children
           if isinstance(t, Tree) and t.data == "valued"}
    tags = {k: float(v) for k, v in raw.items()}
    if word == "MOVJ":
        if "VJ=" not in tags:
            rep.add(fname, line, "MOVJ takes its speed as VJ= (%)")
        elif not 0.01 <= tags["VJ="] <= 100.0:
            rep.add(fname, line, f"VJ={raw['VJ=']}: 0.01..100.00 %")
    elif word in ("MOVL", "MOVC", "MOVS"):
        if "V=" not in tags and "VR=" not in tags:
            rep.add(fname, line, f"{word} takes its speed as V= (mm/s) or VR=")
        elif "V=" in tags and tags["V="] <= 0.0:
            rep.add(fname, line, f"V={raw['V=']}: a speed above 0")
        if "VJ=" in tags:
            rep.add(fname, line, f"{word} takes V=, not VJ=")
    if "PL=" in tags and (tags["PL="] != int(tags["PL="]) or not 0 <= tags["PL="] <= 8):
        rep.add(fname, line, f"PL={raw['PL=']}: a whole number 0..8")
    for key in ("ACC=", "DEC="):
        if key in tags and not 20 <= tags[key] <= 100:
            rep.add(fname, line, f"{key}{raw[key]}: 20..100 %")


def _positions(fname: str, tree: Tree, rep: Report) -> set[str]:
    pos = next(tree.find_data("pos"))
    npos = next(pos.find_data("npos"))
    declared = dict(zip(KINDS, (int(t) for t in npos.children), strict=True))
    counts = dict.fromkeys(KINDS, 0)
    defined: set[str] = set()
    postype = form = None
    tool = user = 0
    rconf: list[int] | None = None
    for item in pos.children[1:]:
        if not isinstance(item, Tree):
            continue
        if item.data == "tool":
            tool = int(item.children[0])
        elif item.data == "user":
            user = int(item.children[0])
        elif item.data == "postype":
            postype = str(item.children[0])
        elif item.data in ("pulse", "rectan"):
            form = item.data
        elif item.data == "rconf":
            rconf = [int(t) for t in item.children]
            if len(rconf) < 6:
                rep.add(fname, line_of(item), "///RCONF has six types (and unused zeros)")
        elif item.data == "posdata":
            var = item.children[0]
            vals = [float(t) for t in item.children[1:]]
            kind = str(var).rstrip("0123456789")
            if str(var) in defined:
                rep.add(fname, var.line, f"{var} is defined again")
            defined.add(str(var))
            counts[kind] += 1
            if postype is None or form is None:
                rep.add(fname, var.line, f"{var} before ///POSTYPE and ///PULSE or ///RECTAN")
                continue
            target = {"file": fname, "name": str(var), "line": var.line, "postype": postype,
                      "tool": tool, "user": user, "values": vals}
            if form == "pulse":
                if any(v != int(v) for v in vals):
                    rep.add(fname, var.line, f"{var}: pulse data are whole numbers")
                target["kind"] = "pulse"
            else:
                if rconf is None and kind in ("C", "P"):
                    rep.add(fname, var.line, f"{var}: Cartesian data after a ///RCONF")
                if kind in ("C", "P") and len(vals) not in (6, 7):
                    rep.add(fname, var.line, f"{var}: X, Y, Z, Rx, Ry, Rz (and Re), not "
                            f"{len(vals)} values")
                if kind in ("C", "P") and any(abs(v) > 180.0 for v in vals[3:6]):
                    rep.add(fname, var.line, f"{var}: Rx, Ry, Rz within -180..180 deg")
                target |= {"kind": "cartesian", "rconf": list(rconf or [])}
            if kind == "C":
                rep.targets.append(target)
    for kind in KINDS:
        if counts[kind] != declared[kind]:
            rep.add(fname, line_of(npos), f"///NPOS says {declared[kind]} {kind} positions, "
                    f"{counts[kind]} follow")
    rep.positions += counts["C"] + counts["P"]
    return defined
