"""What a collision check answers with: obstacles as the checker sees them, contacts,
reports, clearances, motion checks."""


from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from assistant.robots.model import CollisionShape

Array = np.ndarray


class ObstacleView(Protocol):
    """What the checker needs of a cell object (see `cell.Cell.collision_objects_in_base`);
    read only, so frozen dataclasses (`Obstacle`, `cell.model.CollisionObjectView`) are views."""

    @property
    def name(self) -> str: ...
    @property
    def T_base_object(self) -> Array: ...
    @property
    def collision(self) -> tuple[CollisionShape, ...]: ...


@dataclass(frozen=True)
class Obstacle:
    """A plain obstacle for callers without a cell (tests, benchmarks, hidden obstacles)."""

    name: str
    T_base_object: Array
    collision: tuple[CollisionShape, ...]
    role: str = "obstacle"


@dataclass(frozen=True)
class Contact:
    """Link `link` touches `other` (an obstacle name, or another link for self-collision)."""

    link: str
    other: str
    self_collision: bool = False


@dataclass(frozen=True)
class CollisionReport:
    within_limits: bool
    contacts: tuple[Contact, ...]
    limit_violations: tuple[str, ...] = ()

    @property
    def collision_free(self) -> bool:
        return not self.contacts

    @property
    def valid(self) -> bool:
        return self.within_limits and not self.contacts

    def describe(self, words: Mapping[str, str] | None = None) -> str:
        """"link touches other; ..." - with `words` (link name -> the operator's words,
        `CollisionChecker.link_words`) the links are named as the operator knows them."""
        w = words or {}
        parts = [f"{w.get(c.link, c.link)} touches "
                 f"{w.get(c.other, c.other) if c.self_collision else c.other}"
                 for c in self.contacts]
        parts += [f"joint limit: {v}" for v in self.limit_violations]
        return "; ".join(parts) if parts else "free"


@dataclass(frozen=True)
class Clearance:
    """Smallest distance between the robot and an obstacle (negative: penetrating)."""

    distance: float
    link: str
    other: str
    point_on_link: Array = field(repr=False)
    point_on_other: Array = field(repr=False)


@dataclass(frozen=True)
class MotionCheck:
    """Result of a continuous check of the straight joint-space motion q0 -> q1."""

    first_invalid_fraction: float | None
    samples: int
    report: CollisionReport | None = None

    @property
    def valid(self) -> bool:
        return self.first_invalid_fraction is None


