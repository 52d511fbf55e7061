"""MELFA BASIC IV/V: what `melfa.lark` cannot say, checked on its parse trees.

From the CR1/CR1D manual (MELFA-BASIC IV) and the CR750 manual (MELFA-BASIC V): a step is
at most 127 characters, step numbers 1..32767 ascending; a variable name starts with a
letter, then letters, digits and "_" - never "_" as the second character (that makes an
external, system variable such as P_CURR); BASIC IV names are short (8 characters here, as
labels are documented), BASIC V ones up to 16. A variable's type follows its first letter
(P position, J joint) unless declared with DEF POS / DEF JNT. Every position a step uses is
defined once among the position variables (after the steps or in NAME.POS). MVR starts at
its first point: if the robot is elsewhere the controller first moves there in a straight
line, a motion nobody wrote - reported. Position values are written as the teaching box
shows them: explicit sign, fixed decimals.
"""

from __future__ import annotations

import re
from pathlib import PurePath

from lark import Token, Tree

from grammars._base import Report, check_lines, line_of, normalise, parse

MOTIONS = ("mov", "mvs", "mvr", "mvr2", "mvr3", "mvc")
MAX_STEP_CHARS = 127
MAX_NAME = {"IV": 8, "V": 16}
FIXED_SIGNED = re.compile(r"[+-]\d+\.\d+")
NAME_OK = re.compile(r"[A-Z][A-Z0-9_]*")


def check(files: dict[str, str]) -> Report:
    rep = Report()
    by_upper = {PurePath(n).name.upper(): n for n in files}
    programs = [n for n in files if n.upper().endswith((".MB4", ".MB5"))]
    if not programs:
        rep.add("(files)", None, "no MELFA program (.MB4/.MB5) among " + ", ".join(files))
        return rep
    for n in files:
        if not n.upper().endswith((".MB4", ".MB5", ".POS")):
            rep.add(n, None, "not a MELFA program or position file")
    for name in programs:
        variant = "IV" if name.upper().endswith(".MB4") else "V"
        _check_program(name, files, by_upper, variant, rep)
    return rep


def _check_program(name: str, files: dict[str, str], by_upper: dict[str, str],
                   variant: str, rep: Report) -> None:
    text = normalise(files[name])
    check_lines(rep, name, text, MAX_STEP_CHARS)
    tree = parse("melfa", "program", name, text, rep)
    if tree is None:
        return
    stem = PurePath(name).stem.upper()
    decls: dict[str, list[tuple[str, int | None, Tree]]] = {}
    _collect_decls(tree, name, decls)
    pos_name = by_upper.get(f"{stem}.POS")
    if pos_name is not None:
        pos_text = normalise(files[pos_name])
        check_lines(rep, pos_name, pos_text, MAX_STEP_CHARS)
        pos_tree = parse("melfa", "posfile", pos_name, pos_text, rep)
        if pos_tree is not None:
            _collect_decls(pos_tree, pos_name, decls)
    declared_pos, declared_jnt = _type_declarations(tree)
    _check_steps(tree, name, by_upper, rep)
    _check_settings(tree, name, rep)
    used = _check_motions(tree, name, rep)
    for ident, uses in used.items():
        where = decls.get(ident.upper(), [])
        if not where:
            rep.add(name, uses[0], f"position {ident} is used but never defined "
                    f"(neither after END nor in {stem}.POS)")
            _check_name(ident, name, uses[0], variant, rep)
    for ident, where in decls.items():
        for fname, line, _ in where[1:]:
            rep.add(fname, line, f"position {ident} is defined again (first at "
                    f"{where[0][0]} line {where[0][1]})")
        fname, line, decl = where[0]
        _check_name(ident, fname, line, variant, rep)
        _check_decl(ident, decl, fname, line, declared_pos, declared_jnt, rep)
    rep.positions += len(decls)


def _collect_decls(tree: Tree, fname: str, out: dict) -> None:
    for d in tree.find_data("pos_decl"):
        ident = str(d.children[0])
        out.setdefault(ident.upper(), []).append((fname, line_of(d), d))


def _type_declarations(tree: Tree) -> tuple[set[str], set[str]]:
    pos = {str(t).upper() for d in tree.find_data("def_pos") for t in d.children}
    jnt = {str(t).upper() for d in tree.find_data("def_jnt") for t in d.children}
    return pos, jnt


