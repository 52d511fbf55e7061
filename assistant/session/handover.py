"""`hand_over`: a `Session` verb that is one line - the same verb of one of its parts.

The session is a front over composed parts (`session.setup`, `session.planning`, ...). Its
verbs stay where the page and the scripts call them (`session.plan()`), each handed over to
the part that owns the work (`session.planning.plan()`), with the part's signature and
docstring, so a type checker reads `session.plan` exactly as `PlanningPart.plan`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Concatenate, Generic, ParamSpec, TypeVar, overload

P = ParamSpec("P")
R = TypeVar("R")
T = TypeVar("T")


class HandOver(Generic[T, P, R]):
    """A method of the session that calls `getattr(session, part).<name>` (see the module)."""

    def __init__(self, part: str, method: Callable[Concatenate[T, P], R]) -> None:
        self.part = part
        self.name = method.__name__
        self.__doc__ = method.__doc__
        self.__wrapped__ = method

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> HandOver[T, P, R]: ...
    @overload
    def __get__(self, obj: object, owner: type | None = None) -> Callable[P, R]: ...
    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        return getattr(getattr(obj, self.part), self.name)


def hand_over(part: str, method: Callable[Concatenate[T, P], R]) -> HandOver[T, P, R]:
    """`verb = hand_over("planning", PlanningPart.plan)`: `session.verb(...)` is
    `session.planning.plan(...)`."""
    return HandOver(part, method)


class Forward(Generic[R]):
    """An attribute of the session that lives in one of its parts (read and written there):
    `halted = Forward[bool]("setup", "halted")`."""

    def __init__(self, part: str, name: str) -> None:
        self.part = part
        self.name = name

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> Forward[R]: ...
    @overload
    def __get__(self, obj: object, owner: type | None = None) -> R: ...
    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        return getattr(getattr(obj, self.part), self.name)

    def __set__(self, obj: Any, value: R) -> None:
        setattr(getattr(obj, self.part), self.name, value)
