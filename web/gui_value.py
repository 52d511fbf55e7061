"""Setting a viser input's value from our code (the page shows it and sends it to every tab).

`handle.value = v` does this, but viser declares the setter apart from the getter, which a
type checker reads as a read-only property; this one function keeps that exception in one
place instead of at every assignment."""

from __future__ import annotations

from typing import Any


def set_value(handle: Any, value: Any) -> None:
    """`handle.value = value` for a viser GUI input handle."""
    handle.value = value
