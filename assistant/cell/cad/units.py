"""Length units of CAD files: names, factors to metres, and the mm-vs-m guess from the size.

Many mesh formats (STL, OBJ, PLY) carry no unit at all, and most CAD packages write them in
millimetres. A robot cell part is rarely larger than a few metres (the RV-2AJ reaches 0.41 m,
a big fixture table is ~2 m), and a part smaller than a few millimetres is rarely worth
modelling, so "largest dimension > 3 units" means millimetres. The caller can always override.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from assistant.cell.cad.errors import CadImportError

#: Length of one unit in metres, by our short unit names.
UNIT_TO_M: dict[str, float] = {
    "m": 1.0,
    "dm": 0.1,
    "cm": 0.01,
    "mm": 0.001,
    "um": 1e-6,
    "inch": 0.0254,
    "ft": 0.3048,
}

_ALIASES: dict[str, str] = {
    "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "decimeter": "dm", "decimeters": "dm", "decimetre": "dm", "decimetres": "dm",
    "centimeter": "cm", "centimeters": "cm", "centimetre": "cm", "centimetres": "cm",
    "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "micron": "um", "microns": "um", "micrometer": "um", "micrometers": "um", "µm": "um",
    "micrometre": "um", "micrometres": "um",
    "in": "inch", "inches": "inch", '"': "inch",
    "foot": "ft", "feet": "ft",
}

#: A file without a unit whose largest dimension exceeds this many units is in millimetres.
SIZE_THRESHOLD_UNITS = 3.0
#: After conversion, parts outside this range (largest dimension, metres) get a warning.
PLAUSIBLE_SIZE_M = (0.001, 20.0)


class UnitsSource(str, Enum):
    FILE = "file"  # the file states its unit (3MF, DXF $INSUNITS, glTF, STEP)
    SIZE = "size"  # guessed from the part's size
    CALLER = "caller"  # the operator said so


def normalize_unit(name: str, *, filename: str = "<units>") -> str:
    """Our short name for a unit spelled any usual way ('millimeter' -> 'mm')."""
    key = str(name).strip().lower()
    key = _ALIASES.get(key, key)
    if key not in UNIT_TO_M:
        known = ", ".join(UNIT_TO_M)
        raise CadImportError(filename, f"unknown length unit {name!r}", f"use one of {known}")
    return key


def unit_to_m(name: str) -> float:
    return UNIT_TO_M[normalize_unit(name)]


@dataclass(frozen=True)
class UnitDecision:
    """Which unit the file's numbers are in, who said so, and the factor that makes metres."""

    units: str
    source: UnitsSource
    #: Multiply the loader's numbers by this to get metres.
    scale_to_m: float
    #: What the file itself declares (None if it has no unit).
    file_units: str | None
    reason: str


def decide_units(
    *,
    filename: str,
    largest_dimension: float,
    file_units: str | None,
    caller_units: str | None,
    converted_from: str | None = None,
) -> UnitDecision:
    """Pick the unit: the caller's word first, then the file's own unit, then the size.

    `converted_from` is set when the loader already converted the numbers to metres from that
    unit (OpenCASCADE does so for STEP); an override then rescales relative to it.
    """
    already = unit_to_m(converted_from) if converted_from else None
    if caller_units is not None:
        u = normalize_unit(caller_units, filename=filename)
        scale = UNIT_TO_M[u] / already if already else UNIT_TO_M[u]
        reason = f"units set to {u} by the caller"
        if file_units and file_units != u:
            reason += f" (the file itself says {file_units})"
        return UnitDecision(u, UnitsSource.CALLER, scale, file_units, reason)
    if file_units is not None:
        scale = 1.0 if already else UNIT_TO_M[file_units]
        return UnitDecision(file_units, UnitsSource.FILE, scale, file_units,
                            f"the file states its unit: {file_units}")
    if largest_dimension > SIZE_THRESHOLD_UNITS:
        return UnitDecision(
            "mm", UnitsSource.SIZE, 0.001, None,
            f"no unit in the file; largest dimension {largest_dimension:.4g} > "
            f"{SIZE_THRESHOLD_UNITS:g}, so millimetres (give units='m' if that is wrong)")
    return UnitDecision(
        "m", UnitsSource.SIZE, 1.0, None,
        f"no unit in the file; largest dimension {largest_dimension:.4g} <= "
        f"{SIZE_THRESHOLD_UNITS:g}, so metres (give units='mm' if that is wrong)")


def size_warning(largest_dimension_m: float, decision: UnitDecision) -> str | None:
    """A warning when the converted part is implausibly small or large for a robot cell."""
    lo, hi = PLAUSIBLE_SIZE_M
    if lo <= largest_dimension_m <= hi:
        return None
    alt = "mm" if decision.units != "mm" else "m"
    return (f"the part is {largest_dimension_m:.4g} m across in {decision.units} "
            f"({decision.source.value}); if that is wrong, import again with units='{alt}'")
