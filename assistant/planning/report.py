"""What a mission plan reports: per piece and for the whole, in figures and plain words.

The operator sees `describe()`; the session and the benchmark read the numbers. When a plan
fails, `failed_piece` names the piece (a location, a transfer, an application path) and
`reason` says why in the words of the part that failed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from assistant.trajectory.assemble import TrajectoryReport


@dataclass(frozen=True)
class PieceReport:
    """One piece: a location solve, a transfer or an application path."""

    label: str
    kind: str  # "location", "transfer", "application", "ordering", "verification"
    ok: bool
    reason: str = ""
    trajectory: TrajectoryReport | None = None
    seconds: float = 0.0
    #: Roadmap query details for transfers ("roads", "free cells", "direct").
    searched: str = ""
    #: Notes such as smoothing fallbacks or an orientation projected into the arm plane.
    notes: tuple[str, ...] = ()

    def describe(self) -> str:
        head = f"{self.label}: " + ("ok" if self.ok else f"FAILED - {self.reason}")
        if self.ok and self.trajectory is not None:
            head += f" ({self.trajectory.describe()})"
        if self.notes:
            head += "; " + "; ".join(self.notes)
        return head


@dataclass(frozen=True)
class MissionPlanReport:
    ok: bool
    reason: str
    pieces: tuple[PieceReport, ...] = ()
    #: Label of the piece that failed (None if the plan is ok).
    failed_piece: str | None = None
    min_clearance: float | None = None  # m, over the whole trajectory (known obstacles)
    tcp_length: float = 0.0  # m
    joint_length: float = 0.0  # rad
    primitive_counts: dict[str, int] = field(default_factory=dict)
    planning_seconds: float = 0.0
    #: Application paths in the planned order, "(reversed)" where run backwards.
    order: tuple[str, ...] = ()
    ordering_method: str = ""
    exploring: bool = False

    @property
    def primitives(self) -> int:
        return int(sum(self.primitive_counts.values()))

    def describe(self) -> str:
        if not self.ok:
            lines = [f"mission plan FAILED at {self.failed_piece}: {self.reason}"]
        else:
            counts = ", ".join(f"{v} {k}" for k, v in self.primitive_counts.items() if v)
            clear = ("" if self.min_clearance is None
                     else f", min clearance {self.min_clearance * 1000:.1f} mm")
            lines = [f"mission plan ok in {self.planning_seconds:.2f} s: {counts}; TCP "
                     f"{self.tcp_length * 1000:.0f} mm, joints {self.joint_length:.2f} rad"
                     f"{clear}; order {' -> '.join(self.order) or '(no paths)'}"]
        lines += ["  " + p.describe() for p in self.pieces]
        return "\n".join(lines)
