"""`MissionPlanner`: a whole mission - locations, order, transfers, application paths - into one
verified `Trajectory` (SPEC §6).

    planner = MissionPlanner(robot, cell.collision_objects_in_base(), world, roadmap)
    plan = planner.plan_mission(mission, cell.T_world_base, q_current, Progress())
    plan.ok, plan.trajectory, plan.report.describe()

Steps, each ending with a reason that names the failing piece:

1. Locations: start and goal solved by IK (seeded: the configuration the robot was taught
   in, else where the arm comes from, facing the location), refusing unreachable poses,
   5-axis orientations (offering the projection) and poses where every arm configuration
   collides (`locations`).
2. Application paths into motions (`trajectory.application_motions`), verified against the
   known world; reversible paths in both directions.
3. Order (`trajectory.order_paths`): estimated TCP distances first, then measured ones - the
   TCP length of the roadmap's joint path, planned lazily only for the transfers the current
   best order uses; those roadmap paths are reused for the chosen transfers.
4. Transfers: roadmap query, then the elastic net with the world's free cells as `allowed`
   and FCL + recorded collision postures as the particles' validity; low shrink while
   exploring, high for the final plan. A smoothed transfer that fails verification falls
   back to the exploring net, then to joint moves along the roadmap path, for the final
   plan shortcut where a straight joint move is valid (verified too). A final plan's
   smoothed transfer is then written as the fewest joint moves when they verify, keep the
   clearance and run quicker (`joint_moves`: a programmer's MOV/PTP).
5. All pieces joined into one trajectory (labels = mission steps, gripper actions where the
   paths want them) and verified once more as a whole: the exact continuous FCL check against
   every known obstacle, the recorded collision postures and the joint limits. Nothing
   unverified is offered.
"""

from __future__ import annotations

import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import ObstacleView
from assistant.mission.model import Location, ResolvedMission
from assistant.mission.motion import Trajectory
from assistant.planning.certify import all_exact, certificate_refusal, needs_certificate
from assistant.planning.config import MissionPlannerConfig
from assistant.planning.joint_moves import prefer_joint_moves
from assistant.planning.joint_rrt import joint_space_plan
from assistant.planning.known_world import KnownValidity, KnownVerifier, WorldAllowed
from assistant.planning.locations import (
    LocationError,
    SolvedLocation,
    branch_hint,
    branch_seed,
    solve_location,
)
from assistant.planning.pieces import PieceKind, PlanPiece, join_pieces
from assistant.planning.report import MissionPlanReport, PieceReport
from assistant.planning.shortcut import shortcut_joint_path
from assistant.planning.transfer_ends import _joint_moves, _snap_end
from assistant.planning.transfer_forms import direct_move, moves_along, via_move
from assistant.progress import Progress
from assistant.roadmap.planner import PlanFailure, RoadmapPlan, RoadmapPlanner
from assistant.robots.model import Robot
from assistant.trajectory.application import (
    ApplicationMotions,
    application_motions,
    reversed_path,
)
from assistant.trajectory.assemble import (
    AssemblyResult,
    assemble_trajectory,
    joint_interpolation,
    verify,
)
from assistant.trajectory.elastic_net import ElasticNetParams, run_elastic_net
from assistant.trajectory.fit_growth import fit_primitives
from assistant.trajectory.ordering import Endpoint, Ordering, PathEnds, order_paths
from assistant.transforms import inv_T
from assistant.world.model import WorldModel

Array = np.ndarray

#: A path named like "P7-P8" names its end points (when they were typed, not taught).
_SAFE_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9]{0,7}$")


@dataclass(frozen=True)
class TransferResult:
    """A planned transfer (or why not) and where the time went."""

    ok: bool
    piece: PlanPiece | None
    report: PieceReport
    roadmap: RoadmapPlan | None = None
    roadmap_seconds: float = 0.0
    smoothing_seconds: float = 0.0


@dataclass
class MissionPlan:
    """The planned mission: one verified trajectory and its pieces, or the reason for none."""

    ok: bool
    trajectory: Trajectory | None
    pieces: list[PlanPiece]
    report: MissionPlanReport
    T_world_base: Array
    #: Solved joint configurations of the locations (start, goal), by name.
    locations: dict[str, Array] = field(default_factory=dict)
    #: The joined trajectory even when rejected (display of the failure only).
    candidate: Trajectory | None = field(default=None, repr=False)
    ordering: Ordering | None = None

    @property
    def reason(self) -> str:
        return self.report.reason


