"""The world model's settings and the records it hands out: `WorldConfig` (the octree sized
to the arm, `tcp_reach`), `WorldBuildReport`, `WorldChange` (what one observation changed,
for the roadmap's local update) and `RecordedCollision` (what one indication taught).

Split from `world.model` so the model holds the behaviour; it imports only the world's own
configs, the octree and the robot model.
"""

from __future__ import annotations

import contextlib
import weakref
from dataclasses import dataclass, field, replace

import numpy as np

from assistant.robots.model import Robot
from assistant.world.cell_positions import SelectionConfig
from assistant.world.contact_region import ContactRegion
from assistant.world.fusion import FusionConfig
from assistant.world.indications import IndicationConfig
from assistant.world.octree import OctreeGrid
from assistant.world.reachability import ReachabilityConfig

Array = np.ndarray


@dataclass(frozen=True)
class WorldConfig:
    """Octree geometry (thesis: 2 m cube, 62.5 mm leaves, centred on the robot base) and the
    parameters of the parts."""

    size: float = 2.0
    leaf: float = 0.0625
    #: Octree centre in the robot base frame (world -> octree is this translation).
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    reach: ReachabilityConfig = field(default_factory=ReachabilityConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    indication: IndicationConfig = field(default_factory=IndicationConfig)
    #: Cache folder for the reachability table (None: $CELLTEACH_CACHE or ~/.cache/cellteach).
    cache: str | None = None
    use_cache: bool = True
    self_collision: bool = True

    def grid(self) -> OctreeGrid:
        return OctreeGrid.for_leaf(self.size, self.leaf, self.centre)

    @staticmethod
    def for_robot(robot: Robot, *, leaf: float | None = None, **changes) -> WorldConfig:
        """Defaults sized to the arm: a cube centred on the base that holds every TCP position
        with a 0.1 m margin (at least the thesis' 2 m), 32 leaves a side unless `leaf` (m)
        asks for finer ones; other fields as given (`reach=ReachabilityConfig(...)`, ...)."""
        size = max(2.0, 2.0 * (tcp_reach(robot) + 0.1))
        size = float(np.ceil(size * 8.0) / 8.0)  # a round figure (125 mm steps)
        grid = OctreeGrid.for_leaf(size, leaf if leaf else size / 32.0)
        # one joint step moves the TCP at most half a leaf (the thesis' d_step / leaf)
        reach = replace(changes.pop("reach", ReachabilityConfig()), d_step=grid.leaf / 2.0)
        return WorldConfig(size=size, leaf=grid.leaf, reach=reach, **changes)


def tcp_reach(robot: Robot, n: int = 1 << 14) -> float:
    """Largest TCP distance (m) from the base origin over Sobol samples of the limits
    (within ~1 % of the true maximum; the cube's margin covers the rest). Remembered per
    robot and limits: every import and placement asks (~0.3 s each on the RV-2AJ)."""
    lo, hi = robot.limits.lower, robot.limits.upper
    key = (n, lo.tobytes(), hi.tobytes())
    try:
        hit = _REACH.get(robot)
    except TypeError:  # a robot that cannot be weakly referenced: not remembered
        hit = None
    if hit is not None and hit[0] == key:
        return hit[1]
    from scipy.stats import qmc

    U = qmc.Sobol(d=robot.dof, scramble=True, seed=0).random(n)
    P = np.asarray(robot.batch_fk(lo + U * (hi - lo)).positions)
    reach = float(np.linalg.norm(P, axis=1).max())
    with contextlib.suppress(TypeError):
        _REACH[robot] = (key, reach)
    return reach


#: tcp_reach's answers by robot (weakly: a replaced robot takes its entry with it).
_REACH: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class WorldBuildReport:
    table_seconds: float
    table_from_cache: bool
    cad_cells_seconds: float
    positions_seconds: float
    positions_checked: int
    leaves_reachable: int
    leaves_free: int
    leaves_occupied: int
    leaves_blocked_by_arm: int
    leaves_unresolved: int

    @property
    def total_seconds(self) -> float:
        return self.table_seconds + self.cad_cells_seconds + self.positions_seconds


@dataclass(frozen=True)
class WorldChange:
    """What one observation changed (flat leaf ids)."""

    observed_cells: Array
    occupancy_flipped: Array  # binary occupancy changed
    validity_changed: Array  # the leaf gained/lost its last valid joint position
    positions_invalidated: int = 0

    @property
    def changed_cells(self) -> Array:
        return np.union1d(self.occupancy_flipped, self.validity_changed)


@dataclass(frozen=True)
class RecordedCollision:
    """What one collision indication at posture `q` taught this world (for edge checks).
    The list of indications itself is its user's (the session's record, which a rebuilt
    world learns again); `learnt_from` finds the entry one of them made.

    With a `region` (6- and 7-axis arms, the approach known: `contact_region`) the evidence
    is that region; without, the posture box and the arm's leaves (`indications`)."""

    q: Array
    cells: Array
    region: ContactRegion | None = None
    #: Later indications at the same place whose region grew this one's (`learnt_from`).
    grown_by: tuple[Array, ...] = ()
