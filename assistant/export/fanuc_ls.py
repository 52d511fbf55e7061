"""Reading our FANUC .LS text back into instructions, for `FanucDialect.read`.

Only what `fanuc` writes is read; whether the controller's documented syntax takes a file is
the independent reader's business (tests/export/grammars/fanuc.lark). Positions come back as
the values written (`LsProgram.positions`: comment, UF, X..R with CONFIG, or J1..Jn), the
motions as regex matches for `fanuc` to turn into moves.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from assistant.export.errors import ExportError
from assistant.export.pendant_notes import CommentState
from assistant.export.program import Frame
from assistant.export.rules import parse_number

#: A motion line: kind, first point, the circular end point, speed, unit, FINE/CNTn, ACCn.
MOTION = re.compile(
    r"([JLC])\s+P\[(\d+)(?::[^\]]*)?\]\s*(?::\s*P\[(\d+)(?::[^\]]*)?\]\s*)?"
    r"(\d+)(%|mm/sec)\s+(FINE|CNT(\d+))(?:\s+ACC(\d+))?")


@dataclass
class LsProgram:
    name: str
    #: ("move", (match, step)), ("ins", instruction) or ("call", program name)
    body: list = field(default_factory=list)
    positions: dict[int, dict] = field(default_factory=dict)
    calls: set[str] = field(default_factory=set)
    frames: dict[tuple[str, int], Frame] = field(default_factory=dict)
    utool: int = 0
    uframe: int = 0


def parse_ls(key: str, text: str) -> LsProgram:
    text = text.replace("\r\n", "\n")
    m = re.search(r"^/PROG\s+(\w+)", text, re.M)
    if not m or "/MN" not in text or "/POS" not in text:
        raise ExportError(f"{key}: not a FANUC .LS program (/PROG, /MN, /POS)")
    mn = text.split("/MN", 1)[1].split("/POS", 1)[0]
    pos = text.split("/POS", 1)[1].split("/END", 1)[0]
    rows: list[str] = []
    for raw in mn.split("\n"):
        if not raw.strip():
            continue
        if re.match(r"\s*:", raw) and rows:  # continuation of a circular move
            rows[-1] += " " + raw.strip()
        else:
            rows.append(raw)
    out = LsProgram(m.group(1), positions=ls_positions(pos, key))
    notes = CommentState(re.compile(r"(UTOOL|UFRAME)\[(\d+)\]\s*(.*)"))
    for row in rows:
        mm = re.fullmatch(r"\s*\d+:\s*(.*?)\s*;\s*", row)
        if not mm:
            raise ExportError(f"{key}: cannot read {row.strip()!r}")
        ins = mm.group(1)
        if ins.startswith("!"):
            notes.feed(ins[1:])
        elif mo := MOTION.fullmatch(ins):
            out.body.append(("move", (mo, notes.step)))
        elif mo := re.fullmatch(r"(UFRAME_NUM|UTOOL_NUM)=(\d+)", ins):
            if mo.group(1) == "UTOOL_NUM":
                out.utool = int(mo.group(2))
            else:
                out.uframe = int(mo.group(2))
        elif mo := re.fullmatch(r"DO\[(\d+)\]=(ON|OFF)", ins):
            out.body.append(("ins", notes.output(int(mo.group(1)), mo.group(2) == "ON")))
        elif mo := re.fullmatch(r"WAIT\s+([\d.]+)\(sec\)", ins):
            if (w := notes.wait(parse_number(mo.group(1)))) is not None:
                out.body.append(("ins", w))
        elif mo := re.fullmatch(r"CALL\s+(\w+)", ins):
            out.calls.add(mo.group(1).upper())
            out.body.append(("call", mo.group(1).upper()))
        else:
            raise ExportError(f"{key}: cannot read {ins!r}")
    out.frames = notes.frames
    return out


def ls_positions(text: str, key: str) -> dict[int, dict]:
    """/POS: number -> comment, UF and either J (deg) or XYZWPR (mm, deg) with CONFIG."""
    out: dict[int, dict] = {}
    for m in re.finditer(r'P\[(\d+)(?::"([^"]*)")?\]\s*\{(.*?)\};', text, re.S):
        n, body = int(m.group(1)), m.group(3)
        uf = re.search(r"UF\s*:\s*(\d+)", body)
        entry: dict = {"comment": m.group(2) or "", "uf": int(uf.group(1)) if uf else 0}
        joints = re.findall(r"\bJ(\d+)\s*=\s*(-?[\d.]+)\s*deg", body)
        if joints:
            entry["J"] = [parse_number(v) for _, v in sorted(joints, key=lambda j: int(j[0]))]
        else:
            vals = dict(re.findall(r"\b([XYZWPR])\s*=\s*(-?[\d.]+)\s*(?:mm|deg)", body))
            cfg = re.search(r"CONFIG\s*:\s*'([^']*)'", body)
            if set(vals) != set("XYZWPR") or not cfg:
                raise ExportError(f"{key}: P[{n}] needs X, Y, Z, W, P, R and CONFIG")
            entry["XYZWPR"] = [parse_number(vals[k]) for k in "XYZWPR"]
            entry["config"] = cfg.group(1)
        out[n] = entry
    return out
