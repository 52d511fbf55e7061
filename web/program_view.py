"""The exported program as the operator reads it: every file in full, coloured per dialect.

Pygments has no lexer for MELFA BASIC, KUKA KRL, ABB RAPID, FANUC TP or Yaskawa INFORM, so
each dialect is a small
table of regexes (comments, strings, motion instructions, other keywords, system variables,
numbers) tried in order at each place of the text; the position names are the ones the
program itself declares (MELFA .POS lines, KRL DECL E6POS, RAPID robtarget, URScript
assignments, FANUC P[n:"NAME"], INFORM C00000=), so no guess colours a word that is not a
position. Everything is HTML-escaped
and nothing is added or dropped: stripping the tags and unescaping gives the file back exactly
(line endings included), which the tests check on every dialect. Each line is a block of its
own: a long line wraps inside the panel with a hanging indent instead of being cut off.
"""

from __future__ import annotations

import html
import re
from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

#: CSS of the token kinds (class "ct-<kind>"), a light palette readable on viser's white panel.
KIND_STYLE = {
    "motion": "color:#0550ae;font-weight:700",
    "kw": "color:#8250df",
    "sys": "color:#6639ba",
    "name": "color:#953800;font-weight:600",
    "num": "color:#116329",
    "str": "color:#0a3069",
    "comment": "color:#6e7781;font-style:italic",
    "lineno": "color:#8c959f",
}
#: What the colours mean, said once above the preview.
LEGEND = (("motion", "motion"), ("name", "position"), ("kw", "keyword"), ("num", "number"),
          ("comment", "comment"))

#: How far a wrapped line's continuation is indented past the line's own indentation.
HANG_CH = 3

NUMBER = r"(?<![\w.$#])[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
IDENT = r"[A-Za-z_]\w*"


def _words(*words: str) -> str:
    return r"\b(?:" + "|".join(sorted(words, key=len, reverse=True)) + r")\b"


@dataclass(frozen=True)
class Dialect:
    """How one robot language looks: token patterns in priority order, case rule, and the
    pattern whose group 1 is a position name the program declares."""

    tokens: tuple[tuple[str, str], ...]
    declares: str
    ignore_case: bool = True


