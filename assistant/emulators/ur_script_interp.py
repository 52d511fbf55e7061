"""The URScript subset the UR emulator runs, compiled before anything moves (as on a UR).

Understood: one ``def name():`` ... ``end`` program (optionally followed by its call) or a
single statement line; assignments (``X = p[...]``, ``X = [...]``, ``global``/``local``),
``pose_trans(a, b)``; the calls in `SIGNATURES` with positional or keyword arguments;
comments. Anything else - loops, conditionals, threads, other functions, unknown keywords -
is a compile error naming the line, and nothing runs: the emulator must not pretend to
execute what it cannot. Statements are parsed with Python's `ast` (URScript's expression
syntax for these forms is Python's) and evaluated by a whitelist, never `eval`.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass, field

#: Callable statements: parameter names and defaults (None = required), URScript manual.
SIGNATURES: dict[str, tuple[tuple[str, float | None], ...]] = {
    "movej": (("q", None), ("a", 1.4), ("v", 1.05), ("t", 0.0), ("r", 0.0)),
    "movel": (("pose", None), ("a", 1.2), ("v", 0.25), ("t", 0.0), ("r", 0.0)),
    "movec": (("pose_via", None), ("pose_to", None), ("a", 1.2), ("v", 0.25), ("r", 0.0),
              ("mode", 0.0)),
    "stopj": (("a", None),),
    "stopl": (("a", None), ("aRot", 0.0)),
    "set_tcp": (("pose", None),),
    "write_output_integer_register": (("address", None), ("value", None)),
    "set_tool_digital_out": (("n", None), ("b", None)),
    "set_standard_digital_out": (("n", None), ("b", None)),
    "set_digital_out": (("n", None), ("b", None)),
    "sleep": (("t", None),),
    "sync": (),
    "textmsg": (("s1", None), ("s2", "")),
}


class ScriptError(Exception):
    """A compile or runtime error, reported the way the controller does (line, column)."""

    def __init__(self, message: str, line: int = 0, column: int = 0):
        super().__init__(message)
        self.line, self.column = line, column


class Pose(tuple):
    """A ``p[x, y, z, rx, ry, rz]`` value (a plain list is a joint vector)."""


@dataclass
class Statement:
    line: int
    call: str  # function name, or "=" for an assignment
    args: dict[str, ast.expr] = field(default_factory=dict)
    target: str = ""


@dataclass
class Program:
    name: str
    body: list[Statement]


def _strip_comment(line: str) -> str:
    quote = False
    for i, ch in enumerate(line):
        if ch == '"':
            quote = not quote
        elif ch == "#" and not quote:
            return line[:i]
    return line


def compile_script(text: str) -> Program:
    """The program in `text`, or ScriptError for the first thing it does not understand."""
    lines = [(i + 1, _strip_comment(raw).strip()) for i, raw in enumerate(text.splitlines())]
    lines = [(n, s) for n, s in lines if s]
    if not lines:
        raise ScriptError("empty script")
    m = re.fullmatch(r"def\s+([A-Za-z_]\w*)\s*\(\s*\)\s*:", lines[0][1])
    if not m:
        if len(lines) > 1:
            raise ScriptError("several statements outside a 'def name():' program",
                              lines[1][0])
        return Program("secondary", [_statement(*lines[0], set())])
    name = m.group(1)
    ends = [k for k, (_, s) in enumerate(lines) if s == "end"]
    if not ends:
        raise ScriptError(f"'def {name}():' has no 'end'", lines[0][0])
    k_end = ends[-1]
    for n, s in lines[k_end + 1:]:
        if not re.fullmatch(rf"{name}\s*\(\s*\)", s):
            raise ScriptError(f"syntax_error_on_line:{n}: unexpected {s!r} after 'end'", n)
    known: set[str] = set()
    body = [_statement(n, s, known) for n, s in lines[1:k_end]]
    return Program(name, body)


def _statement(n: int, s: str, known: set[str]) -> Statement:
    s = re.sub(r"^(global|local)\s+", "", s)
    if s in ("end", "else:", "break", "continue") or s.endswith(":"):
        raise ScriptError(f"syntax_error_on_line:{n}: {s!r} is not supported by this emulator "
                          "(no blocks, loops or conditionals)", n)
    try:
        tree = ast.parse(s, mode="exec")
    except SyntaxError as exc:
        raise ScriptError(f"syntax_error_on_line:{n}: {exc.msg}", n, exc.offset or 0) from None
    if len(tree.body) != 1:
        raise ScriptError(f"syntax_error_on_line:{n}: one statement per line", n)
    node = tree.body[0]
    if isinstance(node, ast.Assign) and len(node.targets) == 1 and \
            isinstance(node.targets[0], ast.Name):
        _check_expr(node.value, known, n)
        known.add(node.targets[0].id)
        return Statement(n, "=", {"value": node.value}, node.targets[0].id)
    if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)
            and isinstance(node.value.func, ast.Name)):
        raise ScriptError(f"syntax_error_on_line:{n}: {s!r} is not a call or an assignment", n)
    call = node.value
    fname = call.func.id
    if fname not in SIGNATURES:
        raise ScriptError(f"compile_error_name_not_found:{fname} (line {n}): not a function "
                          "this emulator runs", n, call.col_offset + 1)
    params = SIGNATURES[fname]
    if len(call.args) > len(params):
        raise ScriptError(f"{fname}() takes at most {len(params)} arguments (line {n})", n)
    args: dict[str, ast.expr] = {}
    for (pname, _), a in zip(params, call.args, strict=False):
        args[pname] = a
    names = {p for p, _ in params}
    for kw in call.keywords:
        if kw.arg not in names or kw.arg in args:
            raise ScriptError(f"{fname}(): unexpected or repeated argument {kw.arg!r} "
                              f"(line {n})", n)
        args[kw.arg] = kw.value
    for pname, default in params:
        if pname not in args and default is None:
            raise ScriptError(f"{fname}(): missing argument {pname!r} (line {n})", n)
    for a in args.values():
        _check_expr(a, known, n)
    return Statement(n, fname, args)


def _check_expr(e: ast.expr, known: set[str], n: int) -> None:
    if isinstance(e, ast.Constant) and isinstance(e.value, (int, float, str, bool)):
        return
    if isinstance(e, ast.UnaryOp) and isinstance(e.op, (ast.USub, ast.UAdd)):
        return _check_expr(e.operand, known, n)
    if isinstance(e, ast.List):
        for x in e.elts:
            _check_expr(x, known, n)
        return
    if isinstance(e, ast.Subscript) and isinstance(e.value, ast.Name) and e.value.id == "p":
        elts = e.slice.elts if isinstance(e.slice, ast.Tuple) else None
        if elts is None or len(elts) != 6:
            raise ScriptError(f"line {n}: a pose p[...] needs 6 numbers", n)
        for x in elts:
            _check_expr(x, known, n)
        return
    if isinstance(e, ast.Name):
        if e.id not in known:
            raise ScriptError(f"compile_error_name_not_found:{e.id} (line {n})", n)
        return
    if isinstance(e, ast.Call) and isinstance(e.func, ast.Name) and e.func.id == "pose_trans" \
            and len(e.args) == 2 and not e.keywords:
        for x in e.args:
            _check_expr(x, known, n)
        return
    raise ScriptError(f"line {n}: expression {ast.unparse(e)!r} is not supported by this "
                      "emulator", n)


def evaluate(e: ast.expr, env: dict, pose_trans) -> object:  # noqa: ANN001
    """Value of a checked expression: float, bool, str, list (joints) or Pose."""
    if isinstance(e, ast.Constant):
        return e.value if isinstance(e.value, (str, bool)) else float(e.value)
    if isinstance(e, ast.UnaryOp):
        v = evaluate(e.operand, env, pose_trans)
        return -v if isinstance(e.op, ast.USub) else v
    if isinstance(e, ast.List):
        return [float(evaluate(x, env, pose_trans)) for x in e.elts]
    if isinstance(e, ast.Subscript):
        return Pose(float(evaluate(x, env, pose_trans)) for x in e.slice.elts)
    if isinstance(e, ast.Name):
        return env[e.id]
    assert isinstance(e, ast.Call)
    a, b = (evaluate(x, env, pose_trans) for x in e.args)
    return Pose(pose_trans(a, b))