class MissionPlanner:
    """Plans missions in a built world model and roadmap (module docstring).

    Args:
        robot: the robot (with its tool).
        cell_obstacles: the known obstacles in the robot base frame (CAD of the cell).
        world: the world model, built (or built by `roadmap.build`).
        roadmap: the roadmap planner over `world`.
        checker: the exact checker for `cell_obstacles` (built from them if None).
        config: planning parameters.
    """

    def __init__(self, robot: Robot, cell_obstacles: Sequence[ObstacleView], world: WorldModel,
                 roadmap: RoadmapPlanner, checker: CollisionChecker | None = None,
                 config: MissionPlannerConfig | None = None):
        self.robot = robot
        self.obstacles = list(cell_obstacles)
        self.world = world
        self.roadmap = roadmap
        self.checker = checker or CollisionChecker(robot, self.obstacles)
        self.config = config or MissionPlannerConfig()
        self.verifier = KnownVerifier(self.checker, world)
        #: The same checks on the fast conservative model (`CollisionChecker.fast`): what
        #: scores candidate moves and measures their clearance; `verifier` certifies.
        fast = self.checker.fast
        self.screen = KnownVerifier(fast, world) if fast is not None else self.verifier
        #: Application paths and the joined trajectory: without the recorded hand leaves
        #: (each transfer was verified with them).
        self.app_verifier = KnownVerifier(self.checker, world, hand=False)
        self._allowed: WorldAllowed | None = None

    # ------------------------------------------------------------------ transfers
    def allowed(self) -> WorldAllowed:
        """The net's `allowed` over the world's current free cells."""
        if self._allowed is None:
            self._allowed = WorldAllowed(self.world)
        else:
            self._allowed.refresh()
        return self._allowed

    def plan_transfer(self, q_start: Array, q_goal: Array, *, exploring: bool = False,
                      label: str = "transfer", progress: Progress | None = None,
                      roadmap_plan: RoadmapPlan | None = None) -> TransferResult:
        """Roadmap query + smoothing + verification of one transfer q_start -> q_goal; on a
        mesh arm certified by the exact check alone, planned again with every check exact
        if that refuses (`certify`)."""
        res = self._plan_transfer(q_start, q_goal, exploring=exploring, label=label,
                                  progress=progress, roadmap_plan=roadmap_plan)
        if not res.ok or res.piece is None or not needs_certificate(self):
            return res
        t0 = time.perf_counter()
        refusal = certificate_refusal(self, res.piece.trajectory)
        if not refusal:
            return replace(res, smoothing_seconds=res.smoothing_seconds
                           + time.perf_counter() - t0)
        with all_exact(self):  # the repair: the fast model is not asked again
            again = self._plan_transfer(q_start, q_goal, exploring=exploring, label=label,
                                        progress=progress)
        why = again.report.reason
        if again.ok and again.piece is not None:
            why = certificate_refusal(self, again.piece.trajectory)
            if not why:
                rep = replace(again.report, notes=again.report.notes + (
                    f"planned again with exact checks only ({refusal})",))
                return replace(again, report=rep)
        rep = PieceReport(label, "transfer", False, f"{refusal}; planned again with exact "
                          f"checks only: {why}", seconds=time.perf_counter() - t0)
        return TransferResult(False, None, rep, None, res.roadmap_seconds)

    def _plan_transfer(self, q_start: Array, q_goal: Array, *, exploring: bool = False,
                       label: str = "transfer", progress: Progress | None = None,
                       roadmap_plan: RoadmapPlan | None = None) -> TransferResult:
        """`plan_transfer` without the certificate."""
        q_s = np.asarray(q_start, dtype=float)
        q_g = np.asarray(q_goal, dtype=float)
        t0 = time.perf_counter()
        forms = not exploring and self.config.transfer_joint_moves
        direct_c = -1.0
        if forms and roadmap_plan is None and self._terminals_ok(q_s, q_g):
            asm, direct_c = direct_move(self.robot, q_s, q_g, **self._form_args(q_s, label))
            if asm is not None:
                t1 = time.perf_counter()
                notes = ("one joint move: the straight joint motion is free and keeps the "
                         "clearance",)
                piece = PlanPiece(PieceKind.TRANSFER, label, asm.trajectory, asm.report)
                rep = PieceReport(label, "transfer", True, "", asm.report, t1 - t0, "direct",
                                  notes)
                return TransferResult(True, piece, rep, None, t1 - t0, 0.0)
            # one via round what is in the way; else on a 6- or 7-axis arm - where the
            # straight move is free but closer than the clearance - that move, as the
            # roads' direct answer always was there
            asm = via_move(self.robot, self.world, q_s, q_g, **self._form_args(q_s, label))
            how, searched = ("two joint moves through a valid posture, keeping the "
                             "clearance"), "one via"
            if asm is None and direct_c >= 0.0 and self.world.sampled:
                traj = _joint_moves(self.robot, [q_s, q_g], label, self.config.assembly)
                checked = verify(self.robot, traj, self.verifier,
                                 clearance_step=self.config.assembly.clearance_step)
                if checked.ok:
                    asm, searched = checked, "direct"
                    how = "one joint move: the straight joint motion is free"
            if asm is not None:
                t1 = time.perf_counter()
                piece = PlanPiece(PieceKind.TRANSFER, label, asm.trajectory, asm.report)
                rep = PieceReport(label, "transfer", True, "", asm.report, t1 - t0,
                                  searched, (how,))
                return TransferResult(True, piece, rep, None, t1 - t0, 0.0)
        plan = roadmap_plan if roadmap_plan is not None else self.roadmap.plan(
            q_s, q_g, progress.sub(0.0, 0.2) if progress else None,
            direct=direct_c < 0.0)  # free but too close: look for a way round first
        if not plan.ok and plan.failure in (PlanFailure.NO_PATH, PlanFailure.NO_PATH_REGIONS,
                                            PlanFailure.BUDGET) \
                and self.world.sampled:
            plan = self._joint_rrt(q_s, q_g, plan, progress.sub(0.1, 0.2) if progress else None)
        t1 = time.perf_counter()
        if not plan.ok:
            rep = PieceReport(label, "transfer", False, plan.reason, seconds=t1 - t0)
            return TransferResult(False, None, rep, plan, t1 - t0)
        asm = None
        if plan.searched == "direct" and self.world.sampled and not exploring:
            # A free straight joint move on a 6- or 7-axis arm: the programmer's PTP as it
            # is, verified, without the net and the fit (seconds on those arms). Not while
            # exploring: the smoothed road keeps its clearance from what is not known yet.
            traj = _joint_moves(self.robot, plan.joint_path, label, self.config.assembly)
            checked = verify(self.robot, traj, self.verifier,
                             clearance_step=self.config.assembly.clearance_step)
            if checked.ok:
                asm, notes = checked, ["one joint move: the straight joint motion is free"]
        if asm is None and exploring and self.world.sampled and plan.searched != "direct":
            # Exploring on a 6- or 7-axis arm: the searched path itself, as joint moves
            # along the roads (their clearance keeps the run off what is not known yet).
            # The exploring net costs seconds there (a numerical IK per particle) and a
            # re-plan with the arm halted after a Collision! must take well under one; the
            # final plan is formed afresh at the goal.
            traj = _joint_moves(self.robot, plan.joint_path, label, self.config.assembly)
            checked = verify(self.robot, traj, self.verifier,
                             clearance_step=self.config.assembly.clearance_step)
            if checked.ok:
                asm, notes = checked, [f"{len(traj.motions)} joint moves along the roads "
                                       "(exploring)"]
        if asm is None and forms:
            moves, _ = moves_along(self.robot, plan.joint_path, **self._form_args(q_s, label))
            if moves is not None:
                asm = moves
                n = len(moves.trajectory.motions) if moves.trajectory is not None else 0
                notes = [f"{n} joint move{'s' if n > 1 else ''} along the searched path, "
                         f"keeping {self.config.transfer_clearance * 1000:.0f} mm"]
        if asm is None and forms and direct_c >= 0.0 and plan.searched != "direct" and \
                self.world.sampled:
            # no way round keeps the clearance: the free straight move comes closest to it
            plan = replace(plan, joint_path=[q_s, q_g], searched="direct")
        if asm is None:
            asm, notes = self._smooth(plan.joint_path, exploring, label,
                                      progress.sub(0.2, 1.0) if progress else None)
            if asm.trajectory is not None and not exploring and \
                    self.config.transfer_joint_moves:
                asm, notes = self._as_joint_moves(asm, notes, label)
        if asm.trajectory is None and self.world.sampled and plan.searched != "joint space":
            # Nothing along the roads verifies (their edge checks sample the recorded
            # posture boxes more coarsely than the verifier): the joint-space search's path.
            alt = self._joint_rrt(q_s, q_g, replace(plan, ok=False, reason=asm.report.reason),
                                  progress.sub(0.6, 0.7) if progress else None)
            if alt.ok:
                plan = alt
                asm, notes = self._smooth(plan.joint_path, exploring, label, None)
        t2 = time.perf_counter()
        if asm.trajectory is None:
            rep = PieceReport(label, "transfer", False,
                              f"no verified trajectory along the roadmap path: "
                              f"{asm.report.reason}", asm.report, t2 - t0, plan.searched,
                              tuple(notes))
            return TransferResult(False, None, rep, plan, t1 - t0, t2 - t1)
        piece = PlanPiece(PieceKind.TRANSFER, label, asm.trajectory, asm.report)
        rep = PieceReport(label, "transfer", True, "", asm.report, t2 - t0, plan.searched,
                          tuple(notes))
        return TransferResult(True, piece, rep, plan, t1 - t0, t2 - t1)

    def _form_args(self, q_s: Array, label: str) -> dict:
        """What `transfer_forms` needs of this planner for a transfer from q_s."""
        cfg = self.config
        return dict(verifier=self.verifier, screen=self.screen,
                    exempt=self.world.recorded_collisions_at(q_s),
                    clearance=cfg.transfer_clearance, assembly=cfg.assembly, label=label,
                    params=cfg.joint_moves)

    def _terminals_ok(self, q_s: Array, q_g: Array) -> bool:
        """Start and goal within the limits and the world, the goal in no recorded posture
        box: what the roadmap refuses with a reason (it is asked when this is False)."""
        lim = self.robot.limits
        if not (np.isfinite(q_g).all() and lim.contains(q_s) and lim.contains(q_g)):
            return False
        sc, gc = self.world.tcp_cells(np.stack([q_s, q_g])).tolist()
        return sc >= 0 and gc >= 0 and not self.world.near_recorded_collision(q_g[None])[0]

    def _joint_rrt(self, q_s: Array, q_g: Array, failed: RoadmapPlan,
                   progress: Progress | None = None) -> RoadmapPlan:
        return joint_space_plan(self.robot, self.world, self.verifier, q_s, q_g, failed,
                                self.config.joint_rrt, progress)

    def _as_joint_moves(self, asm: AssemblyResult, notes: list[str], label: str,
                        ) -> tuple[AssemblyResult, list[str]]:
        """The smoothed transfer as the fewest joint moves when they verify, keep the
        clearance and run quicker (`planning.joint_moves.prefer_joint_moves`)."""
        assert asm.trajectory is not None
        cfg = self.config
        q0 = np.asarray(asm.trajectory.start.q, dtype=float)
        return prefer_joint_moves(self.robot, asm, notes, self.verifier,
                                  exempt=self.world.recorded_collisions_at(q0),
                                  clearance=cfg.transfer_clearance, step=cfg.assembly.step,
                                  label=label, params=cfg.joint_moves, screen=self.screen)

    def _smooth(self, joint_path: list[Array], exploring: bool, label: str,
                progress: Progress | None) -> tuple[AssemblyResult, list[str]]:
        """Net -> lines/arcs -> verified motions, with fallbacks that never skip verification.

        The fitted primitives may stray from the (valid) net by up to the fit tolerance; if
        that touches something, the same net is refitted tighter before anything else. The
        final plan may fall back to the exploring net (it stays nearer the roads), and last,
        to joint moves along the roadmap path (shortcut: `shortcut_joint_path`).
        """
        cfg = self.config
        nets: list[ElasticNetParams] = [cfg.net_exploring if exploring else cfg.net_final]
        if cfg.fallback_to_joint_moves and not exploring:
            nets.append(cfg.net_exploring)
        tolerances = [cfg.fit.tolerance] + [t for t in (cfg.fit.tolerance / 2.5, 0.001)
                                            if t < cfg.fit.tolerance]
        q0, q1 = np.asarray(joint_path[0]), np.asarray(joint_path[-1])
        validity = KnownValidity(self.checker, self.world,
                                 self.world.recorded_collisions_at(q0))
        assembly = replace(cfg.assembly, label=label)
        allowed = self.allowed()
        notes: list[str] = []
        asm: AssemblyResult | None = None
        deadline = _Deadline(progress, cfg.smoothing_safety_seconds)
        for k, params in enumerate(nets):
            try:
                net = run_elastic_net(self.robot, joint_path, allowed=allowed,
                                      validity=validity, params=params,
                                      progress=deadline.sub(0.0, 0.8))
            except _TimeUp:
                # Never a shortcut to another answer: what the net would have given depends
                # on its iteration budgets only, so running out of wall time is a failure.
                why = (f"smoothing stopped by its safety limit of "
                       f"{cfg.smoothing_safety_seconds:.0f} s of wall time (is the machine "
                       "overloaded?); no trajectory is offered, as one cut short by time "
                       "would depend on the machine's speed")
                notes.append(why)
                traj = _joint_moves(self.robot, joint_path, label, cfg.assembly)
                rep = replace(verify(self.robot, traj, None).report, ok=False, reason=why)
                return AssemblyResult(None, rep, traj), notes
            for tol in tolerances:
                fit = fit_primitives(net.particles.points, replace(cfg.fit, tolerance=tol))
                asm = assemble_trajectory(self.robot, fit, net.particles, self.verifier,
                                          assembly)
                if asm.trajectory is None:
                    notes.append(f"fit within {tol * 1000:.1f} mm rejected: "
                                 f"{asm.report.reason}")
                    continue
                snapped = _snap_end(self.robot, asm.trajectory, q1)
                if snapped is None:
                    notes.append("smoothed path ends too far from the goal posture")
                    continue
                if k > 0:
                    notes.append("smoothed with the exploring net")
                return replace(asm, trajectory=snapped), notes
        if cfg.fallback_to_joint_moves:
            # Shortcuts leave the roads, whose clearance is what keeps an exploring run off
            # what is not known yet (in the thesis scenario shortcut re-plans hit the hidden
            # obstacle twice more): exploring keeps the searched path.
            tries = [(joint_path, "the roadmap path")]
            if not exploring:
                exempt = self.world.recorded_collisions_at(q0)
                short = shortcut_joint_path(
                    joint_path, lambda a, b: self.screen.check_motion(a, b, exempt).valid)
                # Each shortcut passed `check_motion`; `verify` samples the dense moves on
                # its own, and should it still refuse one, the searched path is next.
                if len(short) < len(joint_path):
                    tries.insert(0, (short, "the shortened roadmap path"))
            for path, what in tries:
                traj = _joint_moves(self.robot, path, label, cfg.assembly)
                checked = verify(self.robot, traj, self.verifier,
                                 clearance_step=cfg.assembly.clearance_step)
                if checked.ok:
                    notes.append(f"{len(traj.motions)} joint moves along {what} "
                                 "(smoothing failed)")
                    break
            return checked, notes
        assert asm is not None  # every net was fitted and assembled at least once
        return asm, notes

    # ------------------------------------------------------------------ missions
    def plan_mission(self, mission: ResolvedMission, T_world_base: Array, q_current: Array,
                     progress: Progress | None = None, *, exploring: bool = False,
                     ) -> MissionPlan:
        """Plan the mission from its start location (or `q_current` if it has none).

        Args:
            mission: start, goal and application paths (world frame).
            T_world_base: where the robot base stands in the world.
            q_current: the robot's joints now (IK seed; the start when the mission has none).
            progress: reports and cancels (raises `Cancelled`).
            exploring: low-shrink smoothing for a first run in a partly unknown cell.
        """
        t0 = time.perf_counter()
        progress = progress or Progress("plan mission")
        T_wb = np.asarray(T_world_base, dtype=float)
        T_bw = inv_T(T_wb)
        q_cur = np.asarray(q_current, dtype=float)
        reports: list[PieceReport] = []
        failed = _Failure(T_wb, reports, t0, exploring)
        if mission.start is None and mission.goal is None and not mission.paths:
            return failed("mission", "mission", "the mission is empty: teach a start, a goal "
                          "or an application path")
        progress.update(0.0, "solving locations")
        # 1. start
        locations: dict[str, Array] = {}
        if mission.start is not None:
            try:
                s = self._solve(mission.start, T_wb, q_cur)
            except LocationError as exc:
                return failed(f"start {exc.name}", "location", str(exc))
            start_label = mission.start.name
        else:
            if not self.checker.is_valid(q_cur):
                return failed("start (current posture)", "location",
                              "the robot's current posture is in collision "
                              f"({self.checker.check(q_cur).describe(self.checker.link_words)})")
            s = SolvedLocation("current posture", q_cur, self.robot.fk(q_cur))
            start_label = "current posture"
        locations[s.name] = s.q
        reports.append(PieceReport(f"start {s.name}", "location", True))
        # 2. application paths (both ways if reversible)
        apps: dict[tuple[int, bool], ApplicationMotions] = {}
        seed = s.q
        for i, path in enumerate(mission.paths):
            progress.update(0.05 + 0.1 * i / max(1, len(mission.paths)),
                            f"application path {path.name}")
            for rev in (False, True) if path.reversible else (False,):
                p = reversed_path(path) if rev else path
                p0 = (T_bw @ np.append(p.start, 1.0))[:3]
                am = application_motions(self.robot, p, q_seed=branch_seed(seed, p0),
                                         T_base_world=T_bw,
                                         verifier=self.app_verifier,
                                         params=self.config.application)
                if not am.ok:
                    why = am.failure.describe() if am.failure else "cannot be planned"
                    if rev:  # the forward direction works: just do not offer reversing
                        continue
                    return failed(path.name, "application", f"application path {path.name}: "
                                  f"{why}")
                apps[(i, rev)] = am
            fwd = apps[(i, False)]
            note = ()
            if fwd.max_orientation_correction > np.radians(0.5):
                note = (f"orientation projected into the arm plane by up to "
                        f"{np.degrees(fwd.max_orientation_correction):.1f} deg",)
            reports.append(PieceReport(path.name, "application", True,
                                       trajectory=fwd.verification, notes=note))
        # 3. goal
        goal: SolvedLocation | None = None
        if mission.goal is not None:
            gseed = _end_q(apps[(len(mission.paths) - 1, False)]) if mission.paths else s.q
            if mission.start is not None and mission.goal.name == mission.start.name and \
                    np.allclose(mission.goal.T_world_tool, mission.start.T_world_tool):
                # Back home: the same posture, not a second IK solution a hair apart (a
                # program cannot give one position name two joint solutions).
                goal = s
            else:
                try:
                    goal = self._solve(mission.goal, T_wb, gseed)
                except LocationError as exc:
                    return failed(f"goal {exc.name}", "location", str(exc))
            locations[goal.name] = goal.q
            reports.append(PieceReport(f"goal {goal.name}", "location", True))
        progress.update(0.15, "ordering")
        # 4. order (estimated, then measured transfer lengths)
        cache: dict[tuple[bytes, bytes], RoadmapPlan] = {}
        try:
            ordering = self._order(mission, s, goal, apps, cache, progress)
        except _SafetyStop as stop:
            return failed("ordering", "ordering", f"measuring the transfers: {stop}")
        if not np.isfinite(ordering.cost):
            return failed("ordering", "ordering", "no order of the application paths has a "
                          "transfer path between every pair (see the transfers' reasons)")
        # 5. transfers and application pieces in order
        pieces: list[PlanPiece] = []
        here_q, here_label = s.q, start_label
        # (posture to reach, its label, the application path that starts there, reversed)
        steps: list[tuple[Array, str, ApplicationMotions | None, bool]] = []
        for i, rev in zip(ordering.order, ordering.reversed, strict=True):
            am_i = apps[(i, rev)]
            assert am_i.start is not None
            steps.append((np.asarray(am_i.start.q, dtype=float), mission.paths[i].name, am_i,
                          rev))
        if goal is not None:
            steps.append((goal.q, goal.name, None, False))
        n_steps = max(1, len(steps))
        for k, (q_to, to_label, am, rev) in enumerate(steps):
            if time.perf_counter() - t0 > self.config.max_seconds:
                return failed(f"{here_label} -> {to_label}", "transfer",
                              f"planning stopped by its safety limit of "
                              f"{self.config.max_seconds:.0f} s of wall time (is the machine "
                              "overloaded?)")
            sub = progress.sub(0.2 + 0.75 * k / n_steps, 0.2 + 0.75 * (k + 1) / n_steps,
                               f"{here_label} -> {to_label}")
            if float(np.abs(q_to - here_q).max()) > 1e-9:
                label = f"{here_label} -> {to_label}"
                tr = self.plan_transfer(here_q, q_to, exploring=exploring, label=label,
                                        progress=sub,
                                        roadmap_plan=cache.get((here_q.tobytes(),
                                                                q_to.tobytes())))
                reports.append(tr.report)
                if not tr.ok:
                    return failed(label, "transfer", tr.report.reason, keep_report=True)
                assert tr.piece is not None
                pieces.append(tr.piece)
            if am is not None:
                a, b = _end_names(am.name)
                a, b = (b, a) if rev else (a, b)
                # The operator's location names where the path was taught through them.
                assert am.start is not None
                pieces.append(PlanPiece(PieceKind.APPLICATION, am.name, am.to_trajectory(),
                                        am.verification, path_name=am.name,
                                        start_name=am.start.name or a,
                                        end_name=am.motions[-1].target.name or b))
                here_q, here_label = _end_q(am), am.name
            else:
                here_q, here_label = q_to, to_label
        if not pieces:
            return failed("mission", "mission", "nothing to do: the robot already stands at "
                          "the goal and there are no application paths")
        # 6. one trajectory, verified as a whole
        progress.update(0.96, "verifying the whole trajectory")
        # The operator's names as they are: each dialect makes them legal (and says so).
        traj = join_pieces(pieces, mission.start.name if mission.start is not None else "",
                           goal.name if goal is not None else "")
        checked = verify(self.robot, traj, self.app_verifier,
                         clearance_step=self.config.assembly.clearance_step)
        order_names = tuple(mission.paths[i].name + (" (reversed)" if r else "")
                            for i, r in zip(ordering.order, ordering.reversed, strict=True))
        elapsed = time.perf_counter() - t0
        if not checked.ok:
            reports.append(PieceReport("whole trajectory", "verification", False,
                                       checked.report.reason))
            rep = MissionPlanReport(False, f"the joined trajectory failed verification: "
                                    f"{checked.report.reason}", tuple(reports),
                                    "whole trajectory", planning_seconds=elapsed,
                                    order=order_names, ordering_method=ordering.method,
                                    exploring=exploring)
            return MissionPlan(False, None, pieces, rep, T_wb, locations, traj, ordering)
        r = checked.report
        rep = MissionPlanReport(True, "planned and verified", tuple(reports), None,
                                r.min_clearance, r.tcp_length, r.joint_length,
                                dict(r.primitive_counts), elapsed, order_names,
                                ordering.method, exploring)
        progress.update(1.0, "mission planned", force=True)
        return MissionPlan(True, traj, pieces, rep, T_wb, locations, traj, ordering)

    def _solve(self, loc: Location, T_wb: Array, seed: Array) -> SolvedLocation:
        """Joints for a taught location near `seed` (raises `LocationError` with the reason)."""
        return solve_location(self.robot, self.checker, loc.name, loc.T_world_tool, T_wb,
                              seed=seed, q_hint=branch_hint(loc), taught=loc.q_hint)

    def _order(self, mission: ResolvedMission, s: SolvedLocation, goal: SolvedLocation | None,
               apps: dict[tuple[int, bool], ApplicationMotions],
               cache: dict[tuple[bytes, bytes], RoadmapPlan], progress: Progress) -> Ordering:
        ends = []
        for i, path in enumerate(mission.paths):
            fwd = apps[(i, False)]
            assert fwd.start is not None
            ends.append(PathEnds(Endpoint(fwd.start.position, np.asarray(fwd.start.q, float),
                                          f"{path.name} start"),
                                 Endpoint(fwd.motions[-1].target.position, _end_q(fwd),
                                          f"{path.name} end"),
                                 (i, True) in apps))
        start = Endpoint(s.T_base_tool[:3, 3], s.q, s.name)
        gend = Endpoint(goal.T_base_tool[:3, 3], goal.q, goal.name) if goal else None
        # Trivial orders need no measuring: one one-way path (or none) has a single order.
        trivial = len(mission.paths) == 0 or (len(mission.paths) == 1
                                              and not ends[0].reversible)
        measure = None
        if self.config.measure_ordering and not trivial:
            def measure(a: Endpoint, b: Endpoint) -> float:
                if a.q is None or b.q is None:
                    return float(np.linalg.norm(a.position - b.position))
                # the reversed direction's entry posture is the forward exit's pose
                qa, qb = self._entry_q(a, apps, mission), self._entry_q(b, apps, mission)
                key = (qa.tobytes(), qb.tobytes())
                if key not in cache:
                    progress.check()
                    cache[key] = self.roadmap.plan(qa, qb)
                plan = cache[key]
                if plan.failure == PlanFailure.SAFETY_LIMIT:
                    raise _SafetyStop(plan.reason)  # no answer: not an unreachable pair
                return _tcp_length(self.robot, plan.joint_path) if plan.ok else float("inf")
        return order_paths(ends, start, gend, measure=measure, params=self.config.ordering)

    @staticmethod
    def _entry_q(e: Endpoint, apps: dict[tuple[int, bool], ApplicationMotions],
                 mission: ResolvedMission) -> Array:
        """Joints at an endpoint, taken from the motions that actually start/end there."""
        for i, path in enumerate(mission.paths):
            if e.label == f"{path.name} end" and (i, True) in apps:
                rev = apps[(i, True)]
                assert rev.start is not None
                return np.asarray(rev.start.q, dtype=float)
        assert e.q is not None
        return np.asarray(e.q, dtype=float)


