"""`RoadmapPlanner`: world model + Voronoi roads + lazy search behind three calls.

    world = WorldModel(robot, cad_obstacles, WorldConfig())
    planner = RoadmapPlanner(robot, CollisionChecker(robot, cad_obstacles), world)
    report = planner.build(progress)           # one-time: table (cached), CAD, roads
    plan = planner.plan(q_start, q_goal)        # RoadmapPlan: joint path or a reason
    update = planner.add_collision(q_stopped)   # operator indication: fusion + local update
    update = planner.observe(Source.CAMERA, points, 1.0)  # other evidence, same update

A query adds the start and goal leaves as brushfire sources of their own (an incremental update
of the base roads, so roads form around them), then searches the joint positions of the road
cells plus the start's and goal's regions (thesis §8.5.6). If the roads happen not to connect
them although the free space does (cell-based Voronoi roads can break in 3-D), the search is
repeated over all free cells and the plan says so (`searched`).

Before any of that: a goal outside the limits or the octree is refused ("unreachable goal"), a
goal posture that collides (exact check) or sits in a leaf occupied by non-CAD evidence or in a
recorded collision's posture box is refused ("goal inside an obstacle"); start and goal with a
valid straight joint motion between them are joined directly (closer than one edge on the
RV-2AJ's joint grid, at any distance on the sampled store of 6- and 7-axis arms). The search is
weighted A*
(factor 1.5 by default, `RoadmapConfig.heuristic_weight`; 1.0 gives the optimum over the
graph) with lazy exact edge checks - the found path's edges are checked, the invalid ones
dropped and the search repeated (`path_first`) - under a budget of expansions, edge checks
and seconds.

The joint path is what the elastic net / primitive fitter consumes. Table joints that cannot
move the geometry (J6 with a straight tool) are interpolated between the start and goal values
along the path instead of jumping to the table's fixed value.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from assistant.collision.validity import ValidityChecker
from assistant.progress import Progress
from assistant.roadmap.astar import (
    REASON_BUDGET,
    REASON_NO_PATH,
    REASON_SAFETY,
    SearchBudget,
    SearchResult,
)
from assistant.roadmap.edge_check import EdgeCheck, near_learnt
from assistant.roadmap.free_joints import ramp_free_joints
from assistant.roadmap.graph import GraphBase, JointGraph
from assistant.roadmap.grid_ops import connected26
from assistant.roadmap.path_first import lazy_path_search
from assistant.roadmap.search_masks import search_masks
from assistant.roadmap.sources import SourceLabels, label_sources, relabel
from assistant.roadmap.voronoi import (
    ROAD,
    VoronoiMap,
    build_voronoi,
    terminal_labels,
    update_voronoi,
)
from assistant.robots.model import Robot
from assistant.world.fusion import Source
from assistant.world.model import WorldBuildReport, WorldChange, WorldModel

Array = np.ndarray


class PlanFailure(str, Enum):
    START_INVALID = "start_invalid"
    GOAL_UNREACHABLE = "goal_unreachable"
    GOAL_IN_OBSTACLE = "goal_in_obstacle"
    NO_PATH_REGIONS = "no_path_regions"
    NO_PATH = "no_path"
    BUDGET = "budget"
    #: The search's wall-time safety net tripped: no answer (not "no path").
    SAFETY_LIMIT = "safety_limit"


@dataclass(frozen=True)
class RoadmapConfig:
    """Search parameters. Defaults are ours unless noted (the thesis' values were lost)."""

    #: Reset radius (cells) around a changed source cell before the local re-extension
    #: (thesis d_min; the road keeps ~d_min / 2 from a new obstacle).
    d_min: int = 3
    #: The reset radius (cells) of each query's update around its start and goal. The
    #: update's result is the full rebuild's whatever the radius (it grows until the change
    #: stops reaching further); the radius only sets the work. At 5 one round nearly always
    #: does; a smaller radius makes most queries run a second, larger round, a larger one
    #: resets more cells than the change reaches.
    terminal_reset: int = 5
    #: Cost (m of arm travel) per unit occupancy probability of an entered cell.
    occupancy_penalty: float = 0.2
    #: Longest edge (m of weighted joint distance); longer jumps are left out of the graph.
    max_edge: float = 0.35
    #: The same on the sampled store of 6- and 7-axis arms: its leaves' positions lie
    #: farther apart (a few per IK branch and turn); every edge is still checked exactly.
    max_edge_sampled: float = 0.8
    budget: SearchBudget = field(default_factory=SearchBudget)
    #: 1 = optimal A*; > 1 = weighted A* (cost within that factor of the optimum). 1.5 cuts
    #: expansions and edge checks ~5x on the thesis cell; the elastic net shortens the path
    #: afterwards anyway.
    heuristic_weight: float = 1.5
    #: Search all free cells if the roads do not connect start and goal.
    fallback_to_free_cells: bool = True
    #: Cells (Chebyshev radius) around the start (any) and the goal (CAD leaves only) whose
    #: joint positions stay usable even if occupied: after an indication the robot stands
    #: among the cells it just marked and must be able to leave them, and a point taught on
    #: a part lies among the part's partly filled leaves. Edges are still checked exactly
    #: against CAD and the recorded collision postures.
    terminal_escape: int = 2


@dataclass(frozen=True)
class RoadmapBuildReport:
    world: WorldBuildReport
    roadmap_seconds: float
    road_cells: int
    regions: int

    @property
    def total_seconds(self) -> float:
        return self.world.total_seconds + self.roadmap_seconds


@dataclass(frozen=True)
class RoadmapPlan:
    """A joint path start -> goal, or the reason there is none."""

    ok: bool
    reason: str
    failure: PlanFailure | None = None
    joint_path: list[Array] = field(default_factory=list)
    cost: float = float("inf")
    expansions: int = 0
    edge_checks: int = 0
    rejected_edges: int = 0
    #: "roads" (road cells + start/goal regions), "free cells" (fallback), "direct" or "".
    searched: str = ""
    timings: dict[str, float] = field(default_factory=dict)
    #: The leaf (i, j, k) of each of these joints' TCP (`cells`; the planner's grid).
    cell_of: Callable[[Array], list[tuple[int, int, int]]] | None = field(
        default=None, repr=False, compare=False)

    @functools.cached_property
    def cells(self) -> list[tuple[int, int, int]]:
        """Leaf (i, j, k) of each path node's TCP. Measured when asked (displays and tests
        do; the planning does not, and it costs a batch FK, ~0.03 ms a query)."""
        if self.cell_of is None or not self.joint_path:
            return []
        return self.cell_of(np.array(self.joint_path))


@dataclass(frozen=True)
class CollisionUpdate:
    """What an operator indication changed."""

    world: WorldChange
    roadmap_changed: Array  # flat leaf ids whose brushfire values changed
    region_cells: int
    rounds: int
    rebuilt: bool
    seconds: float


@dataclass(frozen=True)
class _SearchGrids:
    """Flat grids of the world that every query reads (`RoadmapPlanner._search_grids`)."""

    key: tuple  # (occupancy grid, table, position selection, config) they were made for
    squeeze: Array  # the no-corner-squeeze rule's blocked cells: occupied, or reachable
    #                 without a valid position
    penalty: Array  # the occupancy penalty of entering each cell
    free: Array  # `WorldModel.free`: a valid position and not occupied
    offers: Array  # `WorldModel.has_valid`: a valid position, occupied or not


class RoadmapPlanner:
    """Plans joint paths through the Voronoi roads of a `WorldModel` (module docstring).

    `checker` must know the same obstacles as the world's CAD (it verifies the edges the search
    uses); hidden obstacles reach the planner only through `add_collision`.
    """

    def __init__(self, robot: Robot, checker: ValidityChecker, world: WorldModel,
                 config: RoadmapConfig | None = None):
        self.robot = robot
        self.checker = checker
        self.world = world
        self.config = config or RoadmapConfig()
        self.labels: SourceLabels | None = None
        self.voronoi: VoronoiMap | None = None
        self._exact_edge = EdgeCheck(checker, world)
        #: Edges are checked on the fast conservative model when the checker has one
        #: (`CollisionChecker.fast`): what it calls free is free, so the path found needs
        #: no other check; the exact checker takes over where it calls a terminal a
        #: collision or finds no path (a gap only the real shapes pass).
        fast = getattr(checker, "fast", None)
        self._fast_edge = EdgeCheck(fast, world) if fast is not None else None
        self._edge = self._exact_edge
        #: The search graphs' nodes (`GraphBase`) and the positions array they were made of.
        self._base: tuple[Array, GraphBase] | None = None
        self._grids: _SearchGrids | None = None  # `_search_grids`
        #: `_known_dead`'s memo: (base positions, recorded collisions, exempt, answer).
        self._dead: tuple[Array, list, frozenset[int], Array] | None = None

    # ---------------------------------------------------------------- build
    def build(self, progress: Progress | None = None) -> RoadmapBuildReport:
        """World model (table from cache if possible, CAD, valid positions) + base roads."""
        progress = progress or Progress("roadmap")
        wrep = self.world.build(progress.sub(0.0, 0.9))
        t0 = time.perf_counter()
        progress.update(0.9, "Voronoi roads")
        w = self.world
        self.labels = label_sources(w.occupied(), w.object_ids(), w.object_names(),
                                    w.reachable(), w.has_valid())
        self.voronoi = build_voronoi(self.labels.source, w.reachable())
        self._graph_base()  # the queries' graph nodes, decoded and laid out once here
        dt = time.perf_counter() - t0
        progress.update(1.0, "roadmap ready", force=True)
        return RoadmapBuildReport(wrep, dt, int(self.voronoi.roads().sum()),
                                  len(self.labels.names))

    def _need(self) -> tuple[SourceLabels, VoronoiMap]:
        if self.labels is None or self.voronoi is None:
            raise RuntimeError("build the roadmap first (RoadmapPlanner.build)")
        return self.labels, self.voronoi

    # ---------------------------------------------------------------- updates
    def add_collision(self, q: Array, progress: Progress | None = None, *,
                      approach: Array | None = None,
                      protected: Sequence[tuple[str, Array]] = ()) -> CollisionUpdate:
        """The operator flagged a collision at posture q: fuse it, update the roads locally
        (`approach`, `protected`: see `WorldModel.indicate_collision`)."""
        self._need()
        t0 = time.perf_counter()
        try:
            change = self.world.indicate_collision(q, progress, approach=approach,
                                                   protected=protected)
        except BaseException:
            self._sync(None, t0)  # cancelled while refilling: roads follow the world anyway
            raise
        return self._sync(change, t0)

    def forget_collision(self, i: int) -> CollisionUpdate:
        """Drop recorded collision i (0-based, `WorldModel.forget_collision`)."""
        self._need()
        t0 = time.perf_counter()
        return self._sync(self.world.forget_collision(i), t0)

    def observe(self, source: Source | str, points_base: Array, values: Array | float,
                progress: Progress | None = None) -> CollisionUpdate:
        """Sensor/camera occupancy observations at points: fuse them, update the roads."""
        self._need()
        t0 = time.perf_counter()
        try:
            change = self.world.observe(source, points_base, values, progress)
        except BaseException:
            self._sync(None, t0)
            raise
        return self._sync(change, t0)

    def _sync(self, change: WorldChange | None, t0: float) -> CollisionUpdate:
        labels, vmap = self._need()
        w = self.world
        self.labels = relabel(labels, w.occupied(), w.object_ids(), w.object_names(),
                              w.reachable(), w.has_valid())
        upd = update_voronoi(vmap, self.labels.source, d_min=self.config.d_min)
        self.voronoi = upd.vmap
        w.decode_positions()  # the changed selection, before the re-plan's query
        empty = np.zeros(0, dtype=np.int64)
        return CollisionUpdate(change or WorldChange(empty, empty, empty),
                               np.flatnonzero(upd.changed), upd.region_cells, upd.rounds,
                               upd.rebuilt, time.perf_counter() - t0)

    # ---------------------------------------------------------------- queries
    def plan(self, q_start: Array, q_goal: Array, progress: Progress | None = None, *,
             direct: bool = True) -> RoadmapPlan:
        """Joint path from q_start to q_goal through the roads (see RoadmapPlan); with
        `direct` False never the straight joint move (a caller that wants a way round
        what that move passes too closely)."""
        labels, base = self._need()
        if progress is not None:
            progress.update(0.0, "planning")
        t0 = time.perf_counter()
        timings: dict[str, float] = {}
        w = self.world
        q_s = np.asarray(q_start, dtype=float).reshape(-1)
        q_g = np.asarray(q_goal, dtype=float).reshape(-1)
        for q, what in ((q_s, "start"), (q_g, "goal")):
            if q.shape != (self.robot.dof,):
                raise ValueError(f"{what} must have {self.robot.dof} joint values")
        sc, gc = w.tcp_cells(np.stack([q_s, q_g])).tolist()
        pre = self._check_terminals(q_s, q_g, sc, gc)
        if pre is not None:
            return pre
        exempt = w.recorded_collisions_at(q_s)
        self._exact_edge.exempt = exempt
        self._edge = self._exact_edge
        if self._fast_edge is not None:
            self._fast_edge.exempt = exempt
            if self._fast_edge.checker.is_valid_batch(np.stack([q_s, q_g])).all():
                self._edge = self._fast_edge
        allow_direct = direct
        direct = self._weighted(q_s, q_g)
        # A valid straight joint move is the answer (a programmer's PTP): one motion check
        # instead of a search that would bend it into several moves. At any distance on the
        # sampled store (6- and 7-axis arms); the RV-2AJ's grid keeps the thesis' rule (one
        # edge long), whose scenario and tests show the roads.
        if allow_direct and \
                (sc == gc or direct <= self.config.max_edge or self.world.sampled) and \
                self._edge.first_invalid_fraction(q_s, q_g) is None:
            timings["total"] = time.perf_counter() - t0
            return self._plan_from([q_s, q_g], None, "direct", timings, direct)
        # Roads around start and goal: incremental update of the base map.
        t1 = time.perf_counter()
        cells, labs = labels.terminals(sc, gc)
        s_lab, g_lab = labels.next_label, labels.next_label + 1
        lab = terminal_labels(base, cells, labs, d_min=self.config.terminal_reset).reshape(-1)
        timings["roadmap_update"] = time.perf_counter() - t1
        # Escape boxes (`RoadmapConfig.terminal_escape`): around the goal only CAD leaves
        # (partly filled; FCL checked their positions), around the start any leaf (the robot
        # is there). The roads first: the base map's and the terminals' own regions, among
        # the free cells and the escapes (`search_masks`).
        grids = self._search_grids()
        on_roads, free = search_masks(
            lab, ROAD, s_lab, g_lab, grids.free, grids.offers, w.cad_leaves(), w.grid.n, sc,
            gc, self.config.terminal_escape)
        # Then any free cell; then also squeezing out of the start's or into the goal's cell
        # (a point taught next to a part may have no other way out; one the rule leaves no
        # edge at all is exempt from the first try on, see `_search`).
        tries = [("roads", on_roads, False)]
        if self.config.fallback_to_free_cells:
            tries += [("free cells", free, False), ("free cells", free, True)]
        if self._edge is not self._exact_edge:  # then the real shapes, the roads first
            tries += [("roads", on_roads, False, self._exact_edge)]
            if self.config.fallback_to_free_cells:
                tries += [("free cells", free, True, self._exact_edge)]
        res = graph = searched = None
        for i, (name, searchable, exempt, *edge) in enumerate(tries):
            budget = self.config.budget
            if res is not None:
                if res.found or res.reason in (REASON_BUDGET, REASON_SAFETY):
                    break
                budget = replace(budget,
                                 max_expansions=max(1, budget.max_expansions - res.expansions),
                                 max_edge_checks=max(1, budget.max_edge_checks - res.edge_checks),
                                 max_seconds=max(0.0, budget.max_seconds - res.seconds))
            if edge:
                self._edge = edge[0]
            nxt, graph = self._search(q_s, q_g, sc, gc, searchable, progress, timings, budget,
                                      exempt)
            searched = name
            res = nxt if res is None else SearchResult(
                nxt.found, nxt.reason, nxt.nodes, nxt.cost, res.expansions + nxt.expansions,
                res.edge_checks + nxt.edge_checks, res.rejected_edges + nxt.rejected_edges,
                res.seconds + nxt.seconds, nxt.budget_detail)
            if (i == 0 and not res.found and res.reason == REASON_NO_PATH
                    and not connected26(free.reshape(w.grid.shape), sc, gc)):
                return self._regions_apart(res, timings, t0)
        timings["total"] = time.perf_counter() - t0
        if not res.found:
            if res.reason == REASON_SAFETY:
                return RoadmapPlan(False, f"search stopped by its safety limit of "
                                   f"{res.budget_detail}", PlanFailure.SAFETY_LIMIT,
                                   expansions=res.expansions, edge_checks=res.edge_checks,
                                   rejected_edges=res.rejected_edges, timings=timings)
            if res.reason == REASON_BUDGET:
                return RoadmapPlan(False, f"budget exhausted ({res.budget_detail})",
                                   PlanFailure.BUDGET, expansions=res.expansions,
                                   edge_checks=res.edge_checks,
                                   rejected_edges=res.rejected_edges, timings=timings)
            return RoadmapPlan(False, "no path: no collision-free connection through the free "
                               f"cells ({res.rejected_edges} edges rejected)",
                               PlanFailure.NO_PATH, expansions=res.expansions,
                               edge_checks=res.edge_checks, rejected_edges=res.rejected_edges,
                               timings=timings)
        path = [graph.node_q[n].copy() for n in res.nodes]
        return self._plan_from(path, res, searched, timings, res.cost)

    # ---------------------------------------------------------------- helpers
    @staticmethod
    def _regions_apart(res: SearchResult, timings: dict[str, float], t0: float,
                       ) -> RoadmapPlan:
        """The roads held no path and start and goal lie in different free regions: no
        search can connect them. (Tested only once the roads failed: a path through the
        roads, which lie in the free cells, proves the connection, and the flood fill would
        cost every query ~0.1 ms.)"""
        timings["total"] = time.perf_counter() - t0
        return RoadmapPlan(False, "no path: start and goal are in different free regions",
                           PlanFailure.NO_PATH_REGIONS, expansions=res.expansions,
                           edge_checks=res.edge_checks, rejected_edges=res.rejected_edges,
                           timings=timings)

    def _max_edge(self) -> float:
        return self.config.max_edge_sampled if self.world.sampled else self.config.max_edge

    def _weighted(self, a: Array, b: Array) -> float:
        return float(np.linalg.norm((b - a) * self._weights()))

    def _weights(self) -> Array:
        """Arm radii, zero for table joints that cannot move the geometry (J6 with a straight
        tool): their value does not matter to the roads, only to the final orientation."""
        w = self.world.weights.copy()
        w[self._free_joints()] = 0.0
        return w

    def _free_joints(self) -> Array:
        table, positions = self.world.table, self.world.positions
        assert table is not None and positions is not None
        levels = positions.validator.link_level
        out = np.zeros(self.robot.dof, dtype=bool)
        for j in range(self.robot.dof):
            # joint j moves link j + 1 (and everything beyond); irrelevant if it is the last
            # joint, fixed in the table and the last link does not depend on it
            if table.counts[j] == 1 and j == self.robot.dof - 1 and levels[j + 1] == j:
                out[j] = True
        return out

    def _check_terminals(self, q_s: Array, q_g: Array, sc: int, gc: int,
                         ) -> RoadmapPlan | None:
        """Why start or goal (TCP leaves sc, gc) cannot be planned for, or None."""
        w, robot = self.world, self.robot
        if not np.isfinite(q_g).all():
            return RoadmapPlan(False, "unreachable goal: its joint values are not all finite",
                               PlanFailure.GOAL_UNREACHABLE)
        if not robot.limits.contains(q_g):
            v = ", ".join(robot.limits.violations(q_g, robot.joint_names))
            return RoadmapPlan(False, f"unreachable goal: {v}", PlanFailure.GOAL_UNREACHABLE)
        if gc < 0:
            return RoadmapPlan(False, "unreachable goal: its TCP lies outside the world model",
                               PlanFailure.GOAL_UNREACHABLE)
        if not robot.limits.contains(q_s) or sc < 0:
            return RoadmapPlan(False, "start outside the joint limits or the world model",
                               PlanFailure.START_INVALID)
        start_ok, goal_ok = self.checker.is_valid_batch(np.stack([q_s, q_g]))  # one call
        if not start_ok:
            return RoadmapPlan(False, f"start posture is in collision{self._why(q_s)}",
                               PlanFailure.START_INVALID)
        if not goal_ok:
            return RoadmapPlan(False, f"goal inside an obstacle{self._why(q_g)}",
                               PlanFailure.GOAL_IN_OBSTACLE)
        p = float(w.occupancy().reshape(-1)[gc])
        # A leaf a CAD part only partly fills is occupied, yet a taught point on the part's
        # surface lies in it: for CAD leaves the exact check above has the last word. So it
        # has for a leaf an indication marked: those are all the leaves the arm filled when
        # it was stopped, the contact is in one of them; the recorded posture box below is
        # that evidence about the goal posture itself.
        if p >= w.threshold and w.object_ids().reshape(-1)[gc] <= 0 and \
                not any(gc in rc.cells for rc in w.collisions):
            return RoadmapPlan(False, f"goal inside an obstacle: its cell is occupied "
                               f"(P = {p:.2f})", PlanFailure.GOAL_IN_OBSTACLE)
        if w.near_recorded_collision(q_g[None])[0]:
            return RoadmapPlan(False, "goal inside an obstacle: next to a recorded collision",
                               PlanFailure.GOAL_IN_OBSTACLE)
        return None

    def _why(self, q: Array) -> str:
        check = getattr(self.checker, "check", None)
        if check is None:
            return ""
        try:
            return f" ({check(q).describe()})"
        except Exception:  # a test double may not report details
            return ""

    def _search(self, q_s: Array, q_g: Array, sc: int, gc: int, searchable: Array,
                progress: Progress | None, timings: dict[str, float],
                budget: SearchBudget | None = None, exempt_terminals: bool = False,
                ) -> tuple[SearchResult, JointGraph]:
        """One lazy search over the `searchable` cells' positions.

        A terminal the squeeze rule leaves without a single edge (a point taught between
        the table and a part) is exempt from the rule at once - searching on would only
        exhaust the reachable free space before giving up; `exempt_terminals` exempts both.
        """
        t0 = time.perf_counter()
        base = self._graph_base()
        grids = self._search_grids()
        squeeze, penalty = grids.squeeze, grids.penalty

        def build(exempt: Sequence[int]) -> tuple[JointGraph, list[int]]:
            return JointGraph.over(base, searchable, squeeze, penalty, self._weights(),
                                   extra=[(sc, q_s), (gc, q_g)],
                                   max_edge=self._max_edge(), squeeze_exempt=exempt)

        graph, (s_id, g_id) = build((sc, gc) if exempt_terminals else ())
        cut_off = [c for c, i in ((sc, s_id), (gc, g_id)) if not len(graph.successors(i)[0])]
        if cut_off and not exempt_terminals:
            graph, (s_id, g_id) = build(cut_off)
        timings["graph"] = timings.get("graph", 0.0) + time.perf_counter() - t0
        t1 = time.perf_counter()
        res = lazy_path_search(graph, s_id, g_id, self._edge, budget or self.config.budget,
                               progress, heuristic_weight=self.config.heuristic_weight,
                               dead=self._known_dead(graph, base, (s_id, g_id)))
        timings["search"] = timings.get("search", 0.0) + time.perf_counter() - t1
        return res, graph

    def _known_dead(self, graph: JointGraph, base: GraphBase, terminals: Sequence[int],
                    ) -> Array | None:
        """Nodes whose posture lies next to a recorded collision (not the query's start's
        own, `EdgeCheck.exempt`): the search never enters them. Without this the lazy
        search finds them one rejected edge at a time - round a learnt region on a UR5,
        20 000 edge checks (~40 s) before it gave up. One batched check of the base
        positions near what was learnt (`edge_check.near_learnt`) per world state, remembered; the
        terminals are never dead (the search starts and ends there, `_check_terminals`
        judged them)."""
        w = self.world
        if not w.collisions:
            return None
        exempt = self._edge.exempt
        if not np.may_share_memory(graph.node_q, base.node_q):
            # `JointGraph.build`'s own graph (other ids): every node
            dead = w.near_recorded_collision(graph.node_q, exempt)
        else:
            n_base = int(base.cell_start[-1])
            records = list(w.collisions)
            memo = self._dead
            if memo is None or memo[0] is not base.node_q or memo[2] != exempt or \
                    len(memo[1]) != len(records) or \
                    any(a is not b for a, b in zip(memo[1], records, strict=True)):
                ask = near_learnt(w, base, n_base, exempt)
                found = np.zeros(n_base, dtype=bool)
                found[ask] = w.near_recorded_collision(base.node_q[ask], exempt)
                memo = self._dead = (base.node_q, records, exempt, found)
            dead = np.zeros(graph.n_nodes, dtype=bool)
            dead[:n_base] = memo[3]
        dead[list(terminals)] = False
        return dead

    def _search_grids(self) -> _SearchGrids:
        """The world's flat grids a query reads (`_SearchGrids`). Remembered while the
        world's occupancy grid, table and position selection and the config stay the same
        objects (a new occupancy grid or selection is a new array; ~0.04 ms a query
        otherwise)."""
        w = self.world
        key = (w.occupancy(), w.table, w.cell_positions_shared()[2], self.config)
        if self._grids is None or any(a is not b for a, b in zip(self._grids.key, key,
                                                                  strict=True)):
            occupied, offers = w.occupied(), w.has_valid()
            self._grids = _SearchGrids(
                key, (occupied | (w.reachable() & ~offers)).reshape(-1),
                np.asarray(self.config.occupancy_penalty * key[0].reshape(-1), float),
                (offers & ~occupied).reshape(-1), offers.reshape(-1))
        return self._grids

    def _graph_base(self) -> GraphBase:
        """The search graphs' nodes: every position of the world's selection, laid out once
        per selection (`JointGraph.over`; the world's arrays are shared, read only)."""
        cells, offsets, Q = self.world.cell_positions_shared()
        if self._base is None or self._base[0] is not Q:
            self._base = (Q, GraphBase.of(self.world.grid.shape, cells, offsets, Q))
        return self._base[1]

    def _plan_from(self, path: list[Array], res: SearchResult | None, searched: str,
                   timings: dict[str, float], cost: float) -> RoadmapPlan:
        path = self._interpolate_free_joints(path)
        return RoadmapPlan(
            True, "found", None, path, float(cost),
            res.expansions if res else 0, res.edge_checks if res else 1,
            res.rejected_edges if res else 0, searched, timings, self._tcp_leaves)

    def _tcp_leaves(self, Q: Array) -> list[tuple[int, int, int]]:
        """`RoadmapPlan.cells` of the joints Q (M, dof)."""
        ijk = self.world.grid.ijk_of_points(self.robot.batch_fk(Q).positions)
        return [tuple(int(v) for v in c) for c in ijk]

    def _interpolate_free_joints(self, path: list[Array]) -> list[Array]:
        free = self._free_joints()
        if not free.any() or len(path) < 3:
            return path
        P = np.array(path, dtype=float)
        ramp_free_joints(P, free, np.ascontiguousarray(self.world.weights, dtype=float))
        return list(P)
