"""Independent readers of the exported dialects: a lark grammar of each controller's
documented syntax (`melfa.lark`, `krl.lark`, `rapid.lark`, `urscript.lark`, `fanuc.lark`,
`yaskawa.lark`) and a small checker on its parse tree for what a grammar cannot say
(declarations, names, number formats, line lengths, argument shapes). Written from the
vendors' manuals, never from our writers: nothing here imports `assistant` (a test checks
it), so a writer's mistake cannot hide in a reader that shares its code.

    check_text("melfa", {"THESIS.MB4": text, "THESIS.POS": text}) -> ["THESIS.MB4 line 7: ..."]

`check_report` also gives the motion and position counts (and, for FANUC and Yaskawa, the
positions' values as written: `Report.targets`). Tests import this package as
`grammars` (pytest puts tests/export on the path); a script adds tests/export to sys.path.
"""

from __future__ import annotations

from grammars import fanuc, krl, melfa, rapid, urscript, yaskawa
from grammars._base import Report

CHECKERS = {"melfa": melfa.check, "krl": krl.check, "rapid": rapid.check,
            "urscript": urscript.check, "fanuc": fanuc.check, "yaskawa": yaskawa.check}

__all__ = ["CHECKERS", "Report", "check_report", "check_text"]


def check_report(dialect: str, files: dict[str, str | bytes]) -> Report:
    """Problems, motions and positions of one program (file name -> text or bytes)."""
    try:
        checker = CHECKERS[dialect]
    except KeyError:
        raise ValueError(f"no reader for dialect {dialect!r}; known: "
                         f"{', '.join(CHECKERS)}") from None
    texts = {}
    rep = Report()
    for name, data in files.items():
        if isinstance(data, bytes):
            try:
                data = data.decode("ascii")
            except UnicodeDecodeError as exc:
                rep.add(name, None, f"not ASCII (byte {exc.start})")
                data = data.decode("latin-1")
        texts[name] = data
    try:
        out = checker(texts)
    except Exception as exc:  # noqa: BLE001 - a reader bug is reported, never a traceback
        out = Report()
        out.add("(reader)", None, f"the {dialect} reader failed: {exc!r}")
    out.problems[:0] = rep.problems
    return out


def check_text(dialect: str, files: dict[str, str | bytes]) -> list[str]:
    """Problems of one program, each naming its file and line; empty = the controller's
    documented syntax accepts it."""
    return check_report(dialect, files).problems
