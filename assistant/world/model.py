"""`WorldModel`: the octree, fusion, reachability table and valid joint positions of one cell.

Building (`build`) loads or computes the reachability table, rasterises the CAD obstacles into
leaves (CAD observations through the fusion), and finds the valid joint positions per free
leaf (every link checked against CAD with FCL, see `chain_levels`). Afterwards the world
changes only through observations: `indicate_collision` (the operator's button) and
`observe` (sensors, camera). Each returns what changed, so the roadmap can update locally.

Planners read dense grid views: `occupancy()` (fused P per leaf from the octree), `occupied()`,
`reachable()`, `has_valid()`, `object_ids()`, and the selected positions `cell_positions()`.
A leaf is *free* for the roadmap if it has a valid joint position and P < threshold.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence

import numpy as np

from assistant.collision.reports import ObstacleView
from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.world.cell_positions import CellPositions
from assistant.world.chain_levels import ChainValidator
from assistant.world.contact_region import ContactRegion, carve, grown, learn_region
from assistant.world.fusion import FusionUpdate, OccupancyFusion, Source
from assistant.world.hand_cells import HandCells
from assistant.world.indications import (
    indicated_cells,
    near_posture,
    nearby_positions,
    posture_box_half,
)
from assistant.world.leaf_store import JointStore
from assistant.world.model_types import (
    RecordedCollision,
    WorldBuildReport,
    WorldChange,
    WorldConfig,
    tcp_reach,
)
from assistant.world.octree import LinearOctree
from assistant.world.rasterise import rasterise_obstacles
from assistant.world.reachability import is_cached, load_or_build
from assistant.world.region_checks import RegionChecks, indication_name

Array = np.ndarray

__all__ = ["OBSERVED_ID", "RecordedCollision", "WorldBuildReport", "WorldChange",
           "WorldConfig", "WorldModel", "tcp_reach"]

#: object_ids() value for cells occupied by non-CAD evidence (button, sensors, camera).
OBSERVED_ID = -1


class WorldModel:
    """See the module docstring. Not thread-safe: one planner thread owns it."""

    def __init__(self, robot: Robot, cad: Iterable[ObstacleView] = (),
                 config: WorldConfig | None = None, *, store: JointStore | None = None):
        self.robot = robot
        #: A store loaded once for this robot and config and shared read-only (a placement
        #: study builds one world per candidate); None: `build` loads it (disk cache).
        self._shared_store = store
        self.config = config or WorldConfig()
        self.grid = self.config.grid()
        self.cad = list(cad)
        self.octree = LinearOctree(self.grid)
        self.fusion = OccupancyFusion(self.config.fusion)
        self.table: JointStore | None = None
        self.positions: CellPositions | None = None
        self.cad_cells: dict[str, Array] = {}
        self.collisions: list[RecordedCollision] = []
        self.weights = robot.arm_radii()
        self._object_ids = np.zeros(self.grid.n_cells, dtype=np.int32)
        self._cad_leaves: tuple[Array, Array] | None = None  # `cad_leaves`
        #: Postures (the taught ones) the sampled store's leaves list their positions
        #: toward (`SampledTable.toward`); ignored by the joint grid.
        self.anchors: Array | None = None
        self._hand: HandCells | None = None
        #: recorded collision index -> (that record, the leaves its hand filled)
        self._hand_cells: dict[int, tuple[RecordedCollision, Array]] = {}
        self._regions = RegionChecks(robot, self.config.indication.region.clearance)
        #: What the last indication taught, in the operator's words (`indicate_collision`).
        self.last_learnt: str = ""

    @property
    def built(self) -> bool:
        return self.positions is not None

    @property
    def sampled(self) -> bool:
        """Whether the built store holds joint samples (6- and 7-axis arms) rather than the
        thesis' joint grid: the planners' rules for direct moves and edge length differ."""
        return self.table is not None and self.table.kind == "samples"

    @property
    def threshold(self) -> float:
        return self.config.fusion.threshold

    # ---------------------------------------------------------------- build
    def build(self, progress: Progress | None = None) -> WorldBuildReport:
        """Table (cached) + CAD cells + valid joint positions; raises `Cancelled`, leaving the
        model as it was."""
        progress = progress or Progress("world model")
        t0 = time.perf_counter()
        cached = self._shared_store is not None or (self.config.use_cache and is_cached(
            self.robot, self.grid, self.config.reach, self.config.cache))
        table = self._shared_store if self._shared_store is not None else load_or_build(
            self.robot, self.grid, self.config.reach, progress.sub(0.0, 0.4),
            cache=self.config.cache, use_cache=self.config.use_cache)
        if table.kind == "samples" and self.anchors is not None and len(self.anchors):
            cfg = self.config.reach
            table = table.focused(self.robot, self.anchors, cfg.focus_samples,
                                  cfg.focus_margin).toward(self.anchors, self.weights)
        table.index_of_ids(np.zeros(0, dtype=np.int64))  # build the inverse map now, not
        # during the first collision indication; likewise the sample store's box queries
        prepare = getattr(table, "prepare_box_queries", None)
        if prepare is not None:
            prepare()
        t1 = time.perf_counter()
        progress.update(0.4, "rasterising CAD")
        cad_cells = rasterise_obstacles(self.grid, self.cad)
        t2 = time.perf_counter()
        validator = ChainValidator(self.robot, self.cad, table,
                                   self_collision=self.config.self_collision)
        positions = CellPositions(table, validator, self.config.selection)
        # Commit nothing until the expensive, cancellable part is done.
        fusion = OccupancyFusion(self.config.fusion)
        octree = LinearOctree(self.grid)
        object_ids = np.zeros(self.grid.n_cells, dtype=np.int32)
        for i, (name, cells) in enumerate(cad_cells.items()):
            del name
            if len(cells):
                upd = fusion.observe(Source.CAD, self.grid.codes_of_flat(cells).astype(np.int64),
                                     1.0)
                octree.set_leaves(upd.cells.astype(np.uint64), upd.after)
                fresh = object_ids[cells] == 0
                object_ids[cells[fresh]] = i + 1
        occupied = octree.to_dense().reshape(-1) >= self.threshold
        slots = np.flatnonzero(~occupied[table.leaves])
        fill = positions.fill(slots, progress.sub(0.45, 1.0, "valid joint positions"))
        t3 = time.perf_counter()
        self.table, self.positions, self.cad_cells = table, positions, cad_cells
        self.fusion, self.octree, self._object_ids = fusion, octree, object_ids
        self.collisions = []
        free = self.free().sum()
        progress.update(1.0, "world model ready", force=True)
        return WorldBuildReport(
            table_seconds=t1 - t0, table_from_cache=cached, cad_cells_seconds=t2 - t1,
            positions_seconds=t3 - t2, positions_checked=fill.checked,
            leaves_reachable=len(table.leaves), leaves_free=int(free),
            leaves_occupied=int(occupied.sum()),
            leaves_blocked_by_arm=fill.exhausted_blocked, leaves_unresolved=fill.unresolved)

    def _need(self) -> tuple[JointStore, CellPositions]:
        if self.table is None or self.positions is None:
            raise RuntimeError("build the world model first (WorldModel.build)")
        return self.table, self.positions

    # ---------------------------------------------------------------- grid views
    def occupancy(self) -> Array:
        """Dense float32 grid of fused occupancy probabilities P."""
        return self.octree.to_dense()

    def occupied(self) -> Array:
        return self.occupancy() >= self.threshold

    def reachable(self) -> Array:
        return self._need()[0].reachable()

    def has_valid(self) -> Array:
        return self._need()[1].has_valid()

    def free(self) -> Array:
        """Leaves the roadmap may use: a valid joint position and P < threshold."""
        return self.has_valid() & ~self.occupied()

    def object_ids(self) -> Array:
        """Dense int32 grid: i + 1 for leaves of CAD object i (in `cad` order), OBSERVED_ID for
        leaves occupied by other evidence, 0 elsewhere."""
        ids = self._object_ids.copy()
        occ = self.occupied().reshape(-1)
        ids[occ & (ids == 0)] = OBSERVED_ID
        return ids.reshape(self.grid.shape)

    def cad_leaves(self) -> Array:
        """Flat bool grid: leaves of a CAD object (`object_ids` > 0), read only; the same
        array until the CAD is rasterised again (a planning query asks every time)."""
        ids = self._object_ids
        if self._cad_leaves is None or self._cad_leaves[0] is not ids:
            leaves = ids > 0
            leaves.setflags(write=False)
            self._cad_leaves = (ids, leaves)
        return self._cad_leaves[1]

    def object_names(self) -> list[str]:
        return [ob.name for ob in self.cad]

    def cell_positions(self) -> tuple[Array, Array, Array]:
        """(cells, offsets, Q): selected valid joint positions (rad) grouped by flat leaf id."""
        return self._need()[1].selected_joints()

    def cell_positions_shared(self) -> tuple[Array, Array, Array]:
        """`cell_positions` without the copies, for callers that only read them (the
        roadmap's search graph; the copies cost ~0.03 ms a query). Do not write to them."""
        return self._need()[1].decode()

    def decode_positions(self) -> None:
        """Decode the selected positions' joint values now (`cell_positions` remembers them
        until the selection changes): the roadmap does it when it builds or updates, so the
        first query after does not pay ~2.5 ms for it."""
        self._need()[1].decode()

    def tcp_cell(self, q: Array) -> int:
        """Flat leaf id of the TCP at q, -1 outside the octree."""
        return int(self.grid.flat_of_points(self.robot.fk(np.asarray(q, dtype=float))[:3, 3])[0])

    def tcp_cells(self, Q: Array) -> Array:
        """`tcp_cell` of each row of Q (M, dof) in one batch FK; -1 also for a row that is
        not all finite (a planning query's start and goal: ~0.03 ms less than one by one)."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        finite = np.isfinite(Q).all(axis=1)
        out = np.full(len(Q), -1, dtype=np.int64)
        if finite.any():
            P = np.asarray(self.robot.batch_fk(Q[finite]).positions)
            out[finite] = self.grid.flat_of_points(P)
        return out

    # ---------------------------------------------------------------- observations
    def _apply(self, source: Source, cells: Array, values: Array | float) -> FusionUpdate:
        codes = self.grid.codes_of_flat(cells).astype(np.int64)
        upd = self.fusion.observe(source, codes, values)
        self.octree.set_leaves(upd.cells.astype(np.uint64), upd.after)
        return upd

    def observe(self, source: Source | str, points_base: Array, values: Array | float,
                progress: Progress | None = None) -> WorldChange:
        """Occupancy observations (o in [0, 1]) at points from a sensor or the camera."""
        table, positions = self._need()
        flat = self.grid.flat_of_points(points_base)
        vals = np.broadcast_to(np.asarray(values, dtype=float), flat.shape)
        keep = flat >= 0
        flat, vals = flat[keep], vals[keep]
        if not len(flat):
            empty = np.zeros(0, dtype=np.int64)
            return WorldChange(empty, empty, empty)
        upd = self._apply(Source(source), flat, vals)
        flipped = self.grid.flat_of_codes(upd.flipped.astype(np.uint64))
        # Leaves that became free may need their positions (never filled while occupied).
        changed_valid = self._refill(flipped, progress)
        return WorldChange(np.unique(flat), np.unique(flipped), changed_valid)

    def indicate_collision(self, q: Array, progress: Progress | None = None, *,
                           approach: Array | None = None,
                           protected: Sequence[tuple[str, Array]] = ()) -> WorldChange:
        """The operator pressed the collision button with the arm at q (see `indications`).

        With `approach` (the postures the arm went through, ending at q) on a 6- or 7-axis
        arm (either store) the indication teaches the swept region of the last check step
        (`contact_region`), without the arm at `protected` postures (label, q); else the
        posture box and the arm's leaves. `last_learnt` says what was learnt."""
        table, positions = self._need()
        q = np.asarray(q, dtype=float)
        if approach is not None and self.robot.dof >= 6 and len(approach) >= 2 and \
                self.config.indication.learn_regions:
            change = self._learn_region(q, np.asarray(approach, dtype=float), list(protected))
            if change is not None:
                return change
        cfg = self.config.indication
        cells = indicated_cells(self.robot, self.grid, q, cfg)
        upd = self._apply(Source.BUTTON, cells, cfg.value)
        flipped = self.grid.flat_of_codes(upd.flipped.astype(np.uint64))
        near = nearby_positions(table, q, cfg.joint_steps)
        slots = positions.slots_of(near)
        before = positions.n_selected[slots] > 0
        # Record first: a cancelled refill below must not lose the evidence.
        self.collisions.append(RecordedCollision(q.copy(), cells))
        self.last_learnt = (f"{indication_name(len(self.collisions) - 1)}: the postures "
                            "around the stop are learnt as blocked")
        positions.invalidate(near)
        # refill every affected leaf, occupied ones too: the planner may still use positions
        # of occupied leaves around its start (to leave the region it just marked)
        positions.fill(slots, progress)
        after = positions.n_selected[slots] > 0
        lost = table.leaves[slots[before != after]]
        return WorldChange(cells, np.unique(flipped), np.unique(lost), len(near))

    def _learn_region(self, q: Array, approach: Array,
                      protected: list[tuple[str, Array]]) -> WorldChange | None:
        """`indicate_collision` by the swept region; None if the step swept nothing new.

        Indicated again at the same place, the region grows; if it then touches a protected
        posture the operator's word is needed: the region holds it (the re-plan names it,
        `forget_collision` drops it) rather than an endless loop of the same contact."""
        cfg = self.config.indication
        rcfg = cfg.region
        try:
            arm = self._regions.arm
        except ValueError:  # no capsule model of this arm: the posture box
            return None
        region, q0 = learn_region(self.robot, arm, approach, self.weights, cfg.first_link,
                                  rcfg, protected)
        empty = np.zeros(0, dtype=np.int64)
        if region is None:
            return None
        same = [i for i, rc in enumerate(self.collisions) if rc.region is not None
                and rc.region.distance_to(region) <= rcfg.repeat_distance]
        start = [("the posture the last step started from", q0)]
        if same:
            i = same[0]
            old = self.collisions[i]
            assert old.region is not None
            promote = bool(old.region.cut_for or region.cut_for) and \
                old.region.hits + 1 >= rcfg.hold_after
            region = grown(old.region, region, rcfg, promote=promote)
            region = carve(arm, region, rcfg, start, withhold=False)
            if not promote:
                region = carve(arm, region, rcfg, protected)
            self.collisions[i] = RecordedCollision(old.q, old.cells, region,
                                                   (*old.grown_by, q.copy()))
            what = (f"{indication_name(i)} indicated again at the same place: its region "
                    f"grows (spheres of {region.radius * 1000:.0f} mm)")
            if promote:
                what += (" and now holds the place next to the arm at "
                         + ", ".join(region.cut_for) + f" - forget {indication_name(i)} "
                         "if nothing is there")
        else:
            i = len(self.collisions)
            cells = self._region_leaves(q, region, start + protected)
            self.collisions.append(RecordedCollision(q.copy(), cells, region))
            what = f"{indication_name(i)}: {self.describe_region(i)}"
            if region.cut_for:
                what += ("; not learnt where it would touch the arm at "
                         + ", ".join(region.cut_for) + " (kept reachable)")
        self.last_learnt = what
        cells = self.collisions[i].cells
        if not len(cells):
            return WorldChange(empty, empty, empty)
        upd = self._apply(Source.BUTTON, cells, cfg.value)
        flipped = self.grid.flat_of_codes(upd.flipped.astype(np.uint64))
        return WorldChange(cells, np.unique(flipped), self._refill(flipped, None))

    def _region_leaves(self, q: Array, region: ContactRegion,
                       protected: Sequence[tuple[str, Array]]) -> Array:
        """Leaves the roads then avoid: those the arm filled at the stop and those the
        region's centres lie in (`indications.indicated_cells`), but the leaves a protected
        posture's TCP is in. They guide the search round the place (without them the lazy
        search tries edge after edge through it); what is valid the region decides."""
        flat = self.grid.flat_of_points(region.centres)
        flat = np.union1d(flat[flat >= 0], indicated_cells(self.robot, self.grid, q,
                                                           self.config.indication))
        Q = [np.atleast_2d(q) for _, q in protected]
        if Q:
            flat = np.setdiff1d(flat, self.tcp_cells(np.concatenate(Q)))
        return flat.astype(np.int64)

    def describe_region(self, i: int) -> str:
        """Recorded collision i's learnt region in the operator's words (mm)."""
        r = self.collisions[i].region
        if r is None:
            return "the postures around the stop"
        if not len(r.centres):
            return "nothing yet (all of it next to the arm at " + ", ".join(r.cut_for) + ")"
        lo, hi = r.centres.min(axis=0) - r.radius, r.centres.max(axis=0) + r.radius
        c = (lo + hi) / 2.0 * 1000.0
        size = (hi - lo) * 1000.0
        return (f"a region of {size[0]:.0f} x {size[1]:.0f} x {size[2]:.0f} mm around "
                f"({c[0]:.0f}, {c[1]:.0f}, {c[2]:.0f}) mm (robot base)")

    def learnt_from(self, q: Array, nth: int = 0) -> int | None:
        """Index of the recorded collision learnt from posture `q` (bit for bit: the same
        reading) or whose region it grew, the `nth` such from 0 when that posture was
        indicated again; None when this world never learnt it."""
        hits = [i for i, rc in enumerate(self.collisions)
                for p in (rc.q, *rc.grown_by) if np.array_equal(p, q)]
        return hits[nth] if nth < len(hits) else None

    def forget_collision(self, i: int) -> WorldChange:
        """Drop recorded collision i (0-based) and everything it taught."""
        table, positions = self._need()
        if not 0 <= i < len(self.collisions):
            raise IndexError(f"no {indication_name(i)}: {len(self.collisions)} recorded")
        rc = self.collisions.pop(i)
        self._hand_cells.clear()
        empty = np.zeros(0, dtype=np.int64)
        if rc.region is not None:
            return WorldChange(empty, empty, empty)
        # the leaves: drop the button's observations, then give back the others' own
        upd = self.fusion.forget(Source.BUTTON, self.grid.codes_of_flat(rc.cells)
                                 .astype(np.int64))
        self.octree.set_leaves(upd.cells.astype(np.uint64), upd.after)
        flipped = set(self.grid.flat_of_codes(upd.flipped.astype(np.uint64)).tolist())
        cfg = self.config.indication
        for other in self.collisions:
            common = np.intersect1d(other.cells, rc.cells)
            if len(common):
                again = self._apply(Source.BUTTON, common, cfg.value)
                flipped ^= set(self.grid.flat_of_codes(again.flipped.astype(np.uint64))
                               .tolist())
        # the postures: those only this box held become unknown and are checked again
        near = nearby_positions(table, rc.q, cfg.joint_steps)
        held = np.zeros(len(near), dtype=bool)
        for other in self.collisions:
            if other.region is None:
                held |= near_posture(table, table.joints(table.positions[near]), other.q,
                                     cfg.joint_steps)
        slots = positions.reset(near[~held])
        before = positions.n_selected[slots] > 0
        positions.fill(slots, None)
        after = positions.n_selected[slots] > 0
        lost = table.leaves[slots[before != after]]
        return WorldChange(rc.cells, np.array(sorted(flipped), dtype=np.int64),
                           np.unique(lost))

    def _region_records(self, exclude: frozenset[int] = frozenset(),
                        ) -> list[tuple[int, ContactRegion]]:
        return [(i, rc.region) for i, rc in enumerate(self.collisions)
                if rc.region is not None and len(rc.region.centres) and i not in exclude]

    def region_distances(self, q: Array) -> list[tuple[int, float]]:
        """(index, distance in m) from the arm at q to every learnt region, nearest first."""
        out = [(i, self._regions.distance(q, r)) for i, r in self._region_records()]
        return sorted(out, key=lambda t: t[1])

    def _refill(self, flat_cells: Array, progress: Progress | None) -> Array:
        table, positions = self._need()
        slots = table.slot_of_leaf(flat_cells)
        slots = slots[slots >= 0].astype(np.int64)
        if not len(slots):
            return np.zeros(0, dtype=np.int64)
        before = positions.n_selected[slots] > 0
        occupied = self.occupied().reshape(-1)
        positions.fill(slots[~occupied[table.leaves[slots]]], progress)
        after = positions.n_selected[slots] > 0
        return np.unique(table.leaves[slots[before != after]])

    def near_recorded_collision(self, Q: Array, exclude: frozenset[int] = frozenset(),
                                ) -> Array:
        """Bool per row of Q: inside the posture box of a recorded collision (`indications`),
        ignoring the recorded collisions whose indices are in `exclude`."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.zeros(len(Q), dtype=bool)
        if not self.collisions or self.table is None:
            return out
        for i, rc in enumerate(self.collisions):
            if i not in exclude and rc.region is None:
                out |= near_posture(self.table, Q, rc.q, self.config.indication.joint_steps)
        regions = self._region_records(exclude)
        if regions and not out.all():
            out[~out] = self._regions.blocked(Q[~out], regions)
        return out

    def segment_meets_recorded_collision(self, a: Array, b: Array,
                                         exclude: frozenset[int] = frozenset()) -> bool:
        """Whether the straight joint move a -> b passes through a recorded collision's
        posture box (not in `exclude`): exact (slab test), where samples could miss a corner."""
        if not self.collisions or self.table is None:
            return False
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        regions = [(i, rc.region) for i, rc in enumerate(self.collisions)
                   if rc.region is not None and len(rc.region.centres) and i not in exclude]
        if regions and self._regions.motion_meets(a, b, regions):
            return True
        half = posture_box_half(self.table, self.config.indication.joint_steps)
        d = b - a
        for i, rc in enumerate(self.collisions):
            if i in exclude or rc.region is not None:
                continue
            lo, hi = rc.q - half - a, rc.q + half - a
            t0, t1 = 0.0, 1.0
            for j in range(len(d)):
                if not np.isfinite(half[j]):
                    continue
                if abs(d[j]) < 1e-15:
                    if lo[j] > 0.0 or hi[j] < 0.0:
                        break
                    continue
                u, v = lo[j] / d[j], hi[j] / d[j]
                t0, t1 = max(t0, min(u, v)), min(t1, max(u, v))
                if t0 > t1:
                    break
            else:
                return True
        return False

    # ---------------------------------------------------------------- the hand's leaves
    def _hand_of(self) -> HandCells:
        if self._hand is None:
            self._hand = HandCells(self.robot, self.grid, self.config.indication.first_link)
        return self._hand

    def recorded_hand_cells(self, i: int) -> Array:
        """Leaves the hand filled at recorded collision i (`hand_cells`)."""
        rc = self.collisions[i]
        got = self._hand_cells.get(i)
        if got is None or got[0] is not rc:
            got = (rc, self._hand_of().cells(rc.q[None])[0])
            self._hand_cells[i] = got
        return got[1]

    def hand_cells_at(self, Q: Array) -> Array:
        """The leaves the hand fills at the postures of Q (sampled stores; else none): a
        query starting or ending there is exempt from these leaves."""
        if not self.sampled or all(rc.region is not None for rc in self.collisions):
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate(self._hand_of().cells(Q)))

    def hand_blocked(self, Q: Array, exempt_cells: Array | None = None) -> Array:
        """Bool per row of Q (sampled stores): its hand fills a leaf the hand filled at a
        recorded collision (`hand_cells`), other than `exempt_cells`. All False on the
        joint grid."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        if not self.sampled or not self.collisions or not len(Q):
            return np.zeros(len(Q), dtype=bool)
        mask = np.zeros(self.grid.n_cells, dtype=bool)
        for i in range(len(self.collisions)):
            if self.collisions[i].region is None:
                mask[self.recorded_hand_cells(i)] = True
        if exempt_cells is not None:
            mask[np.asarray(exempt_cells, dtype=np.int64)] = False
        if not mask.any():
            return np.zeros(len(Q), dtype=bool)
        return self._hand_of().blocked(Q, mask)

    def recorded_collisions_at(self, q: Array) -> frozenset[int]:
        """Indices of the recorded collisions whose posture box contains q."""
        if self.table is None:
            return frozenset()
        js = self.config.indication.joint_steps
        boxes = {i for i, rc in enumerate(self.collisions) if rc.region is None
                 and near_posture(self.table, np.asarray(q)[None], rc.q, js)[0]}
        return frozenset(boxes | self._regions.meeting(q, self._region_records()))
