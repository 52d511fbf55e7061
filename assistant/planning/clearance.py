"""Where a planned transfer comes closer to a known obstacle than the operator's clearance.

The planner verifies every transfer collision-free; "verified" at 0.6 mm is not what an
operator means by safe. Each transfer whose smallest clearance is below the required one
(`WorldSettings.clearance_mm`, default 10 mm) is reported with where (TCP in the world frame,
which link and which obstacle) and by how much, so the page and the report can say it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.planning.pieces import PieceKind, PlanPiece

Array = np.ndarray


@dataclass(frozen=True)
class ClearanceShortfall:
    label: str  # the transfer, e.g. "START -> SEAM"
    clearance: float  # m, the smallest along the transfer
    required: float  # m
    link: str
    obstacle: str
    tcp_world: Array  # (3,) m

    def describe(self) -> str:
        x, y, z = (1000.0 * self.tcp_world).round().astype(int)
        short = 1000.0 * (self.required - self.clearance)
        return (f"{self.label} passes {self.clearance * 1000:.1f} mm from {self.obstacle} "
                f"({self.link}; TCP near {x}, {y}, {z} mm), {short:.1f} mm short of the "
                f"required {self.required * 1000:.0f} mm")


def clearance_shortfalls(pieces: list[PlanPiece], checker: CollisionChecker, required: float,
                         T_world_base: Array, samples: int = 120) -> list[ClearanceShortfall]:
    """Transfers closer than `required` (m) to a known obstacle, with the closest posture
    among `samples` evenly spaced ones of the dense path."""
    out: list[ClearanceShortfall] = []
    if required <= 0.0:
        return out
    for piece in pieces:
        if piece.kind != PieceKind.TRANSFER:
            continue
        dense = piece.dense()
        if len(dense) == 0:
            continue
        smallest = checker.min_clearance_along(list(dense))
        if smallest >= required:
            continue
        idx = np.unique(np.linspace(0, len(dense) - 1, min(samples, len(dense))).astype(int))
        best = None
        for q in dense[idx]:
            c = checker.clearance(q)
            if c is not None and (best is None or c.distance < best[0].distance):
                best = (c, q)
        if best is None:
            continue
        c, q = best  # where: the closest of the samples; how close: the whole path's figure
        tcp = (np.asarray(T_world_base, float) @ checker.robot.fk(q))[:3, 3]
        out.append(ClearanceShortfall(piece.label, float(smallest), required, c.link,
                                      c.other, tcp))
    return out
