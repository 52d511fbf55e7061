"""KUKA KRL: what `krl.lark` cannot say, checked on its parse trees.

From the KSS 8 programming manual: the module name (DEF / DEFDAT) is the file name; names are
at most 24 characters, a letter or "_" first, and no keyword; every point a motion uses is
declared once (in the .src's declaration part or its .dat); LIN, CIRC and spline segments
need Cartesian points (POS / E6POS / FRAME), PTP takes axis points too; an E6POS names
X, Y, Z, A, B, C (S, T, E1..E6 optional), an E6AXIS A1..A6 (E1..E6 optional), a FRAME
X..C only, each once. A called subprogram is among the files. A SPLINE block counts as one
motion (the controller plans it as one).
"""

from __future__ import annotations

from pathlib import PurePath

from lark import Token, Tree

from grammars._base import Report, check_lines, line_of, normalise, parse

MAX_NAME = 24
KEYWORDS = frozenset({
    "ANIN", "ANOUT", "AND", "B_AND", "B_EXOR", "B_NOT", "B_OR", "BOOL", "BRAKE", "C_DIS", "C_ORI",
    "C_PTP", "C_SPL", "C_VEL", "CASE", "CHAR", "CIRC", "CIRC_REL", "CONST", "CONTINUE", "DECL",
    "DEF", "DEFAULT", "DEFDAT", "DEFFCT", "DELAY", "DO", "ELSE", "END", "ENDDAT", "ENDFCT",
    "ENDFOR", "ENDIF", "ENDLOOP", "ENDSPLINE", "ENDSWITCH", "ENDWHILE", "ENUM", "EXIT", "EXOR",
    "EXT", "EXTFCT", "FALSE", "FOR", "GLOBAL", "GOTO", "HALT", "IF", "IMPORT", "INT", "INTERRUPT",
    "IS", "LIN", "LIN_REL", "LOOP", "MAXIMUM", "MINIMUM", "NOT", "OR", "PRIO", "PTP", "PTP_REL",
    "PUBLIC", "REAL", "REPEAT", "RESUME", "RETURN", "SCIRC", "SEC", "SIGNAL", "SLIN", "SPL",
    "SPLINE", "SPTP", "STRUC", "SWITCH", "THEN", "TO", "TRIGGER", "TRUE", "UNTIL", "WAIT", "WHEN",
    "WHILE"
})
#: System variables a motion program sets (KSS 8 system variables manual).
SYSTEM = {"$TOOL", "$BASE", "$LOAD", "$VEL", "$ACC", "$APO", "$OUT", "$ANOUT", "$ADVANCE",
          "$ORI_TYPE", "$CIRC_TYPE", "$VEL_AXIS", "$ACC_AXIS", "$NULLFRAME", "$TIMER",
          "$FLAG", "$CYCFLAG"}
CARTESIAN = {"E6POS", "POS", "FRAME"}
AXIS = {"E6AXIS", "AXIS"}
EXT = {f"E{i}" for i in range(1, 7)}
COMPONENTS = {
    "E6POS": ({"X", "Y", "Z", "A", "B", "C"}, {"S", "T"} | EXT),
    "POS": ({"X", "Y", "Z", "A", "B", "C"}, {"S", "T"}),
    "FRAME": ({"X", "Y", "Z", "A", "B", "C"}, set()),
    "E6AXIS": ({f"A{i}" for i in range(1, 7)}, EXT),
    "AXIS": ({f"A{i}" for i in range(1, 7)}, set()),
}


def check(files: dict[str, str]) -> Report:
    rep = Report()
    stems = {PurePath(n).stem.upper(): n for n in files if n.lower().endswith(".src")}
    dats = {PurePath(n).stem.upper(): n for n in files if n.lower().endswith(".dat")}
    if not stems:
        rep.add("(files)", None, "no KRL program (.src) among " + ", ".join(files))
    for n in files:
        if not n.lower().endswith((".src", ".dat")):
            rep.add(n, None, "not a KRL .src or .dat file")
    for stem, dat in dats.items():
        if stem not in stems:
            rep.add(dat, None, f"{dat} has no {stem}.src beside it")
    for stem, src in stems.items():
        _check_module(stem, src, dats.get(stem), files, set(stems), rep)
    return rep


