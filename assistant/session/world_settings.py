"""The world model's settings as the operator, a script and the page see them (mm, MB, counts).

Defaults suit every robot: the octree cube is sized to the arm (`WorldConfig.for_robot`), the
joint positions come from the full joint grid where it is small (the RV-2AJ) and from a fixed
sample budget otherwise (`world.joint_samples`), and the store's memory is bounded. Changing a
setting makes the world model stale (it is rebuilt on the next build or plan).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

from assistant.robots.model import Robot

STORES = ("auto", "grid", "samples")


@dataclass(frozen=True)
class WorldSettings:
    #: Octree leaf edge (mm); None: the cube sized to the arm with 32 leaves a side.
    resolution_mm: float | None = None
    #: Joint positions sampled for the sampled store (6- and 7-axis arms).
    joint_samples: int = 1 << 21
    #: Memory the joint-position store may take (MB).
    memory_mb: int = 1536
    #: "auto", "grid" (the thesis' full joint grid) or "samples".
    store: str = "auto"
    #: Clearance (mm) transfers keep from known obstacles where the cell allows it.
    clearance_mm: float = 10.0
    #: The bound of every run (`planning.run_bounds`): collision indications, and seconds
    #: of planning. Not the world's: changing them rebuilds nothing (compare=False keeps
    #: them out of the world's key).
    max_indications: int = field(default=20, compare=False)
    planning_budget_s: float = field(default=120.0, compare=False)

    def __post_init__(self) -> None:
        if self.resolution_mm is not None and not 10.0 <= float(self.resolution_mm) <= 250.0:
            raise ValueError(f"resolution {self.resolution_mm} mm: use 10-250 mm "
                             "(or leave it empty for the default)")
        if not 10_000 <= int(self.joint_samples) <= 50_000_000:
            raise ValueError(f"joint samples {self.joint_samples}: use 10 000 - 50 000 000")
        if not 64 <= int(self.memory_mb) <= 65_536:
            raise ValueError(f"memory budget {self.memory_mb} MB: use 64 - 65 536 MB")
        if self.store not in STORES:
            raise ValueError(f"joint-position store {self.store!r}: use one of "
                             + ", ".join(STORES))
        if not 0.0 <= float(self.clearance_mm) <= 200.0:
            raise ValueError(f"clearance {self.clearance_mm} mm: use 0-200 mm")
        if not 1 <= int(self.max_indications) <= 1000:
            raise ValueError(f"{self.max_indications} indications per run: use 1-1000")
        if not 1.0 <= float(self.planning_budget_s) <= 3600.0:
            raise ValueError(f"{self.planning_budget_s} s of planning per run: use 1-3600 s")

    def changed(self, **changes: Any) -> WorldSettings:
        """A copy with `changes` (unknown names refused with the known ones)."""
        names = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise ValueError(f"unknown world setting {', '.join(unknown)}: use "
                             + ", ".join(sorted(names)))
        if changes.get("resolution_mm") in ("", 0):
            changes["resolution_mm"] = None
        for k in ("joint_samples", "memory_mb", "max_indications"):
            if k in changes:
                changes[k] = int(changes[k])
        for k in ("resolution_mm", "clearance_mm", "planning_budget_s"):
            if changes.get(k) is not None and k in changes:
                changes[k] = float(changes[k])
        return replace(self, **changes)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @staticmethod
    def from_json(d: dict[str, Any]) -> WorldSettings:
        return WorldSettings().changed(**d)

    def world_config(self, robot: Robot) -> Any:
        """The `WorldConfig` these settings ask for on this robot."""
        from assistant.world.model import WorldConfig
        from assistant.world.reachability import ReachabilityConfig

        reach = ReachabilityConfig(store=self.store, samples=int(self.joint_samples),
                                   memory_mb=int(self.memory_mb))
        leaf = None if self.resolution_mm is None else self.resolution_mm / 1000.0
        return WorldConfig.for_robot(robot, leaf=leaf, reach=reach)
