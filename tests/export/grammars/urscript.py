"""URScript: what `urscript.lark` cannot say, checked on its parse trees.

From the URScript manual: the functions a program like ours calls, with their documented
parameters (movej(q, a=1.4, v=1.05, t=0, r=0), movel(pose, a, v, t, r), movep(pose, a, v,
r), movec(pose_via, pose_to, a, v, r, mode), set_tcp(pose), set_standard_digital_out(n, b)
n 0..7, set_tool_digital_out(n, b) n 0..1, set_digital_out(n, b), sleep(t), textmsg(s),
pose_trans(p_from, p_from_to)); a pose p[...] has 6 numbers; a joint vector has one value
per joint - 6 on every UR arm; movec's mode is 0 or 1; speeds and accelerations positive,
blend radii not negative. A variable is assigned before it is used and is not a built-in
function's or keyword's name.
"""

from __future__ import annotations

from lark import Token, Tree

from grammars._base import Report, check_lines, line_of, normalise, parse

MOTIONS = ("movej", "movel", "movep", "movec")
#: name -> (positional parameters (required first), how many are required).
FUNCTIONS: dict[str, tuple[tuple[str, ...], int]] = {
    "movej": (("q", "a", "v", "t", "r"), 1),
    "movel": (("pose", "a", "v", "t", "r"), 1),
    "movep": (("pose", "a", "v", "r"), 1),
    "movec": (("pose_via", "pose_to", "a", "v", "r", "mode"), 2),
    "set_tcp": (("pose",), 1),
    "set_payload": (("m", "cog"), 1),
    "set_standard_digital_out": (("n", "b"), 2),
    "set_tool_digital_out": (("n", "b"), 2),
    "set_digital_out": (("n", "b"), 2),
    "set_configurable_digital_out": (("n", "b"), 2),
    "sleep": (("t",), 1),
    "sync": ((), 0),
    "textmsg": (("s1", "s2"), 1),
    "pose_trans": (("p_from", "p_from_to"), 2),
    "stopj": (("a",), 1),
    "stopl": (("a",), 1),
}
OUTPUT_RANGE = {"set_standard_digital_out": 7, "set_tool_digital_out": 1,
                "set_digital_out": 9, "set_configurable_digital_out": 7}
KEYWORDS = {"def", "end", "if", "elif", "else", "while", "for", "in", "return", "and", "or",
            "not", "xor", "True", "False", "global", "local", "thread", "run", "kill", "halt",
            "break", "continue", "pass", "sec", "enter_critical", "exit_critical"}
JOINTS = 6


def check(files: dict[str, str]) -> Report:
    rep = Report()
    scripts = [n for n in files if n.lower().endswith((".script", ".urscript"))]
    if not scripts:
        rep.add("(files)", None, "no URScript file (.script) among " + ", ".join(files))
    for n in files:
        if n not in scripts:
            rep.add(n, None, "not a URScript file")
    for n in scripts:
        text = normalise(files[n])
        check_lines(rep, n, text, None)
        tree = parse("urscript", "script", n, text, rep)
        if tree is not None:
            _check_script(tree, n, rep)
    return rep


def _check_script(tree: Tree, fname: str, rep: Report) -> None:
    defs = {str(d.children[0]) for d in tree.find_data("definition")}
    for d in tree.children:
        if isinstance(d, Tree) and d.data == "call" and str(d.children[0]) not in defs:
            rep.add(fname, line_of(d), f"{d.children[0]}() is called but not defined")
    for d in tree.find_data("definition"):
        kinds: dict[str, tuple[str, int]] = {}
        for st in d.children[1:]:
            if st.data in ("global_assign", "local_assign"):
                st = st.children[0]
            if st.data == "assign":
                name, value = str(st.children[0]), st.children[1]
                if name in FUNCTIONS or name in KEYWORDS or name in defs:
                    rep.add(fname, line_of(st), f"{name} is a keyword or function name")
                kinds[name] = _kind(value, kinds, fname, rep)
                if kinds[name][0] in ("pose", "joints"):
                    rep.positions += 1
            elif st.data == "call":
                _kind(st, kinds, fname, rep)