def _check_module(stem: str, src: str, dat: str | None, files: dict[str, str],
                  modules: set[str], rep: Report) -> None:
    text = normalise(files[src])
    check_lines(rep, src, text, None)
    tree = parse("krl", "src", src, text, rep)
    decls: dict[str, list[tuple[str, int | None, Tree]]] = {}
    if dat is not None:
        dtext = normalise(files[dat])
        check_lines(rep, dat, dtext, None)
        dtree = parse("krl", "dat", dat, dtext, rep)
        if dtree is not None:
            _module_name(dtree, dat, stem, "DEFDAT", rep)
            _collect(dtree, dat, decls)
    if tree is None:
        return
    _module_name(tree, src, stem, "DEF", rep)
    _collect(tree, src, decls)
    for ident, where in decls.items():
        for fname, line, _ in where[1:]:
            rep.add(fname, line, f"{ident} is declared again (first at {where[0][0]} line "
                    f"{where[0][1]})")
        fname, line, d = where[0]
        _check_name(str(d.children[-2] if d.data == "decl" else d.children[-1]), fname, line,
                    rep)
        if d.data == "decl":
            _check_aggregate(ident, d, fname, line, rep)
    rep.positions += sum(1 for w in decls.values() if _type(w[0][2]) in CARTESIAN | AXIS)
    _check_motions(tree, src, decls, rep)
    for tok in tree.scan_values(lambda v: isinstance(v, Token) and v.type == "SYSVAR"):
        if str(tok).upper() not in SYSTEM:
            rep.add(src, tok.line, f"{tok} is not a system variable a motion program sets")
    for call in tree.find_data("subcall"):
        callee = str(call.children[0]).upper()
        if callee not in modules:
            rep.add(src, line_of(call), f"{callee}( ) is called but no {callee}.src is here")
        if callee == stem:
            rep.add(src, line_of(call), f"{callee} calls itself")


def _module_name(tree: Tree, fname: str, stem: str, word: str, rep: Report) -> None:
    names = [t for t in tree.children if isinstance(t, Token) and t.type == "NAME"]
    if names and str(names[0]).upper() != stem:
        rep.add(fname, names[0].line, f"{word} {names[0]} but the file is {stem}: KRL wants "
                "the module name to be the file name")
    if names:
        _check_name(str(names[0]), fname, names[0].line, rep)


def _collect(tree: Tree, fname: str, out: dict) -> None:
    for d in list(tree.find_data("decl")) + list(tree.find_data("decl_only")):
        name = [t for t in d.children if isinstance(t, Token) and t.type == "NAME"][0]
        out.setdefault(str(name).upper(), []).append((fname, line_of(d), d))


def _type(d: Tree) -> str:
    return [str(t).upper() for t in d.children if isinstance(t, Token) and t.type == "TYPE"][0]


def _check_name(ident: str, fname: str, line: int | None, rep: Report) -> None:
    if len(ident) > MAX_NAME:
        rep.add(fname, line, f"{ident} is {len(ident)} characters; KRL takes {MAX_NAME}")
    if ident.upper() in KEYWORDS:
        rep.add(fname, line, f"{ident} is a KRL keyword")


def _check_aggregate(ident: str, d: Tree, fname: str, line: int | None, rep: Report) -> None:
    typ = _type(d)
    value = d.children[-1]
    if typ not in COMPONENTS:
        return
    if not (isinstance(value, Tree) and value.data == "aggregate"):
        rep.add(fname, line, f"{ident}: a {typ} is initialised with {{...}}")
        return
    keys = [str(c.children[0]).upper() for c in value.children]
    need, may = COMPONENTS[typ]
    dup = {k for k in keys if keys.count(k) > 1}
    if dup:
        rep.add(fname, line, f"{ident}: {', '.join(sorted(dup))} given twice")
    if unknown := set(keys) - need - may:
        rep.add(fname, line, f"{ident}: {typ} has no {', '.join(sorted(unknown))}")
    if missing := need - set(keys):
        rep.add(fname, line, f"{ident}: {typ} lacks {', '.join(sorted(missing))}")
    for c in value.children:
        key, val = str(c.children[0]).upper(), c.children[1]
        if key in ("A", "B", "C") and typ in CARTESIAN and isinstance(val, Tree) \
                and abs(float(val.children[0])) > 180.0:
            rep.add(fname, line, f"{ident}: {key} {val.children[0]} outside -180..180 deg")
        if key in ("S", "T") and isinstance(val, Tree) and not str(val.children[0]).isdigit():
            rep.add(fname, line, f"{ident}: {key} is a whole number (bit field), not "
                    f"{val.children[0]}")


def _check_motions(tree: Tree, fname: str, decls: dict, rep: Report) -> None:
    for node in tree.iter_subtrees_topdown():
        if node.data in ("ptp", "lin", "circ", "spline"):
            rep.motions += 1
        if node.data not in ("ptp", "lin", "circ", "spl", "slin", "scirc"):
            continue
        for t in node.children:
            if not (isinstance(t, Token) and t.type == "NAME"):
                continue
            where = decls.get(str(t).upper())
            if not where:
                rep.add(fname, t.line, f"point {t} is used but not declared (.dat or .src)")
                continue
            typ = _type(where[0][2])
            if node.data != "ptp" and typ not in CARTESIAN:
                rep.add(fname, t.line, f"{node.data.upper()} needs a Cartesian point; {t} is "
                        f"{typ}")
            elif node.data == "ptp" and typ not in CARTESIAN | AXIS:
                rep.add(fname, t.line, f"PTP {t}: {typ} is not a point")
