"""The speed each motion of a program commands, read from the grammars' parse trees.

From the vendors' manuals, like the checkers (nothing here imports `assistant`): a setting
stays in force until set again, a motion without its own speed runs at the one in force.

- URScript: movej v (rad/s, the leading joint; default 1.05), movel/movec v (m/s; default
  0.25).
- KRL: BAS(#VEL_PTP, %) sets every $VEL_AXIS[i]; PTP runs at the largest of them (%);
  $VEL.CP (m/s) for LIN, CIRC and splines.
- MELFA: OVRD (%) scales every motion; MOV runs at JOVRD (%, default 100) x OVRD; MVS, MVR,
  MVC at SPD (mm/s) x OVRD.
- RAPID: speeddata (predefined vNNN = NNN mm/s or declared [v_tcp, ...]) is a TCP speed even
  for MoveJ/MoveAbsJ, whose joint speeds the controller keeps within its axes' own;
  VelSet override (%) and max (mm/s) apply to every motion.
- FANUC TP: J moves in % of the axes' maxima, L/C/A in mm/sec (or cm/min, inch/min);
  OVERRIDE (%) is the program's override.
- Yaskawa INFORM: MOVJ VJ= (% of the axes' maxima), MOVL/MOVC V= (mm/s).

`speeds(dialect, files)` -> one `Speed` per motion, in program order (unsplit programs:
the main file only).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from lark import Token, Tree

from grammars._base import line_of, normalise, parser

#: (dialect, the main file's suffix, the grammar's start rule)
MAIN = {"urscript": (".script", "script"), "krl": (".src", "src"), "melfa": (".mb4", "program"),
        "rapid": (".mod", "module"), "fanuc": (".ls", "ls"), "yaskawa": (".jbi", "jbi")}


@dataclass(frozen=True)
class Speed:
    """What one motion commands: `kind` "joint" or "cartesian"; `value` in `unit` ("%" of
    the axes' maxima, "rad/s" of the leading axis, "mm/s" or "m/s" of the TCP; for a RAPID
    joint move "tcp mm/s", its TCP speed, the axes being the controller's to limit)."""

    kind: str
    value: float
    unit: str
    line: int | None


def speeds(dialect: str, files: dict[str, str]) -> list[Speed]:
    suffix, start = MAIN[dialect]
    main = [n for n in files if n.lower().endswith(suffix)]
    if len(main) != 1:
        raise ValueError(f"expected one {suffix} file among {', '.join(files)}")
    tree = parser(dialect).parse(normalise(files[main[0]]), start=start)
    return {"urscript": _urscript, "krl": _krl, "melfa": _melfa, "rapid": _rapid,
            "fanuc": _fanuc, "yaskawa": _yaskawa}[dialect](tree)


def _num(node) -> float:
    """A `number` tree or a NUMBER token as a float."""
    if isinstance(node, Tree):
        node = node.children[0]
    return float(str(node))


# ------------------------------------------------------------------------------ URScript
def _urscript(tree: Tree) -> list[Speed]:
    out = []
    for call in tree.find_data("call"):
        name = str(call.children[0])
        if name not in ("movej", "movel", "movec", "movep"):
            continue
        kw = {str(a.children[0]): a.children[1] for a in call.children[1:]
              if isinstance(a, Tree) and a.data == "keyword"}
        joint = name == "movej"
        v = _num(kw["v"]) if "v" in kw else (1.05 if joint else 0.25)
        out.append(Speed("joint" if joint else "cartesian", v, "rad/s" if joint else "m/s",
                         line_of(call)))
    return sorted(out, key=lambda s: s.line or 0)


# ------------------------------------------------------------------------------ KRL
def _krl(tree: Tree) -> list[Speed]:
    axes: dict[int, float] = {}
    cp: float | None = None
    out = []
    for st in tree.children:
        if not isinstance(st, Tree):
            continue
        if st.data == "bas" and str(st.children[0]).upper() == "#VEL_PTP":
            pct = _num(st.children[1])
            axes = {i: pct for i in range(1, 7)}
        elif st.data == "assign":
            var = str(st.children[0]).upper()
            field = [str(c).upper() for c in st.children[1:-1] if isinstance(c, Token)]
            if var == "$VEL" and field[:1] == ["CP"]:
                cp = _num(st.children[-1])
            elif var == "$VEL_AXIS" and field:
                axes[int(field[-1])] = _num(st.children[-1])
        elif st.data == "ptp":
            out.append(Speed("joint", max(axes.values(), default=100.0), "%", line_of(st)))
        elif st.data in ("lin", "circ", "spline"):
            if cp is None:
                raise ValueError(f"line {line_of(st)}: a CP motion before any $VEL.CP")
            out.append(Speed("cartesian", cp, "m/s", line_of(st)))
    return out


# ------------------------------------------------------------------------------ MELFA
def _melfa(tree: Tree) -> list[Speed]:
    ovrd, jovrd, spd = 100.0, 100.0, None
    out = []
    for step in tree.find_data("step"):
        st = next((c for c in step.children if isinstance(c, Tree)), None)
        if st is None:
            continue
        if st.data == "ovrd":
            ovrd = _num(st.children[0])
        elif st.data == "jovrd":
            jovrd = _num(st.children[0])
        elif st.data == "spd":
            spd = _num(st.children[0]) if st.children else None
        elif st.data == "mov":
            out.append(Speed("joint", jovrd * ovrd / 100.0, "%", line_of(st)))
        elif st.data in ("mvs", "mvr", "mvr2", "mvr3", "mvc"):
            if spd is None:
                raise ValueError(f"line {line_of(st)}: a linear motion before any SPD")
            out.append(Speed("cartesian", spd * ovrd / 100.0, "mm/s", line_of(st)))
    return out


# ------------------------------------------------------------------------------ RAPID
def _rapid(tree: Tree) -> list[Speed]:
    declared: dict[str, float] = {}
    for d in tree.find_data("data_decl"):
        names = [c for c in d.children if isinstance(c, Token) and c.type == "NAME"]
        value = d.children[-1]
        if len(names) >= 2 and str(names[0]).lower() == "speeddata" and \
                isinstance(value, Tree) and value.data == "aggregate":
            declared[str(names[1]).upper()] = _num(value.children[0])
    override, vmax = 100.0, float("inf")
    out = []
    for routine in tree.find_data("routine"):
        for st in routine.children:
            if not isinstance(st, Tree):
                continue
            if st.data == "velset":
                override, vmax = _num(st.children[0]), _num(st.children[1])
                continue
            if st.data not in ("movej", "movel", "movec", "moveabsj"):
                continue
            sp = next(c for c in st.children if isinstance(c, Tree) and c.data == "speed")
            name = str(sp.children[0]).upper()
            if len(sp.children) > 1:  # \V:= overrides the TCP speed
                v = _num(sp.children[1])
            elif name in declared:
                v = declared[name]
            elif m := re.fullmatch(r"V(\d+)", name):
                v = float(m.group(1))
            else:
                raise ValueError(f"line {line_of(st)}: speeddata {name} is not declared")
            v = min(v * override / 100.0, vmax)
            joint = st.data in ("movej", "moveabsj")
            out.append(Speed("joint" if joint else "cartesian", v,
                             "tcp mm/s" if joint else "mm/s", line_of(st)))
    return out


# ------------------------------------------------------------------------------ FANUC
_FANUC_UNITS = {"%": ("%", 1.0), "mm/sec": ("mm/s", 1.0), "cm/min": ("mm/s", 10.0 / 60.0),
                "inch/min": ("mm/s", 25.4 / 60.0)}


def _fanuc(tree: Tree) -> list[Speed]:
    override = 100.0
    out = []
    for line in tree.find_data("mn_line"):
        ins = next((c for c in line.children if isinstance(c, Tree)), None)
        if ins is None:
            continue
        if ins.data == "override":
            m = re.fullmatch(r"(\d+\.?\d*)%", str(ins.children[0]))
            override = float(m.group(1)) if m else override
            continue
        if ins.data != "motion":
            continue
        kind = "joint" if str(ins.children[0]) == "J" else "cartesian"
        sp = next(c for c in ins.children if isinstance(c, Tree) and c.data == "speed")
        m = re.fullmatch(r"(\d+\.?\d*|\.\d+)(%|mm/sec|cm/min|inch/min)", str(sp.children[0]))
        if m is None:
            raise ValueError(f"line {line_of(ins)}: speed {sp.children[0]} is not a value "
                             "this reader turns into a speed")
        unit, scale = _FANUC_UNITS[m.group(2)]
        out.append(Speed(kind, float(m.group(1)) * scale * override / 100.0, unit,
                         line_of(ins)))
    return out


# ------------------------------------------------------------------------------ INFORM
def _yaskawa(tree: Tree) -> list[Speed]:
    """An arc is three MOVC (its start, via and end point): one motion, at the fastest of
    their V= (each holds for the stretch into its point)."""
    vj: float | None = None
    v: float | None = None
    out: list[Speed] = []
    arc: list[Speed] = []
    for mv in tree.find_data("move"):
        word = str(mv.children[0])
        tags = {str(t.children[0]): _num(t.children[1]) for t in mv.children[1:]
                if isinstance(t, Tree) and t.data == "valued"}
        if word == "MOVJ":
            vj = tags.get("VJ=", vj)
            if vj is None:
                raise ValueError(f"line {line_of(mv)}: MOVJ without VJ=")
            out.append(Speed("joint", vj, "%", line_of(mv)))
        else:
            v = tags.get("V=", v)
            if v is None:
                raise ValueError(f"line {line_of(mv)}: {word} without V=")
            sp = Speed("cartesian", v, "mm/s", line_of(mv))
            if word != "MOVC":
                out.append(sp)
                continue
            arc.append(sp)
            if len(arc) == 3:
                out.append(max(arc, key=lambda a: a.value))
                arc = []
    if arc:
        raise ValueError(f"line {arc[0].line}: an arc of {len(arc)} MOVC, not 3")
    return out
