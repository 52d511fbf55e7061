"""Reading our INFORM .JBI text back, for `YaskawaDialect.read`.

Only what `yaskawa` writes is read; whether the controller's documented syntax takes a job is
the independent reader's business (tests/export/grammars/yaskawa.lark). Positions come back
as the values written (`Job.positions`: C number -> X..Rz and RCONF), the motion steps with
their tags and the name comment before them for `yaskawa` to turn into moves.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from assistant.export.errors import ExportError
from assistant.export.pendant_notes import CommentState
from assistant.export.program import Frame
from assistant.export.rules import parse_number


@dataclass
class Job:
    name: str
    positions: dict[int, tuple[list[float], list[int]]] = field(default_factory=dict)
    #: ("move", (word, C number, name, tags, step)), ("ins", instruction), ("call", job)
    body: list = field(default_factory=list)
    calls: set[str] = field(default_factory=set)
    frames: dict[tuple[str, int], Frame] = field(default_factory=dict)
    tool: int = 0
    user: int | None = None


def parse_jbi(key: str, text: str) -> Job:
    rows = [r.strip() for r in text.replace("\r\n", "\n").split("\n") if r.strip()]
    if not rows or rows[0] != "/JOB" or "//INST" not in rows:
        raise ExportError(f"{key}: not an INFORM job (/JOB ... //INST)")
    name_row = next((r for r in rows if r.startswith("//NAME ")), None)
    if name_row is None:
        raise ExportError(f"{key}: no //NAME")
    job = Job(name_row[7:].strip())
    inst = rows.index("//INST")
    _positions(key, rows[:inst], job)
    notes = CommentState(re.compile(r"(TOOL|USER) (\d+)\s*(.*)"))
    name = ""
    started = False
    for r in rows[inst + 1:]:
        if r.startswith("///"):
            continue
        if r == "NOP":
            started = True
            continue
        if not started:
            raise ExportError(f"{key}: instructions before NOP")
        if r == "END":
            break
        if r.startswith("'"):
            if nm := re.fullmatch(r"(from|via|to) (\S+)", r[1:].strip()):
                name = nm.group(2)
            else:
                notes.feed(r[1:])
        elif m := re.fullmatch(r"(MOVJ|MOVL|MOVC)\s+C(\d{5})((?:\s+\S+)*)", r):
            job.body.append(("move", (m.group(1), int(m.group(2)), name,
                                      _tags(key, r, m.group(3)), notes.step)))
            name = ""
        elif m := re.fullmatch(r"DOUT\s+OT#\((\d+)\)\s+(ON|OFF)", r):
            job.body.append(("ins", notes.output(int(m.group(1)), m.group(2) == "ON")))
        elif m := re.fullmatch(r"TIMER\s+T=([\d.]+)", r):
            if (w := notes.wait(parse_number(m.group(1)))) is not None:
                job.body.append(("ins", w))
        elif m := re.fullmatch(r"CALL\s+JOB:(\w+)", r):
            job.calls.add(m.group(1).upper())
            job.body.append(("call", m.group(1).upper()))
        else:
            raise ExportError(f"{key}: cannot read {r!r}")
    job.frames = notes.frames
    return job


def _positions(key: str, rows: list[str], job: Job) -> None:
    rconf: list[int] = []
    rectan = False
    for r in rows:
        if r.startswith("///TOOL "):
            job.tool = int(r[8:])
        elif r.startswith("///USER "):
            job.user = int(r[8:])
        elif r.startswith("///POSTYPE "):
            kind = r[11:].strip()
            if kind not in ("BASE", "USER"):
                raise ExportError(f"{key}: positions of type {kind} are not read here")
        elif r == "///RECTAN":
            rectan = True
        elif r == "///PULSE":
            raise ExportError(f"{key}: pulse positions need the pulses per degree")
        elif r.startswith("///RCONF "):
            rconf = [int(v) for v in r[9:].split(",")]
        elif m := re.fullmatch(r"C(\d{5})=(.*)", r):
            if not rectan:
                raise ExportError(f"{key}: C{m.group(1)} before ///RECTAN")
            vals = [parse_number(v) for v in m.group(2).split(",")]
            if len(vals) < 6:
                raise ExportError(f"{key}: C{m.group(1)} needs X, Y, Z, Rx, Ry, Rz")
            job.positions[int(m.group(1))] = (vals[:6], rconf)


def _tags(key: str, row: str, text: str) -> dict:
    tags: dict = {}
    for tag in text.split():
        if tag == "FPT":
            tags["FPT"] = True
        elif mt := re.fullmatch(r"(VJ|V|PL|ACC)=([\d.]+)", tag):
            tags[mt.group(1)] = parse_number(mt.group(2))
        else:
            raise ExportError(f"{key}: cannot read the tag {tag!r} in {row!r}")
    return tags
