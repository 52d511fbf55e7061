"""The project's KRL reader (tests/export/grammars: `krl.lark`, written from KUKA's KSS 8
manual) extended by what a controller-side KRL program needs and an exported motion program
never has: declarations of several names and CHAR arrays, STATE_T / MODUS_T, assignments of
expressions, IF / LOOP / WHILE / SWITCH blocks, function calls with arguments (CWRITE, SREAD,
SWRITE, INVERSE) and the geometric operator ":". The motion statements, aggregates, header
lines, names and numbers stay the project's own rules; the extension adds alternatives
(lark's %extend / %override) and never imports `assistant`.

    problems("cellbridge.src", src_text, "cellbridge.dat", dat_text) -> ["... line 7: ..."]
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

EXPORT_TESTS = Path(__file__).resolve().parents[1] / "export"
if str(EXPORT_TESTS) not in sys.path:
    sys.path.insert(0, str(EXPORT_TESTS))

from grammars._base import HERE, Report, _describe, normalise  # noqa: E402

EXTENSION = r"""
%override TYPE.2: /(E6POS|E6AXIS|POS|AXIS|FRAME|INT|REAL|BOOL|CHAR|STATE_T|MODUS_T)\b/i
%extend decl_line: "DECL"i GLOBAL? TYPE NAME ("," NAME)+          -> decl_many
                 | "DECL"i GLOBAL? TYPE NAME "[" INT "]"          -> decl_array
%override assign: SYSVAR ("." NAME)* "=" expr
%extend target: SYSVAR
%extend stmt: if_block | loop_block | while_block | switch_block | var_assign | fcall

if_block: "IF"i expr "THEN"i _NL+ (stmt _NL+)* ("ELSE"i _NL+ (stmt _NL+)*)? "ENDIF"i
loop_block: "LOOP"i _NL+ (stmt _NL+)* "ENDLOOP"i
while_block: "WHILE"i expr _NL+ (stmt _NL+)* "ENDWHILE"i
switch_block: "SWITCH"i expr _NL+ case+ default? "ENDSWITCH"i
case: "CASE"i expr ("," expr)* _NL+ (stmt _NL+)*
default: "DEFAULT"i _NL+ (stmt _NL+)*
var_assign: lvalue "=" expr
fcall: NAME "(" expr ("," expr)* ")"
lvalue: NAME ("." NAME | "[" "]" | "[" expr "]")*

?expr: or_expr
?or_expr: and_expr (OR_OP and_expr)*
?and_expr: not_expr (AND_OP not_expr)*
?not_expr: NOT_OP not_expr | cmp_expr
?cmp_expr: sum_expr (CMP sum_expr)*
?sum_expr: prod_expr (ADD_OP prod_expr)*
?prod_expr: geo_expr (MUL_OP geo_expr)*
?geo_expr: atom (":" atom)*
?atom: number | STRING | ENUM | BOOL | aggregate | "(" expr ")"
     | lvalue | sysref | NAME "(" expr ("," expr)* ")" -> func
sysref: SYSVAR ("." NAME | "[" expr "]")*
OR_OP.3: /(OR|EXOR|B_OR|B_EXOR)\b/i
AND_OP.3: /(AND|B_AND)\b/i
NOT_OP.3: /(NOT|B_NOT)\b/i
CMP: "==" | "<>" | "<=" | ">=" | "<" | ">"
ADD_OP: "+" | "-"
MUL_OP: "*" | "/"
STRING: /"[^"\n]*"/
"""


def parser() -> Lark:
    base = (HERE / "krl.lark").read_text(encoding="utf-8")
    return Lark(base + EXTENSION, parser="lalr", lexer="contextual",
                propagate_positions=True, maybe_placeholders=False, start=["src", "dat"])


def parse(fname: str, text: str, start: str, report: Report) -> Tree | None:
    text = normalise(text)
    try:
        return parser().parse(text, start=start)
    except UnexpectedInput as exc:
        report.add(fname, *_describe(exc, text))
        return None


def declared(*trees: Tree) -> set[str]:
    out: set[str] = set()
    for t in trees:
        for kind in ("decl", "decl_only", "decl_many", "decl_array"):
            for d in t.find_data(kind):
                out |= {str(x).upper() for x in d.children
                        if isinstance(x, Token) and x.type == "NAME"}
    return out


def problems(src_name: str, src: str, dat_name: str, dat: str) -> list[str]:
    """Syntax problems, plus every variable used but not declared (.src or .dat)."""
    rep = Report()
    src_tree = parse(src_name, src, "src", rep)
    dat_tree = parse(dat_name, dat, "dat", rep)
    if src_tree is None or dat_tree is None:
        return rep.problems
    known = declared(src_tree, dat_tree)
    module = [str(t) for t in src_tree.children if isinstance(t, Token) and t.type == "NAME"]
    stem = Path(src_name).stem.upper()
    if module and module[0].upper() != stem:
        rep.add(src_name, None, f"DEF {module[0]} but the file is {stem}")
    builtin = {"CWRITE", "SREAD", "SWRITE", "INVERSE", "BAS"}
    for node in src_tree.iter_subtrees():
        if node.data in ("lvalue", "ptp", "lin", "circ"):
            first = node.children[0] if node.children else None
            if isinstance(first, Token) and first.type == "NAME" and \
                    first.upper() not in known:
                rep.add(src_name, first.line, f"{first} is used but not declared")
        if node.data in ("fcall", "func", "fcall_args"):
            name = str(node.children[0]).upper()
            if name not in builtin:
                rep.add(src_name, node.meta.line, f"{name}( ) is not a KRL built-in here")
    for word in re.findall(r"\$[A-Za-z_]+", src):
        if word.upper() not in SYSTEM_VARIABLES:
            rep.add(src_name, None, f"{word} is not a KSS 8 system variable")
    return rep.problems


#: The system variables the program reads or writes (KSS 8 system variables manual).
SYSTEM_VARIABLES = {"$FCT_CALL", "$POS_ACT", "$AXIS_ACT", "$TOOL", "$BASE", "$NULLFRAME",
                    "$OV_PRO", "$SOFTN_END", "$SOFTP_END"}
