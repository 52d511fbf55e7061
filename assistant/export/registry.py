"""Dialects by name: one place that knows every program language we write."""

from __future__ import annotations

from assistant.export.dialect import Dialect
from assistant.export.fanuc import FanucDialect
from assistant.export.krl import KrlDialect
from assistant.export.melfa import MelfaDialect
from assistant.export.rapid import RapidDialect
from assistant.export.urscript import URScriptDialect
from assistant.export.yaskawa import YaskawaDialect

#: Default instance of each dialect (settings as in the modules' docstrings).
DIALECT_NAMES = ("melfa", "krl", "rapid", "urscript", "fanuc", "yaskawa")

#: Short names for messages ("choose MELFA, KRL or RAPID").
_LABELS = {"melfa": "MELFA", "krl": "KRL", "rapid": "RAPID", "urscript": "URScript",
           "fanuc": "FANUC", "yaskawa": "Yaskawa"}


def dialect_label(name: str) -> str:
    """The short name an operator knows a dialect by: "melfa" -> "MELFA"."""
    return _LABELS.get(name, name)


def get_dialect(dialect: str | Dialect) -> Dialect:
    """A dialect instance by name (`DIALECT_NAMES`), or the one given."""
    if not isinstance(dialect, str):
        return dialect
    key = dialect.lower()
    factories = {"melfa": MelfaDialect, "krl": KrlDialect, "rapid": RapidDialect,
                 "urscript": URScriptDialect, "fanuc": FanucDialect, "yaskawa": YaskawaDialect}
    if key not in factories:
        raise ValueError(f"unknown dialect {dialect!r}; choose one of {', '.join(DIALECT_NAMES)}")
    return factories[key]()
