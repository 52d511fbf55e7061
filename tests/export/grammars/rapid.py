"""ABB RAPID: what `rapid.lark` cannot say, checked on its parse trees.

From the RAPID reference manuals: a name is a letter, then letters, digits, "_", at most 32
characters and no reserved word; data are declared once per task (a LOCAL one once per
module) and declared data is what a routine refers to; MoveJ/MoveL/MoveC go to robtargets,
MoveAbsJ to jointtargets; speed, zone, tool and work object are speeddata (v5..v7000, vmax),
zonedata (fine, z0..z200), tooldata (tool0) and wobjdata (wobj0) - predefined or declared.
Aggregates have the documented shapes: robtarget [[x,y,z],[q1..q4],[cf1,cf4,cf6,cfx],
[eax_a..eax_f]], jointtarget [[rax_1..6],[eax_a..f]], tooldata [robhold,[[x,y,z],[q]],
[mass,[cog],[aom],ix,iy,iz]], wobjdata [robhold,ufprog,ufmec,[uframe],[oframe]], speeddata
4 numbers, zonedata [finep, 6 numbers]. Orientations are unit quaternions; a tool's load
mass is positive. One PROC main is the entry. An exponent (9E+09) belongs only in the
external-axis slots, where the manual writes 9E9 for "no axis".
"""

from __future__ import annotations

import math

from lark import Token, Tree

from grammars._base import EXPONENT, Report, check_lines, line_of, normalise, parse

MAX_NAME = 32
RESERVED = frozenset({
    "ALIAS", "AND", "BACKWARD", "CASE", "CONNECT", "CONST", "DEFAULT", "DIV", "DO", "ELSE",
    "ELSEIF", "ENDFOR", "ENDFUNC", "ENDIF", "ENDMODULE", "ENDPROC", "ENDRECORD", "ENDTEST",
    "ENDTRAP", "ENDWHILE", "ERROR", "EXIT", "FALSE", "FOR", "FROM", "FUNC", "GOTO", "IF", "INOUT",
    "LOCAL", "MOD", "MODULE", "NOSTEPIN", "NOT", "NOVIEW", "OR", "PERS", "PROC", "RAISE",
    "READONLY", "RECORD", "RETRY", "RETURN", "STEP", "SYSMODULE", "TEST", "THEN", "TO", "TRAP",
    "TRUE", "TRYNEXT", "UNDO", "VAR", "VIEWONLY", "WHILE", "WITH", "XOR"
})
SPEEDS = {f"V{v}" for v in (5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 300, 400, 500,
                            600, 800, 1000, 1500, 2000, 2500, 3000, 4000, 5000, 6000, 7000)}
SPEEDS |= {"VMAX"}
ZONES = {"FINE"} | {f"Z{z}" for z in (0, 1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200)}
PREDEFINED = {"speeddata": SPEEDS, "zonedata": ZONES, "tooldata": {"TOOL0"},
              "wobjdata": {"WOBJ0"}, "loaddata": {"LOAD0"}}
#: Shapes: an int is that many numbers, "b" a bool, "s" a string, a list nests.
SHAPES = {
    "robtarget": [3, 4, 4, 6],
    "jointtarget": [6, 6],
    "tooldata": ["b", [3, 4], [1, 3, 4, 1, 1, 1]],
    "wobjdata": ["b", "b", "s", [3, 4], [3, 4]],
    "speeddata": 4,
    "zonedata": ["b", 1, 1, 1, 1, 1, 1],
    "pos": 3, "orient": 4, "confdata": 4,
}
#: Where a unit quaternion sits, as index paths into the aggregate.
QUATERNIONS = {"robtarget": [(1,)], "tooldata": [(1, 1), (2, 2)],
               "wobjdata": [(3, 1), (4, 1)]}
#: Where 9E9 ("no external axis") may stand.
EXTERNAL = {"robtarget": (3,), "jointtarget": (1,)}
MOTION_TYPES = {"movej": "robtarget", "movel": "robtarget", "movec": "robtarget",
                "moveabsj": "jointtarget"}


def check(files: dict[str, str]) -> Report:
    rep = Report()
    mods = [n for n in files if n.lower().endswith((".mod", ".modx", ".prg"))]
    if not mods:
        rep.add("(files)", None, "no RAPID module (.mod) among " + ", ".join(files))
        return rep
    for n in files:
        if n not in mods:
            rep.add(n, None, "not a RAPID module")
    trees: dict[str, Tree] = {}
    for n in mods:
        text = normalise(files[n])
        check_lines(rep, n, text, None)
        if (tree := parse("rapid", "module", n, text, rep)) is not None:
            trees[n] = tree
    data: dict[str, tuple[str, str, int | None, Tree, bool]] = {}
    procs: dict[str, tuple[str, int | None]] = {}
    modules: dict[str, str] = {}
    for n, tree in trees.items():
        mname = [t for t in tree.children if isinstance(t, Token) and t.type == "NAME"][0]
        _check_name(str(mname), n, mname.line, rep)
        if str(mname).upper() in modules:
            rep.add(n, mname.line, f"module {mname} is also in {modules[str(mname).upper()]}")
        modules[str(mname).upper()] = n
        _declarations(tree, n, data, rep)
        for r in tree.find_data("routine"):
            pname = [t for t in r.children if isinstance(t, Token) and t.type == "NAME"][0]
            _check_name(str(pname), n, pname.line, rep)
            if str(pname).upper() in procs or str(pname).upper() in data:
                rep.add(n, pname.line, f"{pname} is declared twice in the task")
            procs[str(pname).upper()] = (n, pname.line)
    if trees and "MAIN" not in procs:
        rep.add(next(iter(trees)), None, "no PROC main (the entry routine)")
    for n, tree in trees.items():
        _check_routines(tree, n, data, procs, rep)
    rep.positions = sum(1 for d in data.values() if d[0] in ("robtarget", "jointtarget"))
    return rep


