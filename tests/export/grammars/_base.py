"""What the independent readers share: loading a grammar, turning a lark error into one
line of text that names the file and line, and the report a checker returns.

Nothing here (or anywhere in this package) imports `assistant`: the readers are written from
the vendors' documented syntax, not from our writers, so a writer's mistake cannot be
mirrored by its reader."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

HERE = Path(__file__).resolve().parent


@dataclass
class Report:
    """The outcome of one program's check: problems (empty = the controller would take it),
    motion instructions and declared positions counted from the parse trees."""

    problems: list[str] = field(default_factory=list)
    motions: int = 0
    positions: int = 0
    #: The positions as written, for a round trip through the kinematics (the readers that
    #: collect them: FANUC, Yaskawa): file, number, name, frame numbers, values, flags.
    targets: list[dict] = field(default_factory=list)

    def add(self, fname: str, line: int | None, message: str) -> None:
        where = f"{fname} line {line}" if line else fname
        self.problems.append(f"{where}: {message}")


@cache
def parser(dialect: str) -> Lark:
    """The LALR parser of `<dialect>.lark` (built once per process); its start rules are
    named on the grammar's `// start:` line."""
    text = (HERE / f"{dialect}.lark").read_text(encoding="utf-8")
    starts = re.search(r"^// start: (.+)$", text, re.M)
    assert starts, f"{dialect}.lark names no start rules"
    return Lark(text, parser="lalr", lexer="contextual", propagate_positions=True,
                maybe_placeholders=False, start=starts.group(1).split())


def normalise(text: str) -> str:
    """Controllers store CR LF; the grammars read LF. A last line without LF gets one."""
    text = text.replace("\r\n", "\n")
    return text if text.endswith("\n") else text + "\n"


def parse(dialect: str, start: str, fname: str, text: str, report: Report) -> Tree | None:
    """Parse one file from rule `start`; a syntax error becomes one problem naming the line
    and its text."""
    try:
        return parser(dialect).parse(text, start=start)
    except UnexpectedInput as exc:
        report.add(fname, *_describe(exc, text))
        return None


def _describe(exc: UnexpectedInput, text: str) -> tuple[int, str]:
    lines = text.split("\n")
    n_lines = max((k for k, row in enumerate(lines, start=1) if row.strip()), default=1)
    if isinstance(exc, UnexpectedEOF) or (
            isinstance(exc, UnexpectedToken) and exc.token.type == "$END"):
        expected = getattr(exc, "expected", ()) or ()
        return n_lines, (f"the file ends too early (expected {_names(expected)}): "
                         f"{lines[n_lines - 1].strip()!r}")
    line = getattr(exc, "line", None) or 1
    src = lines[line - 1].strip() if 0 < line <= len(lines) else ""
    here = text_at(lines, line, getattr(exc, "column", 0), 40)
    word = re.match(r"[+-]?(\d+\.?\d*|\.\d+)[eE][+-]?\d+", here)
    if word:
        return line, (f"{word.group(0)} is a number with an exponent; the controller reads "
                      f"fixed-point numbers: {src!r}")
    if isinstance(exc, UnexpectedCharacters):
        col = exc.column
        return line, (f"unexpected character {text_at(lines, line, col)!r} at column {col}: "
                      f"{src!r}")
    if isinstance(exc, UnexpectedToken):
        tok = exc.token
        got = "end of line" if tok.type.endswith("NL") else repr(str(tok))
        return line, f"unexpected {got} (expected {_names(exc.expected)}): {src!r}"
    return line, f"syntax error: {src!r}"


def text_at(lines: list[str], line: int, col: int, n: int = 1) -> str:
    row = lines[line - 1] if 0 < line <= len(lines) else ""
    return row[col - 1:col - 1 + n] if 0 < col <= len(row) else ""


#: Lark's names for punctuation, as a programmer reads them.
_PUNCT = {"COMMA": "','", "LPAR": "'('", "RPAR": "')'", "LSQB": "'['", "RSQB": "']'",
          "LBRACE": "'{'", "RBRACE": "'}'", "EQUAL": "'='", "SEMICOLON": "';'",
          "COLON": "':'", "DOT": "'.'", "NL": "end of line"}


def _names(expected) -> str:
    names = [e.lstrip("_") for e in expected]
    shown = sorted({_PUNCT.get(e, e) for e in names if not e.startswith("ANON")})
    if any(e.startswith("ANON") for e in names):
        shown.append("an option")
    more = len(shown) > 6
    return ", ".join(shown[:6]) + (", ..." if more else "") if shown else "more"


def line_of(node: Tree | Token) -> int | None:
    if isinstance(node, Token):
        return node.line
    return getattr(node.meta, "line", None)


#: A number with an exponent (1e-05, 2.5E+03), not part of a name like P1E5.
EXPONENT = re.compile(r"(?<![A-Za-z0-9_.])\d+(\.\d*)?[eE][+-]?\d+")


def check_lines(report: Report, fname: str, text: str, max_len: int | None) -> None:
    """Line length (when the controller limits it) and ASCII only (every controller here)."""
    for k, row in enumerate(text.split("\n"), start=1):
        if max_len is not None and len(row) > max_len:
            report.add(fname, k, f"{len(row)} characters; the controller allows {max_len}")
        if not row.isascii():
            report.add(fname, k, f"non-ASCII character in {row.strip()!r}")