DIALECTS: dict[str, Dialect] = {
    "melfa": Dialect(
        tokens=(("lineno", r"^\d+"), ("comment", r"'[^\r\n]*|\bREM\b[^\r\n]*"),
                ("str", r'"[^"\r\n]*"?'),
                ("motion", _words("MOV", "MVS", "MVR", "MVR2", "MVR3", "MVC", "MVA", "MVQ",
                                  "MVB", "MVTL")),
                ("kw", _words("TOOL", "BASE", "OVRD", "SPD", "JOVRD", "ACCEL", "CNT", "HOPEN",
                              "HCLOSE", "END", "DLY", "WAIT", "GOTO", "GOSUB", "RETURN", "IF",
                              "THEN", "ELSE", "FOR", "TO", "NEXT", "DEF", "POS", "JNT", "FINE",
                              "SERVO", "ON", "OFF", "HLT", "CALLP", "FPRM", "MOD")),
                ("sys", r"\b[MP]_\w+")),
        declares=r"(?m)^\s*(\w+)\s*="),
    "krl": Dialect(
        tokens=(("comment", r";[^\r\n]*"), ("str", r'"[^"\r\n]*"?'),
                ("kw", r"&\w+"),
                ("motion", _words("PTP", "LIN", "CIRC", "SPL", "SLIN", "SCIRC", "SPTP",
                                  "PTP_REL", "LIN_REL", "CIRC_REL")),
                ("kw", _words("DEF", "DEFDAT", "ENDDAT", "DEFFCT", "ENDFCT", "END", "DECL",
                              "GLOBAL", "PUBLIC", "E6POS", "E6AXIS", "POS", "AXIS", "FRAME",
                              "INT", "REAL", "BOOL", "CHAR", "BAS", "SPLINE", "ENDSPLINE",
                              "IF", "THEN", "ELSE", "ENDIF", "FOR", "TO", "ENDFOR", "WHILE",
                              "ENDWHILE", "LOOP", "ENDLOOP", "WAIT", "SEC", "TRUE", "FALSE",
                              "HALT", "RETURN", "C_PTP", "C_DIS", "C_VEL", "C_ORI", "C_SPL",
                              "TRIGGER", "WHEN", "DISTANCE", "DELAY", "DO")),
                ("sys", r"\$\w+(?:\.\w+)*|#\w+")),
        declares=r"(?i)\bDECL\s+(?:GLOBAL\s+)?(?:E6POS|E6AXIS|POS|AXIS|FRAME)\s+(\w+)"),
    "rapid": Dialect(
        tokens=(("comment", r"![^\r\n]*"), ("str", r'"[^"\r\n]*"?'),
                ("motion", _words("MoveJ", "MoveL", "MoveC", "MoveAbsJ", "MoveJDO", "MoveLDO",
                                  "MoveCDO", "MoveJSync", "MoveLSync", "TriggJ", "TriggL",
                                  "TriggC", "SearchL")),
                ("kw", _words("MODULE", "ENDMODULE", "PROC", "ENDPROC", "FUNC", "ENDFUNC",
                              "CONST", "PERS", "VAR", "LOCAL", "TASK", "robtarget",
                              "jointtarget", "tooldata", "wobjdata", "speeddata", "zonedata",
                              "loaddata", "num", "bool", "string", "IF", "THEN", "ELSE",
                              "ELSEIF", "ENDIF", "FOR", "FROM", "TO", "DO", "ENDFOR", "WHILE",
                              "ENDWHILE", "RETURN", "TRUE", "FALSE", "fine", "SetDO",
                              "WaitTime", "WaitDI", "Reset", "Set", "TPWrite", "ConfJ",
                              "ConfL", "SingArea", "AccSet", "VelSet", "Stop", "EXIT")),
                ("sys", r"\\\w+|\b[vz]\d+\b|\bwobj0\b|\btool0\b")),
        declares=r"(?i)\b(?:robtarget|jointtarget)\s+(\w+)"),
    "urscript": Dialect(
        tokens=(("comment", r"#[^\r\n]*"), ("str", r'"[^"\r\n]*"?|\'[^\'\r\n]*\'?'),
                ("motion", _words("movej", "movel", "movec", "movep", "servoj", "servoc",
                                  "speedj", "speedl", "stopj", "stopl")),
                ("kw", _words("def", "end", "if", "elif", "else", "while", "for", "return",
                              "thread", "run", "join", "kill", "global", "local", "halt",
                              "True", "False", "sleep", "sync")),
                ("sys", _words("set_tcp", "set_payload", "set_tool_digital_out",
                               "set_digital_out", "set_standard_digital_out",
                               "set_configurable_digital_out", "textmsg", "popup",
                               "pose_trans", "pose_inv", "get_actual_tcp_pose",
                               "get_actual_joint_positions", "p"))),
        declares=r"(?m)^\s*(\w+)\s*=\s*(?:p?\[|pose_trans)", ignore_case=False),
    "fanuc": Dialect(
        tokens=(("lineno", r"^[ \t]*\d*:"), ("comment", r"![^\r\n;]*|//[^\r\n;]*"),
                ("str", r'"[^"\r\n]*"?|\'[^\'\r\n]*\'?'),
                ("motion", r"(?<=:)[JLCA](?=[ \t])"),
                ("kw", _words("FINE", "UFRAME_NUM", "UTOOL_NUM", "WAIT", "CALL", "RUN", "JMP",
                              "IF", "THEN", "ELSE", "ENDIF", "PAUSE", "ABORT", "END", "OVERRIDE",
                              "ON", "OFF", "TIMEOUT", "CONFIG", "UF", "UT", "Wjnt", "Offset",
                              "Tool_Offset") + r"|\b(?:CNT|ACC|CR)\d+\b"),
                ("sys", r"\b(?:DO|DI|RO|RI|UO|UI|GO|GI|AO|AI|SR|PR|R|F|M|LBL)\[[^\]\r\n]*\]"
                        r"|^/(?:PROG|ATTR|APPL|MN|POS|END)\b")),
        declares=r'P\[\d+:"(\w+)"\]', ignore_case=False),
    "yaskawa": Dialect(
        tokens=(("kw", r"^/{1,3}[A-Z0-9]+"), ("comment", r"'[^\r\n]*"),
                ("motion", _words("MOVJ", "MOVL", "MOVC", "MOVS", "IMOV")),
                ("kw", _words("NOP", "END", "DOUT", "TIMER", "CALL", "JOB", "WAIT", "PAUSE",
                              "RET", "JUMP", "FPT", "NWAIT", "ON", "OFF")
                 + r"|\b(?:VJ|VR|PL|CR|ACC|DEC|V|T)="),
                ("sys", r"\b(?:OT|IN|OG|IG)#\(\d+\)")),
        declares=r"(?m)^(C\d{5})=", ignore_case=False),
}


