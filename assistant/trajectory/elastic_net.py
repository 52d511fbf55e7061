"""Elastic net (thesis §8.5.8, SPEC §6): smooth a searched path into lines and arcs.

Particles are TCP points with their joints. Each iteration moves every interior particle by
a blend of three local forces (A, B, C = previous, this, next particle; t = (C - A)/|C - A|):

* equidistance ``F_eq = (|BC| - |AB|) t`` keeps the spacing even;
* shrink ``F_sh = (A - B) + (C - B)``, taken normal to t ("considering the equidistance
  constraint"), pulls the path straight;
* rotation equalises the turn angles of neighbouring particles, so bends become arcs.

A particle whose three neighbouring turn angles are all below ``t_a,min`` (the turn angle of a
regular polygon with the current spacing on a circle of radius ``r_max``) is on a line and
only shrinks; otherwise (65) applies: ``F = C1 F_eq + (1 - lam) C2 F_rot + lam C3 F_sh`` with
``lam = C5 E / (1 + C5 E)`` and E the mean particle movement of the previous iteration, so the
net orders itself by shrinking while it still moves a lot and forms arcs once it is calm.
Stage 1 (the strategy of the elastic-net paper): equidistance plus a strong shrink, no
rotation, no threshold; stage 2: the full rule. A stage ends when E < epsilon (thesis 1e-10),
when every proposed move was rejected, or at its iteration budget; stage 1 also when the net
stopped getting shorter (taut); the result says which.

Every proposed move is mapped back to joints by local position IK seeded from the particle's
joints (null-space pull towards the neighbours' joints keeps the tool pitch smooth) and is
rejected - the particle stays - if the point or the midpoints of its two edges are not
`allowed` (octree: occupied or unreachable cell), if IK fails or jumps, or if the arm would
collide (`ValidityChecker.is_valid_batch`). A rejected move is retried once at half length;
a particle refused at both lengths is pinned against a constraint and proposes only half
moves until one is accepted (in the benchmark's cells nearly all refused moves come from a
particle refused the sweep before, and nearly all their retries are refused again, so a
retry call for them mostly buys nothing but time).
A checker that also gives free margins (`validity.MarginValidity`) lets a particle skip
the exact check while its arm travel since its last exact check stays inside that margin:
the same answers, 36 % of the final transfer nets' checks certified in the benchmark's cells
(with their 5 mm `min_gap`; the margin is one number for the whole arm, and the links' own
10-20 mm gaps bound it in most postures - per-link-pair travel bounds would certify 62 %).
The same margins let the net keep a distance (`min_gap`): a move that brings the arm's
covering spheres nearer than that to an obstacle (or the arm to itself) is refused, unless the
particle already was nearer (the roadmap path may pass closer; it is never pushed out).

Constants (thesis Table 10: 0.8, 4.0, 0.1, 0.1, 200.0; the table's header was lost, so the
mapping is ours). Particles are updated one colour class at a time (i mod 3: a particle never
moves together with a neighbour it reads), i.e. Gauss-Seidel, which makes each gain a
relaxation factor of the exact local correction:

* C1 = 0.8 on the literal F_eq: B moves 1.6x the step that would equalise |AB| and |BC|
  (successive over-relaxation, stable below 2);
* C2 = 4.0 on F_rot, which we define as the *mean of four* edge-rotation corrections like
  the thesis (each a quarter of the exact local one): C2 = 4 makes the sum, relaxation 1.0;
* C3 = 0.1 shrink inside the curve rule (65), C4 = 0.1 shrink on lines: relaxation 0.2,
  deliberately gentle so a calm net keeps its arcs;
* C5 = 200 per metre in lam: lam = 0.5 at 5 mm mean movement per iteration.

Shrink strength of stage 1 is the explore/final switch: low while exploring (stay near the
road, i.e. the clearance of the Voronoi roadmap), high once the final path is known. The
final net over-relaxes (0.7 = relaxation 1.4): the shrink is a diffusion along the net whose
slowest mode needs on the order of N^2 iterations on N particles, and over-relaxation is what
cuts that; at 0.4 a 1 m path is still far from taut after 300 iterations, at 0.7 most nets
settle in well under 200 with the same primitives, and 0.9 ripples.

Every budget counts iterations (and the moves checked in them), never seconds: the same
input gives the same particles on any machine and under any load.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from assistant.collision.validity import ValidityChecker
from assistant.kernels.lazy import is_pending
from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.trajectory.net_forces import propose_moves
from assistant.trajectory.net_kernel import (
    ACCEPTED,
    ASK_FCL,
    NetKernelModel,
    apply_moves,
    check_moves,
)
from assistant.trajectory.particles import (
    Particles,
    polyline_length,
    resample_joint_path,
    row_norms,
)
from assistant.trajectory.position_ik import BatchPositionIK, PositionIKParams

Array = np.ndarray

#: Is each TCP point (N, 3) allowed (free, reachable cell)? The octree provides this.
AllowedFn = Callable[[Array], Array]


@dataclass(frozen=True)
class ElasticNetParams:
    """Forces, thresholds and budgets of the net (metres, radians)."""

    c_equidistance: float = 0.8  # C1
    c_rotation: float = 4.0  # C2
    c_shrink: float = 0.1  # C3, inside the curve rule (65)
    c_line_shrink: float = 0.1  # C4, on lines
    c_error: float = 200.0  # C5, 1/m: lam = C5 E / (1 + C5 E)
    #: Shrink gain of stage 1 (0.4 = relaxation 0.8); see `exploring`/`final`.
    stage1_shrink: float = 0.4
    #: Bends with a radius above r_max count as straight (the line/arc switch t_a,min).
    r_max: float = 0.4
    #: Bends tighter than r_min are shrunk instead of rotated (the paper's t_a,max); 0 = off.
    r_min: float = 0.0
    #: Target particle spacing when resampling the searched path (m). The shrink is a
    #: diffusion whose slowest mode needs ~N^2 sweeps on N particles, and a sweep costs about
    #: the same for any N (an IK and a collision batch), so the spacing sets the net's time;
    #: it must stay fine enough for the bends the fit should see: a circle of radius r
    #: drawn by particles this far apart is off by spacing^2 / (8 r) (cf. `planning.config`).
    spacing: float = 0.02
    #: Largest move of one particle in one iteration (m): keeps IK local and moves checkable.
    max_move: float = 0.005
    #: The same in stage 1 (None: `max_move`). Stage 1 pulls the searched path taut, and
    #: its over-relaxed shrink asks moves of centimetres that a 5 mm cap spreads over many
    #: sweeps; stage 2 forms the arcs, where small steps keep the net smooth for the fit.
    stage1_max_move: float | None = None
    epsilon: float = 1e-10
    #: Mean movement per iteration (m) below which a stage counts as settled. The thesis'
    #: epsilon sits below the noise floor that IK back-projection leaves (~1e-7 m), so
    #: without this a stage would always run to its cap; at 1 um the slowest shrink mode
    #: has at most ~0.1 mm left to go, far inside the primitive tolerance. 0 = off.
    settle: float = 1e-6
    #: Stage 1 also ends once the net's TCP length shrank by less than `taut_length` (m)
    #: over the last `taut_window` iterations: it is taut, and what still moves slides
    #: along the path (equidistance), which stage 2 carries on with anyway. In the planning
    #: benchmark's cells the iterations after this point shorten paths by under a
    #: millimetre (the fit tolerance is 5 mm) and make up a third of stage 1; the fitted
    #: primitives and lengths stay those of the full run. 0 = off.
    taut_length: float = 1e-4
    taut_window: int = 10
    stage1_iterations: int = 300
    #: Stage 2 forms the arcs within a few dozen iterations; run much longer, its gentle
    #: line shrink keeps creeping and can split a line (cf. `planning.config`).
    stage2_iterations: int = 60
    #: Keep the arm this far (m) from obstacles and itself, by the broad phase's sphere gap
    #: (a lower bound of the true clearance): a move that ends nearer is refused unless the
    #: particle was nearer still. Needs a checker with free margins; 0 = off.
    min_gap: float = 0.0
    #: Also require the midpoints of a moved particle's two edges to be allowed.
    check_edge_midpoints: bool = True
    ik: PositionIKParams = field(default_factory=PositionIKParams)

    @staticmethod
    def exploring(**kw) -> ElasticNetParams:
        """Low shrink: smooth the road but stay near it (keeps the roadmap's clearance)."""
        return replace(ElasticNetParams(stage1_shrink=0.05), **kw)

    @staticmethod
    def final(**kw) -> ElasticNetParams:
        """High shrink: pull the final path taut around what is known to be occupied."""
        return replace(ElasticNetParams(stage1_shrink=0.7), **kw)


class StopReason(str, Enum):
    CONVERGED = "converged"  # mean movement below epsilon
    SETTLED = "settled"  # mean movement below `settle` (the IK's noise floor is near)
    TAUT = "taut"  # stage 1: the TCP length stopped shrinking (`taut_length`)
    BLOCKED = "blocked"  # every proposed move was rejected
    ITERATION_CAP = "iteration_cap"
    NOTHING_TO_DO = "nothing_to_do"  # fewer than three particles


@dataclass(frozen=True)
class StageReport:
    iterations: int
    stop: StopReason
    final_movement: float  # E of the last iteration (m)


@dataclass(frozen=True)
class ElasticNetResult:
    particles: Particles
    initial: Particles
    stage1: StageReport
    stage2: StageReport
    rejected_moves: int
    accepted_moves: int
    seconds: float
    #: Moves whose exact check a free margin made unnecessary (`MarginValidity`).
    certified_moves: int = 0

    @property
    def iterations(self) -> int:
        return self.stage1.iterations + self.stage2.iterations

    def describe(self) -> str:
        return (f"elastic net: {len(self.particles)} particles, stage 1 {self.stage1.iterations} "
                f"it ({self.stage1.stop.value}), stage 2 {self.stage2.iterations} it "
                f"({self.stage2.stop.value}); TCP length {self.initial.tcp_length() * 1000:.0f} "
                f"-> {self.particles.tcp_length() * 1000:.0f} mm; {self.rejected_moves} of "
                f"{self.rejected_moves + self.accepted_moves} moves rejected")


def run_elastic_net(
    robot: Robot,
    joint_path: Sequence[Array] | Array,
    *,
    allowed: AllowedFn | None = None,
    validity: ValidityChecker | None = None,
    params: ElasticNetParams | None = None,
    progress: Progress | None = None,
) -> ElasticNetResult:
    """Resample a searched joint path into particles and relax them (both stages).

    Args:
        robot: kinematics for FK and IK.
        joint_path: the searched path, first and last configurations are kept exactly.
        allowed: TCP points -> bool, False for occupied/unreachable space (octree).
        validity: arm collision and joint limits for the particles' joints.
        params: forces and budgets; `ElasticNetParams.final()` by default.
        progress: reports per iteration and can cancel (raises `Cancelled`).
    """
    params = params or ElasticNetParams.final()
    initial = resample_joint_path(robot, joint_path, params.spacing)
    return relax(robot, initial, allowed=allowed, validity=validity, params=params,
                 progress=progress)


def relax(
    robot: Robot,
    particles: Particles,
    *,
    allowed: AllowedFn | None = None,
    validity: ValidityChecker | None = None,
    params: ElasticNetParams | None = None,
    progress: Progress | None = None,
) -> ElasticNetResult:
    """Run both stages on given particles (already about equidistant)."""
    params = params or ElasticNetParams.final()
    net = _Net(robot, particles, allowed, validity, params)
    t0 = time.perf_counter()
    total = max(1, params.stage1_iterations + params.stage2_iterations)
    s1 = net.run_stage(1, params.stage1_iterations, progress, 0.0, total)
    s2 = net.run_stage(2, params.stage2_iterations, progress, s1.iterations, total)
    return ElasticNetResult(Particles(net.P.copy(), net.Q.copy()), particles, s1, s2,
                            net.rejected, net.accepted, time.perf_counter() - t0,
                            net.certified_moves)


def turn_angles(P: Array) -> Array:
    """Turn angle at each interior point of a polyline (N - 2,), radians in [0, pi]."""
    a = np.diff(P, axis=0)
    # atan2(|a x b|, a . b): well conditioned at every angle (arccos of the normalised dot
    # product turns its last bit into ~1e-8 rad near straight)
    cross = row_norms(np.cross(a[:-1], a[1:]))
    return np.arctan2(cross, np.einsum("ij,ij->i", a[:-1], a[1:]))


class _Net:
    """Mutable state of one relaxation: positions P, joints Q, counters."""

    def __init__(self, robot: Robot, particles: Particles, allowed: AllowedFn | None,
                 validity: ValidityChecker | None, params: ElasticNetParams):
        self.robot = robot
        self.P = np.array(particles.points, dtype=float)
        self.Q = np.array(particles.joints, dtype=float)
        self.allowed = allowed
        self.validity = validity
        self.p = params
        self.ik = BatchPositionIK(robot, params.ik)
        self.rejected = 0
        self.accepted = 0
        self.E = np.inf  # mean movement of the last iteration (m)
        n = len(self.P)
        self._pinned = np.zeros(n, dtype=bool)
        # Certified moves: per particle the joints of its last exact check and the free margin
        # it gave; a move whose arm travel from there stays below the margin needs no exact
        # check (identical answers, see `CollisionChecker.is_valid_batch_margin`).
        self._certify = validity is not None and hasattr(validity, "is_valid_batch_margin")
        self._ref_Q = self.Q.copy()
        self._ref_margin = np.full(n, -np.inf)
        self.certified_moves = 0
        # Per particle a lower bound of its sphere gap (min_gap); unknown (-inf) at first.
        self._gap = np.full(n, -np.inf)
        if self._certify and params.min_gap > 0.0:
            valid, margin = validity.is_valid_batch_margin(self.Q)
            self._ref_margin = np.where(np.asarray(valid, bool), margin, -np.inf)
            self._gap = self._ref_margin.copy()
        # The compiled move test once it is compiled; while a first run's background compile
        # has not delivered it, the numpy path (its interpreted Python is ~10x slower).
        self._kernel = (_kernel_model(robot, allowed, validity)
                        if self._certify and COMPILED_MOVES and not is_pending(check_moves)
                        else None)

    # ---------------------------------------------------------------- stages
    def run_stage(self, stage: int, budget: int, progress: Progress | None, done: int,
                  total: int) -> StageReport:
        if len(self.P) < 3:
            return StageReport(0, StopReason.NOTHING_TO_DO, 0.0)
        p = self.p
        taut = stage == 1 and p.taut_length > 0.0
        lengths = np.empty(budget + 1)  # the TCP length before the stage and after each sweep
        n_len = 0
        if taut:
            lengths[0] = polyline_length(self.P)
            n_len = 1
        it = 1
        per = SWEEPS_PER_REPORT  # a report (and its cancel check) every `per` sweeps
        while it <= budget:
            if progress is not None and it % per == 1:
                progress.update((done + it) / total, f"elastic net stage {stage}, iteration {it}")
            E = self.E
            lam = p.c_error * E / (1.0 + p.c_error * E) if np.isfinite(E) else 1.0
            self.E, accepted, proposed = self.iterate(stage, lam)
            if proposed and not accepted:
                return StageReport(it, StopReason.BLOCKED, 0.0)
            if self.E < p.epsilon:
                return StageReport(it, StopReason.CONVERGED, float(self.E))
            if self.E < p.settle:
                return StageReport(it, StopReason.SETTLED, float(self.E))
            if taut:
                lengths[n_len] = polyline_length(self.P)
                n_len += 1
                w = p.taut_window
                if n_len > w and lengths[n_len - 1 - w] - lengths[n_len - 1] < p.taut_length:
                    return StageReport(it, StopReason.TAUT, float(self.E))
            it += 1
        return StageReport(budget, StopReason.ITERATION_CAP, float(self.E))

    def _cap(self, stage: int) -> float:
        """The largest particle move of a sweep of this stage (m)."""
        p = self.p
        return p.stage1_max_move if stage == 1 and p.stage1_max_move is not None else p.max_move

    def iterate(self, stage: int, lam: float) -> tuple[float, int, int]:
        """One sweep: (E, accepted, proposed moves).

        Forces are evaluated one colour class at a time on the tentative positions
        (Gauss-Seidel, compiled: `net_forces.propose_moves`); the moves are then checked
        together in one batch (one `allowed`, one IK, one validity call per sweep) and the
        rejected ones retried at half length, except those pinned (see below).
        """
        p = self.p
        idx, D, trial = propose_moves(self.P, stage, lam, p.c_equidistance, p.c_rotation,
                                      p.c_shrink, p.c_line_shrink, p.stage1_shrink, p.r_max,
                                      p.r_min, self._cap(stage))
        idx, D, pin = _live_moves(idx, D, trial, self.P, self._pinned)
        if not len(idx):
            return 0.0, 0, 0
        # A particle refused at both lengths last sweep is pinned against a constraint (the
        # octree, the arm's gap): it proposed the half move straight away and is not
        # retried - a retry call for it almost never bought a move (module docstring).
        ok = self.try_moves(idx, D, trial)
        retry = _halve_retries(ok, pin, idx, D, trial, self.P)
        ok2 = (self.try_moves(idx[retry], D[retry], trial) if len(retry)
               else np.zeros(0, dtype=bool))
        self.rejected += _repin(ok, pin, retry, ok2, idx, self._pinned)
        accepted = int(ok.sum())
        self.accepted += accepted
        E = float(row_norms(D[ok]).sum()) / max(1, len(self.P) - 2)
        return E, accepted, len(idx)

    # ---------------------------------------------------------------- moves
    def try_moves(self, idx: Array, D: Array, trial: Array) -> Array:
        """Apply the moves that pass every test; returns which were accepted.

        Edge midpoints are probed against both the old and the tentative position of each
        neighbour, since the neighbour's own move may be accepted or not.
        """
        if self._kernel is not None:
            return self._try_moves_compiled(idx, D, trial)
        new_P = self.P[idx] + D
        ok = np.ones(len(idx), dtype=bool)
        if self.allowed is not None:
            probe = [new_P]
            if self.p.check_edge_midpoints:
                for nb in (idx - 1, idx + 1):
                    probe += [0.5 * (new_P + self.P[nb]), 0.5 * (new_P + trial[nb])]
            flags = np.asarray(self.allowed(np.concatenate(probe)), dtype=bool)
            ok &= flags.reshape(len(probe), len(idx)).all(axis=0)
        cand = np.nonzero(ok)[0]
        if not len(cand):
            return ok
        ref = 0.5 * (self.Q[idx[cand] - 1] + self.Q[idx[cand] + 1])
        res = self.ik.solve(new_P[cand], self.Q[idx[cand]], ref)
        ok[cand] &= res.ok
        Qn = res.joints
        margin_of = None  # per candidate: the free margin of its exact check (NaN: none)
        if self.validity is not None:
            good = np.nonzero(res.ok)[0]
            if len(good):
                if self._certify:
                    valid, margin, gap = self._check_certified(idx[cand[good]], Qn[good])
                    margin_of = np.full(len(cand), np.nan)
                    margin_of[good] = margin
                    gap_of = np.full(len(cand), -np.inf)
                    gap_of[good] = gap
                else:
                    valid = np.asarray(self.validity.is_valid_batch(Qn[good]), dtype=bool)
                ok[cand[good[~valid]]] = False
        acc = np.nonzero(ok)[0]
        pos = np.searchsorted(cand, acc)
        if margin_of is not None:
            checked = ~np.isnan(margin_of[pos])  # accepted after an exact check: new reference
            moved = idx[acc[checked]]
            self._ref_Q[moved] = Qn[pos[checked]]
            self._ref_margin[moved] = margin_of[pos[checked]]
            self._gap[idx[acc]] = gap_of[pos]
        self.Q[idx[acc]] = Qn[pos]
        self.P[idx[acc]] = (res.points[pos] if res.points is not None else
                            np.asarray(self.robot.batch_fk(Qn[pos]).positions, dtype=float))
        return ok

    def _try_moves_compiled(self, idx: Array, D: Array, trial: Array) -> Array:
        """`try_moves` in one compiled pass (`net_kernel.check_moves`); FCL decides here
        the few moves the broad phase could not clear."""
        km, p = self._kernel, self.p
        grid = km.grid if km.grid is not None else _NO_GRID
        status, Qn, Pn, margin, gap, frames, env_c, self_c, certified = check_moves(
            self.P, self.Q, idx, D, trial, *grid, km.grid is not None,
            p.check_edge_midpoints, km.robot, km.checker, km.recorded_q, km.recorded_half,
            p.ik.nullspace_gain, p.ik.max_joint_jump, p.ik.tolerance * 10.0, self._ref_Q,
            self._ref_margin, self._gap, p.min_gap)
        self.certified_moves += certified
        ask = np.flatnonzero(status == ASK_FCL)
        if len(ask):
            free = ask[~km.first_contacts(frames[ask], env_c[ask], self_c[ask])]
            rows = np.zeros(len(idx), dtype=bool)
            rows[free] = True
            apply_moves(self.P, self.Q, idx, rows, Qn, Pn, margin, gap, self._ref_Q,
                        self._ref_margin, self._gap)
            status[free] = ACCEPTED
        return status == ACCEPTED

    def _check_certified(self, particles: Array, Q: Array) -> tuple[Array, Array, Array]:
        """Validity of new joints Q for these particles, skipping the exact check where the
        arm travel from the particle's last exact check stays inside its free margin (less
        `min_gap`); with the margin of each exact check and a lower bound of each gap."""
        v = self.validity
        need = self.p.min_gap
        travel = v.travel(self._ref_Q[particles], Q)
        sure = self._ref_margin[particles] > travel + need + 1e-9
        self.certified_moves += int(sure.sum())
        valid, margin = v.is_valid_batch_margin(Q, sure)
        valid = np.asarray(valid, dtype=bool)
        margin = np.asarray(margin, dtype=float)
        gap = np.where(sure, self._ref_margin[particles] - travel, margin)
        if need > 0.0:  # nearer than min_gap, and nearer than the particle was: refused
            valid &= ~(~sure & (margin < need) & (margin < self._gap[particles]))
        return valid, margin, gap


#: Use the compiled move test (`net_kernel`) where robot, validity and `allowed` provide
#: its pieces; False forces the numpy path (the tests compare the two).
COMPILED_MOVES = True
#: Sweeps between two progress reports (each also a cancel check): a sweep is well under a
#: millisecond on a transfer's ~25 particles, so a cancel is still instant. The particles do
#: not depend on it.
SWEEPS_PER_REPORT = 16


def _live_moves(idx: Array, D: Array, trial: Array, P: Array, pinned: Array,
                ) -> tuple[Array, Array, Array]:
    """The proposed moves of non-zero length: (particles, moves, pinned flag per move); a
    pinned particle's move is halved straight away, its tentative position with it."""
    live = (D * D).sum(axis=1) > 0.0  # NaN and underflow count as no move
    idx, D = idx[live], D[live]
    pin = pinned[idx]
    D[pin] *= 0.5
    trial[idx[pin]] = P[idx[pin]] + D[pin]
    return idx, D, pin


def _halve_retries(ok: Array, pin: Array, idx: Array, D: Array, trial: Array, P: Array,
                   ) -> Array:
    """Rows refused at full length and not pinned: their moves (and tentative positions)
    halved for a second test; returns those rows."""
    rows = np.flatnonzero(~ok & ~pin)
    D[rows] *= 0.5
    trial[idx[rows]] = P[idx[rows]] + D[rows]
    return rows


def _repin(ok: Array, pin: Array, retry: Array, ok2: Array, idx: Array, pinned: Array,
           ) -> int:
    """Merge the retries' answers into ok and pin (in place) the particles refused at
    both lengths, or at half length when pinned; returns how many were refused."""
    refused = ~ok & pin
    ok[retry[ok2]] = True
    refused[retry[~ok2]] = True
    pinned[:] = False
    pinned[idx[refused]] = True
    return int(refused.sum())

_NO_GRID = (np.zeros(3), 1.0, 0, np.zeros(0, dtype=bool))


def _kernel_model(robot: Robot, allowed: AllowedFn | None,
                  validity: ValidityChecker | None) -> NetKernelModel | None:
    """The compiled move test's model, or None when a piece has no compiled form: a robot
    without `net_kernel_robot` (or with a tool off the flange axis), a validity without
    `net_kernel_validity`, an `allowed` without `grid_flags`."""
    robot_hook = getattr(robot, "net_kernel_robot", None)
    validity_hook = getattr(validity, "net_kernel_validity", None)
    if robot_hook is None or validity_hook is None:
        return None
    if allowed is not None and not hasattr(allowed, "grid_flags"):
        return None
    rob, val = robot_hook(), validity_hook()
    if rob is None or val is None:
        return None
    checker, rec_q, rec_half, exact = val
    grid = allowed.grid_flags() if allowed is not None else None
    return NetKernelModel(rob, checker, np.ascontiguousarray(rec_q, dtype=float),
                          np.ascontiguousarray(rec_half, dtype=float), exact, grid)