def _declarations(tree: Tree, fname: str, data: dict, rep: Report) -> None:
    for d in tree.find_data("data_decl"):
        toks = [t for t in d.children if isinstance(t, Token)]
        typ, name = (str(t) for t in [t for t in toks if t.type == "NAME"][:2])
        line = line_of(d)
        _check_name(name, fname, line, rep)
        key = name.upper()
        if key in data:
            rep.add(fname, line, f"{name} is declared again (first in {data[key][1]} line "
                    f"{data[key][2]})")
            continue
        scoped = any(t.type == "SCOPE" for t in toks)
        value = d.children[-1] if len(d.children) == 5 - (not scoped) else None
        data[key] = (typ, fname, line, d, any(t.type == "SCOPE" and t.upper() == "LOCAL"
                                                 for t in toks))
        storage = [t for t in toks if t.type == "STORAGE"][0].upper()
        if storage == "CONST" and value is None:
            rep.add(fname, line, f"CONST {name} has no value")
        if typ in SHAPES and isinstance(value, Token) and value.type == "NAME":
            continue  # a copy of other data: its own declaration is checked
        if typ in SHAPES and value is not None and \
                _check_shape(name, typ, value, SHAPES[typ], fname, line, rep):
            _check_values(name, typ, value, fname, line, rep)


def _check_name(ident: str, fname: str, line: int | None, rep: Report) -> None:
    if len(ident) > MAX_NAME:
        rep.add(fname, line, f"{ident} is {len(ident)} characters; RAPID takes {MAX_NAME}")
    if ident.upper() in RESERVED:
        rep.add(fname, line, f"{ident} is a reserved word in RAPID")


def _items(node) -> list:
    return list(node.children) if isinstance(node, Tree) and node.data == "aggregate" else []


def _check_shape(name: str, typ: str, node, shape, fname: str, line, rep: Report) -> bool:
    if isinstance(shape, int):
        items = _items(node)
        ok = len(items) == shape and all(isinstance(i, Tree) and i.data == "number"
                                         for i in items)
        if shape == 1:
            ok = isinstance(node, Tree) and node.data == "number"
    elif shape == "b":
        ok = isinstance(node, Token) and node.type == "BOOL"
    elif shape == "s":
        ok = isinstance(node, Token) and node.type == "STRING"
    else:
        items = _items(node)
        ok = len(items) == len(shape) and all(
            _check_shape(name, typ, i, s, fname, line, None)
            for i, s in zip(items, shape, strict=True))
    if not ok and rep is not None:
        rep.add(fname, line, f"{name}: not a {typ} (documented shape {shape})")
    return ok


def _at(node, path: tuple[int, ...]):
    for k in path:
        node = _items(node)[k]
    return node


def _check_values(name: str, typ: str, value: Tree, fname: str, line, rep: Report) -> None:
    for path in QUATERNIONS.get(typ, []):
        q = [float(n.children[0]) for n in _items(_at(value, path))]
        norm = math.sqrt(sum(v * v for v in q))
        if abs(norm - 1.0) > 1e-3:
            rep.add(fname, line, f"{name}: quaternion {q} is not a unit quaternion "
                    f"(|q| = {norm:.4f})")
    if typ == "tooldata":
        mass = float(_at(value, (2, 0)).children[0])
        if mass <= 0.0:
            rep.add(fname, line, f"{name}: a tool's load mass must be positive, not {mass}")
    ext = EXTERNAL.get(typ)
    for k, item in enumerate(_items(value)):
        if ext is not None and (k,) == ext:
            continue
        for n in (item.find_data("number") if isinstance(item, Tree) else []):
            if EXPONENT.search(str(n.children[0])):
                rep.add(fname, line, f"{name}: {n.children[0]} has an exponent (9E9 belongs "
                        "only in the external axes)")
    if typ == "robtarget":
        for n in _items(_at(value, (2,))):
            if not float(n.children[0]).is_integer():
                rep.add(fname, line, f"{name}: confdata {n.children[0]} is not whole")


def _check_routines(tree: Tree, fname: str, data: dict, procs: dict, rep: Report) -> None:
    def known(ident: str, typ: str, line) -> None:
        key = ident.upper()
        if key in PREDEFINED.get(typ, ()):
            return
        d = data.get(key)
        if d is None:
            rep.add(fname, line, f"{ident} ({typ}) is not declared")
        elif d[0] != typ:
            rep.add(fname, line, f"{ident} is {d[0]}, the instruction wants {typ}")
        elif d[4] and d[1] != fname:
            rep.add(fname, line, f"{ident} is LOCAL to {d[1]}")

    for node in tree.iter_subtrees_topdown():
        if node.data in MOTION_TYPES:
            rep.motions += 1
            line = line_of(node)
            for t in node.children:
                if isinstance(t, Token) and t.type == "NAME":
                    known(str(t), MOTION_TYPES[node.data], t.line)
            for sub in node.children:
                if not isinstance(sub, Tree) or sub.data not in ("speed", "zone", "tool"):
                    continue
                names = [t for t in sub.children if isinstance(t, Token) and t.type == "NAME"]
                typ = {"speed": "speeddata", "zone": "zonedata", "tool": "tooldata"}[sub.data]
                known(str(names[0]), typ, line)
                if sub.data == "tool" and len(names) > 1:
                    known(str(names[1]), "wobjdata", line)
        elif node.data == "call":
            callee = str(node.children[0])
            if callee.upper() not in procs:
                rep.add(fname, line_of(node), f"{callee} is called but no PROC {callee} is here")

