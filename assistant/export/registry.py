"""Dialects by name: one place that knows every program language we write."""

from __future__ import annotations

from assistant.export.dialect import Dialect
from assistant.export.dialect_names import DIALECT_NAMES, dialect_label
from assistant.export.fanuc import FanucDialect
from assistant.export.krl import KrlDialect
from assistant.export.melfa import MelfaDialect
from assistant.export.rapid import RapidDialect
from assistant.export.urscript import URScriptDialect
from assistant.export.yaskawa import YaskawaDialect

__all__ = ["DIALECT_NAMES", "dialect_label", "get_dialect"]


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