def _check_steps(tree: Tree, fname: str, by_upper: dict[str, str], rep: Report) -> None:
    last = 0
    ended = False
    for st in tree.find_data("step"):
        no = int(st.children[0])
        if not 1 <= no <= 32767:
            rep.add(fname, line_of(st), f"step number {no} outside 1..32767")
        if no <= last:
            rep.add(fname, line_of(st), f"step number {no} does not follow {last}")
        last = no
        kinds = [c.data for c in st.children if isinstance(c, Tree)]
        ended = ended or "end" in kinds
    if not ended:
        steps = list(tree.find_data("step"))
        rep.add(fname, line_of(steps[-1]) if steps else None,
                "the program has no END step (a MELFA program ends with END)")
    for call in tree.find_data("callp"):
        callee = str(call.children[0]).strip('"').upper()
        if not any(by_upper.get(f"{callee}{ext}") for ext in (".MB4", ".MB5")):
            rep.add(fname, line_of(call), f"CALLP {callee}: no such program among the files")


#: Documented ranges of settings: OVRD/JOVRD/ACCEL percent, SPD mm/s, DLY s, CNT mm.
RANGES = {"ovrd": (1.0, 100.0), "jovrd": (1.0, 100.0), "accel": (1.0, 100.0),
          "spd": (0.01, 1e4), "dly": (0.0, 1e5), "cnt": (0.0, 1e4)}


def _check_settings(tree: Tree, fname: str, rep: Report) -> None:
    for kind, (lo, hi) in RANGES.items():
        for node in tree.find_data(kind):
            for n in node.find_data("number"):
                v = float(n.children[0])
                if not lo <= v <= hi:
                    rep.add(fname, line_of(node), f"{kind.upper()} {n.children[0]} outside "
                            f"{lo:g}..{hi:g}")


def _check_motions(tree: Tree, fname: str, rep: Report) -> dict[str, list[int | None]]:
    used: dict[str, list[int | None]] = {}
    at: str | None = None
    for node in tree.iter_subtrees_topdown():
        if node.data not in MOTIONS:
            continue
        rep.motions += 1
        targets = [str(t.children[0]) for t in node.children
                   if isinstance(t, Tree) and t.data == "target"]
        for t in targets:
            used.setdefault(t, []).append(line_of(node))
        if node.data in ("mvr", "mvr2", "mvr3", "mvc") and at is not None \
                and targets[0].upper() != at.upper():
            rep.add(fname, line_of(node), f"{node.data.upper()} starts at {targets[0]} but the "
                    f"robot is at {at}: the controller adds a straight move nobody wrote")
        at = targets[-1] if node.data != "mvc" else targets[0]
    return used


def _check_name(ident: str, fname: str, line: int | None, variant: str, rep: Report) -> None:
    up = ident.upper()
    if not NAME_OK.fullmatch(up):
        rep.add(fname, line, f"{ident}: a variable name is a letter, then letters, digits, _")
    if len(up) > 1 and up[1] == "_":
        rep.add(fname, line, f"{ident}: '_' as the second character makes an external "
                "(system) variable")
    if len(up) > MAX_NAME[variant]:
        rep.add(fname, line, f"{ident} is {len(up)} characters; MELFA BASIC {variant} takes "
                f"{MAX_NAME[variant]}")


def _check_decl(ident: str, decl: Tree, fname: str, line: int | None, pos: set[str],
                jnt: set[str], rep: Report) -> None:
    up = ident.upper()
    values = [str(n.children[0]) for n in decl.find_data("number")]
    flags = [c for c in decl.children if isinstance(c, Tree) and c.data == "flags"]
    is_joint = up in jnt or (up.startswith("J") and up not in pos)
    if not is_joint and not (up.startswith("P") or up in pos):
        rep.add(fname, line, f"{ident}: not a position variable (starts with P, or DEF POS)")
    if is_joint and flags:
        rep.add(fname, line, f"{ident}: a joint variable has no structure flags")
    if not is_joint and not flags:
        rep.add(fname, line, f"{ident}: a position needs its structure flags (FL1,FL2)")
    if not is_joint and any(abs(float(v)) > 180.0 for v in values[3:6]):
        rep.add(fname, line, f"{ident}: A, B, C {values[3:6]} outside -180..180 deg")
    for v in values:
        if not FIXED_SIGNED.fullmatch(v):
            rep.add(fname, line, f"{ident}: {v} is not a signed fixed-point value (+12.30)")
    if flags:
        fl1, fl2 = (int(t) for t in flags[0].children if isinstance(t, Token))
        if fl1 > 7:
            rep.add(fname, line, f"{ident}: FL1 {fl1} is not a 3-bit posture flag (0..7)")
        if fl2 > 0xFFFFFFFF:
            rep.add(fname, line, f"{ident}: FL2 {fl2} beyond 32 bits")
