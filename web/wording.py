"""The operator's words for what the assistant reports: progress messages without internal
stage names, the planner's report in mm, degrees and seconds with readable labels.

Only wording: the numbers come from the session as they are (one source for every count);
the raw report stays in report.json and the session folder for whoever needs it.
"""

from __future__ import annotations

import math
import re
from typing import Any

#: Internal progress messages -> what the operator reads (first match wins; `\1` keeps a
#: group, e.g. the name of the path being driven).
PHRASES: tuple[tuple[str, str], ...] = (
    (r"elastic net stage \d+, iteration \d+", "smoothing the path"),
    (r"checking links up to joint \d+ against CAD", "finding where the arm would touch the parts"),
    (r"rasterising CAD", "mapping the parts"),
    (r"\d+ joint positions in \d+ leaves", "the robot's reach is mapped"),
    (r"(grouping joint positions per leaf|topping up thin leaves|valid joint positions"
     r"|diversity order|joint steps)", "mapping where the robot can reach"),
    (r"Voronoi roads", "finding the free corridors"),
    (r"roadmap ready", "free corridors found"),
    (r"world model ready", "world model ready"),
    (r"solving locations", "checking the robot reaches every location"),
    (r"ordering", "ordering the paths"),
    (r"primitives fitted", "turning the path into lines and arcs"),
    (r"verifying the whole trajectory", "checking the whole path against the parts"),
    (r"trajectory verified", "path checked"),
    (r"trajectory rejected", "path too close to a part: trying another"),
    (r"final plan", "checking the final path"),
    (r"mission planned", "mission planned"),
    (r"driving (.+)", r"the robot drives \1"),
    (r"random target (\d+) of (\d+)", r"move \1 of \2"),
    (r"road target (\d+) of (\d+)", r"move \1 of \2 along the corridors"),
)
_COMPILED = tuple((re.compile(rf"^\s*{p}\s*$", re.IGNORECASE), w) for p, w in PHRASES)


def progress_words(message: str) -> str:
    """A progress message in the operator's words (unknown ones pass through unchanged)."""
    for pattern, words in _COMPILED:
        m = pattern.match(message)
        if m:
            return m.expand(words)
    return message


MOVE_WORDS = {"joint": "joint move", "linear": "line", "circular": "arc", "spline": "curve"}


def moves_words(primitives: dict[str, int] | None) -> tuple[int, str]:
    """(number of moves, "4 joint moves, 1 line") from the report's primitive counts."""
    if not primitives:
        return 0, "no moves"
    parts = []
    for kind, n in primitives.items():
        if not n:
            continue
        word = MOVE_WORDS.get(kind, kind)
        parts.append(f"{n} {word}{'s' if n != 1 else ''}")
    return sum(int(n) for n in primitives.values()), ", ".join(parts)


def _value(key: str, v: Any) -> tuple[str, str] | None:
    """A raw report entry as (label, text) in operator units, or None to leave it out."""
    label = key.replace("_", " ")
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        return None
    if isinstance(v, str):
        return label[:1].upper() + label[1:], v
    for suffix, unit, scale in (("_mm", "mm", 1.0), ("_m", "mm", 1000.0), ("_rad", "°",
                                math.degrees(1.0)), ("_s", "s", 1.0)):
        if key.endswith(suffix):
            label = key[: -len(suffix)].replace("_", " ")
            return label[:1].upper() + label[1:], f"{float(v) * scale:.1f} {unit}".replace(
                " °", "°")
    return label[:1].upper() + label[1:], f"{v:.3g}" if isinstance(v, float) else str(v)


#: The report entries the page names itself, in this order.
KNOWN = ("reason", "primitives", "min_clearance_m", "clearance_required_mm",
         "tcp_path_length_m", "joint_path_length_rad", "planning_time_s", "order",
         "clearance_shortfalls")


def report_rows(report: dict[str, Any]) -> list[tuple[str, str]]:
    """The planner's report as (label, value) rows in mm, degrees and seconds."""
    rows: list[tuple[str, str]] = []
    ok = report.get("ok")
    reason = str(report.get("reason", ""))
    rows.append(("Result", reason or ("planned" if ok else "not planned")))
    n, kinds = moves_words(report.get("primitives"))
    rows.append(("Moves", f"{n} ({kinds})"))
    if "min_clearance_m" in report:
        text = f"{report['min_clearance_m'] * 1000.0:.1f} mm"
        if "clearance_required_mm" in report:
            text += f" (at least {report['clearance_required_mm']:g} mm asked)"
        rows.append(("Closest to a known part", text))
    if "tcp_path_length_m" in report:
        rows.append(("Tool path length", f"{report['tcp_path_length_m'] * 1000.0:.0f} mm"))
    if "joint_path_length_rad" in report:
        rows.append(("Joint travel (all axes)",
                     f"{math.degrees(report['joint_path_length_rad']):.0f}°"))
    if "planning_time_s" in report:
        rows.append(("Planning time (this plan)", f"{report['planning_time_s']:.1f} s"))
    if report.get("order"):
        rows.append(("Paths in the order run", ", ".join(map(str, report["order"]))))
    for line in report.get("clearance_shortfalls") or ():
        rows.append(("Closer than asked", str(line)))
    for key, v in report.items():
        if key in KNOWN or key in ("ok", "description"):
            continue
        row = _value(key, v)
        if row is not None:
            rows.append(row)
    return rows


def goal_reached(goal: str | None, summary: dict[str, Any]) -> str:
    """The end of a good run in the operator's words: where the robot is, what it learnt."""
    where = f"the robot is at {goal}" if goal else "the mission is complete"
    n, r = int(summary.get("collision_indications", 0)), int(summary.get("replans", 0))
    learnt = "" if not n else (f" {n} collision{'s' if n != 1 else ''} learnt, {r} "
                               f"re-plan{'s' if r != 1 else ''}; the final path is planned round "
                               "what was learnt.")
    return f"Goal reached: {where}.{learnt}"