def _kind(node, kinds: dict, fname: str, rep: Report) -> tuple[str, int]:
    """('pose'|'joints'|'number'|'other', length) of an expression, checking calls inside."""
    if isinstance(node, Token):
        if node.type == "NAME":
            if str(node) not in kinds:
                rep.add(fname, node.line, f"{node} is used before it is assigned")
                return ("other", 0)
            return kinds[str(node)]
        return ("other", 0)
    if node.data == "number":
        return ("number", 1)
    if node.data == "pose":
        vals = [c for c in node.children if not (isinstance(c, Token) and c.type == "POSE_OPEN")]
        for v in vals:
            _kind(v, kinds, fname, rep)
        if len(vals) != 6:
            rep.add(fname, line_of(node), f"a pose has 6 values (x, y, z, rx, ry, rz), not "
                    f"{len(vals)}")
        return ("pose", len(vals))
    if node.data == "list":
        for v in node.children:
            _kind(v, kinds, fname, rep)
        return ("joints", len(node.children))
    if node.data == "call":
        return _call(node, kinds, fname, rep)
    return ("other", 0)


def _call(node: Tree, kinds: dict, fname: str, rep: Report) -> tuple[str, int]:
    name = str(node.children[0])
    line = line_of(node)
    args = [a for a in node.children[1:] if isinstance(a, Tree)]
    pos = [a.children[0] for a in args if a.data == "positional"]
    kw = {str(a.children[0]): a.children[1] for a in args if a.data == "keyword"}
    if name in MOTIONS:
        rep.motions += 1
    if name not in FUNCTIONS:
        rep.add(fname, line, f"{name}() is not a URScript function this check knows")
        for a in pos + list(kw.values()):
            _kind(a, kinds, fname, rep)
        return ("other", 0)
    params, required = FUNCTIONS[name]
    kinds_in_order = [a.data for a in args]
    if "keyword" in kinds_in_order and \
            "positional" in kinds_in_order[kinds_in_order.index("keyword"):]:
        rep.add(fname, line, f"{name}(): a positional argument after a keyword argument")
    if len(pos) > len(params):
        rep.add(fname, line, f"{name}() takes {len(params)} arguments, not {len(pos)}")
    bound = dict(zip(params, pos, strict=False))  # too many: reported above
    for k, v in kw.items():
        if k not in params:
            rep.add(fname, line, f"{name}() has no parameter {k}")
        elif k in bound:
            rep.add(fname, line, f"{name}(): {k} given twice")
        bound[k] = v
    if missing := [p for p in params[:required] if p not in bound]:
        rep.add(fname, line, f"{name}() needs {', '.join(missing)}")
    vals = {k: _kind(v, kinds, fname, rep) for k, v in bound.items()}
    for k in ("q", "pose", "pose_via", "pose_to", "p_from", "p_from_to"):
        kind = vals.get(k)
        if kind is None:
            continue
        if kind[0] == "joints" and kind[1] != JOINTS:
            rep.add(fname, line, f"{name}(): {k} has {kind[1]} joint values; UR arms have "
                    f"{JOINTS}")
        if kind[0] == "number":
            rep.add(fname, line, f"{name}(): {k} is a number, not a pose or joint vector")
        if k in ("p_from", "p_from_to") and kind[0] == "joints":
            rep.add(fname, line, f"{name}(): {k} must be a pose p[...]")
    for k in ("a", "v", "t", "r", "mode", "n"):
        if k in bound and isinstance(bound[k], Tree) and bound[k].data == "number":
            x = float(bound[k].children[0])
            if k in ("a", "v") and x <= 0.0:
                rep.add(fname, line, f"{name}(): {k}={x} must be positive")
            if k in ("t", "r") and x < 0.0:
                rep.add(fname, line, f"{name}(): {k}={x} must not be negative")
            if k == "mode" and x not in (0.0, 1.0):
                rep.add(fname, line, f"{name}(): mode is 0 or 1, not {x:g}")
            if k == "n" and not (x.is_integer() and 0 <= x <= OUTPUT_RANGE.get(name, 0)):
                rep.add(fname, line, f"{name}(): output {x:g} outside 0..{OUTPUT_RANGE[name]}")
    if "b" in bound and not (isinstance(bound["b"], Token) and bound["b"].type == "BOOL"):
        rep.add(fname, line, f"{name}(): the value is True or False")
    return ("pose", 6) if name == "pose_trans" else ("other", 0)
