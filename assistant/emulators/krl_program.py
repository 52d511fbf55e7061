"""The motions of an uploaded KRL module, for the bridge emulator to execute.

Reads PTP / LIN / SPL / SLIN / SPTP / CIRC with literal aggregates (``{X 1, Y 2, ...}``,
``{A1 10, A2 ...}``) or names declared in the module's .dat (``DECL E6POS XP1={...}``).
Everything else (``$VEL``, ``$OUT[1]=TRUE``, ``WAIT``, ``BAS``, blending suffixes ...) is
accepted and ignored: the emulator checks geometry, not the controller's full language.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

_AGG = re.compile(r"\{([^{}]*)\}")
_MOTION = re.compile(r"^\s*(PTP|LIN|SPL|SLIN|SPTP|CIRC)\b\s*(.*)$", re.IGNORECASE)


class KrlError(ValueError):
    """A motion statement we cannot execute; the message names the line."""


@dataclass(frozen=True)
class KrlMotion:
    kind: str  # PTP | LIN | CIRC
    target: dict[str, float]
    aux: dict[str, float] | None = None
    line: int = 0

    @property
    def is_axis(self) -> bool:
        return any(k.startswith("A") and k[1:].isdigit() for k in self.target)


def parse_aggregate(text: str) -> dict[str, float]:
    """'{X 1.5, Y -2, S 'B010'}' -> {'X': 1.5, 'Y': -2.0, 'S': 2}."""
    out: dict[str, float] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        m = re.fullmatch(r"([A-Za-z]\w*)\s+(.+)", item)
        if not m:
            raise KrlError(f"bad aggregate item {item!r}")
        key, val = m.group(1).upper(), m.group(2).strip()
        b = re.fullmatch(r"'B([01]+)'", val)
        out[key] = float(int(b.group(1), 2)) if b else float(val)
    return out


def parse_dat(text: str) -> dict[str, dict[str, float]]:
    points: dict[str, dict[str, float]] = {}
    for m in re.finditer(r"DECL\s+(?:E6POS|POS|E6AXIS|AXIS|FRAME)\s+(\w+)\s*=\s*\{([^{}]*)\}",
                         text, re.IGNORECASE):
        points[m.group(1).upper()] = parse_aggregate(m.group(2))
    return points


def parse_motions(src: str, points: dict[str, dict[str, float]]) -> list[KrlMotion]:
    out: list[KrlMotion] = []
    for no, raw in enumerate(src.splitlines(), start=1):
        line = raw.split(";", 1)[0].strip()
        m = _MOTION.match(line)
        if not m:
            continue
        kw, rest = m.group(1).upper(), m.group(2)
        kind = {"SPL": "LIN", "SLIN": "LIN", "SPTP": "PTP"}.get(kw, kw)
        args = _AGG.findall(rest)
        names = [n.upper() for n in re.findall(r"(?<![\w{])([A-Za-z_]\w*)(?![\w}])",
                                               _AGG.sub(" ", rest))
                 if n.upper() not in ("C_PTP", "C_DIS", "C_VEL", "C_ORI", "C_SPL", "CA")]
        aggs = [parse_aggregate(a) for a in args]
        for n in names:
            if n not in points:
                raise KrlError(f"line {no}: unknown point {n}")
            aggs.append(points[n])
        need = 2 if kind == "CIRC" else 1
        if len(aggs) < need:
            raise KrlError(f"line {no}: {kw} needs {need} point(s): {raw.strip()!r}")
        if kind == "CIRC":
            out.append(KrlMotion("CIRC", aggs[1], aggs[0], no))
        else:
            out.append(KrlMotion(kind, aggs[0], None, no))
    return out