@lru_cache(maxsize=32)
def _scanner(dialect: str, names: tuple[str, ...]) -> re.Pattern[str]:
    """One alternation of named groups; earlier entries win where several match. The
    declared positions come before the keywords (a position may be spelt like one)."""
    d = DIALECTS[dialect]
    parts: list[tuple[str, str]] = []
    for kind, pattern in d.tokens:
        if names and kind in ("motion", "kw", "sys") and all(k != "name" for k, _ in parts):
            parts.append(("name", _words(*map(re.escape, names))))
        parts.append((kind, pattern))
    parts += [("num", NUMBER), ("ident", IDENT)]
    alt = "|".join(f"(?P<g{i}_{kind}>{p})" for i, (kind, p) in enumerate(parts))
    return re.compile(alt, re.MULTILINE | (re.IGNORECASE if d.ignore_case else 0))


def declared_names(texts: Iterable[str], dialect: str) -> frozenset[str]:
    """The position names the program's files declare (what is coloured as a position)."""
    d = DIALECTS.get(dialect)
    if d is None:
        return frozenset()
    rx = re.compile(d.declares)
    return frozenset(m.group(1) for t in texts for m in rx.finditer(t))


def highlight(text: str, dialect: str, names: Iterable[str] = ()) -> str:
    """`text` as HTML spans (class "ct-<kind>"); unknown dialects come back escaped only."""
    if dialect not in DIALECTS:
        return html.escape(text)
    out: list[str] = []
    at = 0
    for m in _scanner(dialect, tuple(sorted(set(names)))).finditer(text):
        kind = (m.lastgroup or "").split("_", 1)[1]
        if kind == "ident":
            continue  # a plain word, consumed whole so that no number starts inside it
        out.append(html.escape(text[at:m.start()]))
        out.append(f'<span class="ct-{kind}">{html.escape(m.group())}</span>')
        at = m.end()
    out.append(html.escape(text[at:]))
    return "".join(out)


def line_blocks(markup: str) -> str:
    """Each line of highlighted markup in its own block (its newline inside), so that a long
    line wraps with a hanging indent; no token span crosses a line, so the split is safe.
    A long position tuple has no spaces: it may wrap after a comma (<wbr>), not inside a
    number (no tag or escaped text holds a comma, so the replace touches text only)."""
    out = []
    for ln in re.split(r"(?<=\n)", markup.replace(",", ",<wbr>")):
        if not ln:
            continue
        indent = len(ln) - len(ln.lstrip(" "))  # continuation lines hang below the text
        hang = indent + HANG_CH
        style = f' style="padding-left:{hang}ch;text-indent:-{hang}ch"' if indent else ""
        out.append(f'<span class="ct-line"{style}>{ln}</span>')
    return "".join(out)


STYLE = "<style>" + "".join(f".ct-prog .ct-{k}{{{v}}}" for k, v in KIND_STYLE.items()) + (
    ".ct-prog pre{font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace;"
    "font-size:0.78em;line-height:1.35;white-space:pre-wrap;overflow-wrap:anywhere;"
    "max-height:60vh;overflow:auto;margin:0.2em 0 0.8em;padding:0.5em 0.6em;"
    "background:#f6f8fa;border:1px solid #d0d7de;border-radius:4px;tab-size:4}"
    f".ct-prog .ct-line{{display:block;padding-left:{HANG_CH}ch;text-indent:-{HANG_CH}ch}}"
    ".ct-prog .ct-file{font-size:0.85em;margin-top:0.3em}"
    ".ct-prog .ct-legend{font-size:0.75em}</style>")


def program_html(result: Any) -> str:
    """Every file of an export result, in full, each in its own scrolling monospace box."""
    texts = [(f.name, f.data.decode("ascii", errors="replace"), len(f.data))
             for f in result.files]
    names = declared_names((t for _, t, _ in texts), result.dialect)
    legend = " &nbsp; ".join(f'<span class="ct-{k}">{label}</span>' for k, label in LEGEND)
    parts = [STYLE, '<div class="ct-prog">', f'<div class="ct-legend">{legend}</div>']
    for name, text, size in texts:
        parts.append(f'<div class="ct-file"><b>{html.escape(name)}</b> ({size:,} bytes)</div>')
        parts.append(f'<pre data-file="{html.escape(name)}">'
                     f"{line_blocks(highlight(text, result.dialect, names))}</pre>")
    parts.append("</div>")
    return "".join(parts)