class _SafetyStop(Exception):
    """A roadmap query behind the ordering tripped its wall-time safety net."""


class _TimeUp(Exception):
    """The smoothing's wall-time safety limit is reached (raised from the net's progress)."""


class _Deadline(Progress):
    """Progress for the net that also ends it at a wall-time safety limit; forwards to the
    caller's progress, so a user's cancel still cancels.

    The net's result is decided by iteration budgets alone (the same operator actions must
    give the same program on any machine, under any load); this limit only keeps a stuck
    computation from hanging the session, and reaching it fails the transfer loudly.
    """

    def __init__(self, parent: Progress | None, seconds: float):
        super().__init__(parent.task if parent is not None else "smoothing")
        self._parent = parent
        self._end = time.perf_counter() + seconds

    def update(self, fraction: float, message: str = "", *, force: bool = False) -> None:
        if time.perf_counter() > self._end:
            raise _TimeUp()
        if self._parent is not None:
            self._parent.update(fraction, message, force=force)
        super().update(fraction, message, force=force)


class _Failure:
    """Builds failed `MissionPlan`s with the reports gathered so far."""

    def __init__(self, T_wb: Array, reports: list[PieceReport], t0: float, exploring: bool):
        self.T_wb, self.reports, self.t0, self.exploring = T_wb, reports, t0, exploring

    def __call__(self, label: str, kind: str, reason: str, *,
                 keep_report: bool = False) -> MissionPlan:
        if not keep_report:
            self.reports.append(PieceReport(label, kind, False, reason))
        rep = MissionPlanReport(False, reason, tuple(self.reports), label,
                                planning_seconds=time.perf_counter() - self.t0,
                                exploring=self.exploring)
        return MissionPlan(False, None, [], rep, self.T_wb)


def _end_names(path_name: str) -> tuple[str, str]:
    """A path named like "P7-P8" names its start and end positions P7 and P8 in programs."""
    parts = path_name.split("-")
    if len(parts) == 2 and all(_SAFE_NAME.match(p) for p in parts):
        return parts[0], parts[1]
    return "", ""


def _end_q(am: ApplicationMotions) -> Array:
    return np.asarray(am.motions[-1].target.q, dtype=float)


def _tcp_length(robot: Robot, joint_path: Sequence[Array], step: float = 0.01) -> float:
    """TCP length of a joint path moved in straight joint segments (densified)."""
    if len(joint_path) < 2:
        return 0.0
    dense = [joint_interpolation(robot, a, b, step) for a, b in
             zip(joint_path[:-1], joint_path[1:], strict=True)]
    P = robot.batch_fk(np.concatenate(dense)).positions
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
