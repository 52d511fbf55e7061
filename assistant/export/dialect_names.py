"""The dialects' names, the short labels operators know them by and the axis counts each
controller runs: the table a dialect's own checks read (which other dialect would take this
arm?) without importing the other dialects, and the registry builds on."""

from __future__ import annotations

#: Default instance of each dialect (settings as in the modules' docstrings).
DIALECT_NAMES = ("melfa", "krl", "rapid", "urscript", "fanuc", "yaskawa")

#: Short names for messages ("choose MELFA, KRL or RAPID").
_LABELS = {"melfa": "MELFA", "krl": "KRL", "rapid": "RAPID", "urscript": "URScript",
           "fanuc": "FANUC", "yaskawa": "Yaskawa"}

#: The arms' axis counts each dialect's controller runs (each dialect's `axis_counts`).
AXIS_COUNTS: dict[str, tuple[int, ...]] = {
    "melfa": (4, 5, 6), "krl": (4, 5, 6, 7), "rapid": (4, 5, 6, 7), "urscript": (6,),
    "fanuc": (4, 5, 6), "yaskawa": (4, 5, 6)}


def dialect_label(name: str) -> str:
    """The short name an operator knows a dialect by: "melfa" -> "MELFA"."""
    return _LABELS.get(name, name)
