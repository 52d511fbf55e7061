"""A transfer as a programmer writes it: the fewest straight joint moves (MOV / PTP / MoveJ /
movej) through postures of the verified smoothed path, each move checked exactly and kept at
least as far from every known obstacle as the clearance asks.

The elastic net and the line/arc fit give a smooth TCP path, but a transfer through free
space needs no Cartesian path at all: a programmer writes one joint move, or two around an
obstacle, and the controller runs them faster than a chain of lines and arcs (no
Cartesian speed limit, no exact stops between primitives). The vias are taken from the
smoothed path itself (it has the clearance), the farthest one a straight joint move still
reaches validly first (greedy, as `planning.shortcut` does for the roadmap's path); every
move must pass the exact continuous FCL check, the recorded collision postures and the
clearance floor; the result is verified as a whole like any other trajectory.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from assistant.mission.motion import Motion, MotionKind, Trajectory, Waypoint
from assistant.planning.known_world import KnownVerifier
from assistant.roadmap.edge_samples import edge_samples
from assistant.robots.model import Robot
from assistant.trajectory.assemble import AssemblyResult, joint_interpolation, verify

Array = np.ndarray

#: Arm travel (m) between the samples of the coarse screen of many candidate moves.
SCREEN_STEP = 0.04
#: Moves screened in one call when the first of them is asked for (`_Moves.prefetch`).
SCREEN_BATCH = 8


@dataclass(frozen=True)
class JointMoveParams:
    #: Postures of the smoothed path offered as vias (evenly spaced by arm travel).
    candidates: int = 24
    #: Most joint moves a transfer may become; more and the smoothed path is kept.
    max_moves: int = 3
    #: Arm travel (m) between clearance samples when screening a candidate move (the
    #: chosen moves are verified at 10 mm).
    clearance_step: float = 0.02
    #: Moving a via off the smoothed path to gain clearance: rounds of `samples` random
    #: displacements at each of `scales` (m of arm travel), best kept (seeded: the same
    #: plan for the same input).
    rounds: int = 3
    samples: int = 12
    scales: tuple[float, ...] = (0.06, 0.03, 0.015)
    seed: int = 35
    #: Largest blend radius (m) at a via (never more than half the verified clearance).
    blend: float = 0.01
    #: TCP lifts (m, base z) of path postures also offered as the single via.
    lifts: tuple[float, ...] = (0.05, 0.1, 0.2)
    #: Most distinct moves checked per transfer (`_Moves`).
    max_checks: int = 100
    #: Most candidate moves measured on the real shapes where the fast model's capsules
    #: come nearer than the target (`_Moves`; each ~3-10 ms on a UR). Four left a UR5
    #: transfer whose moves keep 15 mm to the smoothing (3 s instead of 0.8 s): the
    #: capsules reach beyond a UR's housings by up to a few centimetres.
    exact_checks: int = 16


@dataclass(frozen=True)
class JointMoveResult:
    """The joint-move form of a transfer (None if none verified) and what it cost."""

    result: AssemblyResult | None
    checks: int
    reason: str = ""
    clearance: float = 0.0


class _Moves:
    """Straight joint moves scored by their clearance (-1: invalid), counted and cached.

    At most `budget` distinct moves are checked: past it a new move scores -1 (never
    chosen) while the moves checked already keep their scores, so the search ends with the
    best it found. Why: where the cell does not allow the target clearance the via search
    tries every via and every displacement: a query took 34-36 s on a UR10 cell (8-9 s with
    100 checks; the thesis transfers need at most 67)."""

    def __init__(self, verifier: KnownVerifier, exempt: frozenset[int], step: float,
                 budget: int, target: float = np.inf, exact_budget: int = 0):
        self.verifier, self.exempt, self.step, self.budget = verifier, exempt, step, budget
        self.checks = 0
        self._seen: dict[bytes, float] = {}
        #: On the fast model: a valid move whose capsules come nearer than `target` is
        #: measured on the real shapes (at most `exact_budget` times): one that keeps the
        #: target scores it (`FastChecker.keeps_clearance`).
        self.target, self.exact_left = target, exact_budget
        #: Moves handed to `prefetch` and not screened yet, in the order handed.
        self._pending: dict[bytes, tuple[Array, Array]] = {}

    def prefetch(self, pairs: list[tuple[Array, Array]]) -> None:
        """Moves to screen at a coarse step (`motions_free`) before their own check: those
        it finds colliding score -1 without it. The screen runs when a move is first
        asked for, in one batched call with the next `SCREEN_BATCH` - 1 moves handed here
        after it: a search that stops at its first good via screens only the moves up
        to it (a move's screen does not depend on the moves it is screened with)."""
        for a, b in pairs:
            key = np.concatenate([a, b]).tobytes()
            if key not in self._seen:
                self._pending.setdefault(key, (a, b))

    def _screen(self, key: bytes) -> None:
        """The coarse screen of the pending move `key` and the pending moves after it."""
        keys = list(self._pending)
        batch = keys[keys.index(key):][:SCREEN_BATCH]
        todo = [self._pending.pop(k) for k in batch]
        free = motions_free(self.verifier, np.array([a for a, _ in todo]),
                            np.array([b for _, b in todo]), self.exempt,
                            max_step=SCREEN_STEP)
        for k, f in zip(batch, free.tolist(), strict=True):
            if not f:  # a coarse sample collides: invalid (the others get the fine check)
                self._seen[k] = -1.0

    def clearance(self, a: Array, b: Array) -> float:
        key = np.concatenate([a, b]).tobytes()
        if key in self._pending:
            self._screen(key)
        if key in self._seen:
            return self._seen[key]
        if self.checks >= self.budget:
            return -1.0
        self.checks += 1
        if not self.verifier.check_motion(a, b, self.exempt).valid:
            c = -1.0
        else:
            c = self.verifier.min_clearance_along([a, b], max_step=self.step)
            c = float(c) if np.isfinite(c) else 1.0  # no obstacle known: any move is clear
            exact = getattr(getattr(self.verifier, "checker", None), "keeps_clearance", None)
            if c < self.target and exact is not None and self.exact_left > 0:
                self.exact_left -= 1
                if exact([a, b], self.target, self.step):
                    c = self.target
        self._seen[key] = c
        return c

    def chain(self, postures: list[Array]) -> float:
        return min(self.clearance(a, b) for a, b in zip(postures[:-1], postures[1:],
                                                        strict=True))


def prefer_joint_moves(robot: Robot, asm: AssemblyResult, notes: list[str],
                       verifier: KnownVerifier, *, exempt: frozenset[int], clearance: float,
                       step: float, label: str, params: JointMoveParams | None = None,
                       screen: KnownVerifier | None = None,
                       ) -> tuple[AssemblyResult, list[str]]:
    """The verified smoothed transfer `asm`, or its fewest joint moves if they keep
    `clearance` (or the smoothed path's own, if that is less) and the program runs quicker
    with them (the predicted cycle time, `export.cycle_time`; fewer motions on a tie) - or
    if they keep the required `clearance` where the smoothed path does not: the clearance
    is a requirement, the cycle time a preference."""
    assert asm.trajectory is not None
    if screen is None:
        own = asm.report.min_clearance
    else:  # the smoothed path's clearance on the fast model (a lower bound)
        c = float(screen.min_clearance_along(asm.trajectory.dense_joint_path(),
                                             max_step=step_verify(params or JointMoveParams())))
        own = c if np.isfinite(c) else None
    floor = clearance if own is None else min(clearance, own)
    jm = fewest_joint_moves(robot, asm.trajectory, verifier, exempt=exempt, floor=floor,
                            target=clearance, step=step, speed=None, label=label,
                            params=params, screen=screen)
    moves = jm.result
    if moves is None or moves.trajectory is None:
        return asm, notes
    t_smooth = _cycle_seconds(robot, asm.trajectory)
    t_joint = _cycle_seconds(robot, moves.trajectory)
    n, n0 = len(moves.trajectory.motions), len(asm.trajectory.motions)
    if own is not None and own < clearance <= jm.clearance:
        better = True  # the required clearance, which only the joint moves keep, comes first
    elif t_joint is not None and t_smooth is not None:
        better = t_joint < t_smooth - 1e-3 or (abs(t_joint - t_smooth) <= 1e-3 and n < n0)
    else:
        better = n < n0
    if not better:
        return asm, notes + [f"{n} joint moves would not be quicker than the smoothed path"]
    when = "" if t_joint is None or t_smooth is None else (
        f", predicted {t_joint:.2f} s instead of {t_smooth:.2f} s")
    return moves, notes + [f"{n} joint move{'s' if n > 1 else ''} instead of the smoothed "
                           f"path's {n0} motions, {jm.clearance * 1000:.1f} mm from known "
                           f"obstacles{when}"]


def _cycle_seconds(robot: Robot, traj: Trajectory) -> float | None:
    """Predicted time of a piece as a program would run it (None: not writable)."""
    from assistant.export import ExportError, predict_cycle_time, program_from_trajectory

    try:
        prog = program_from_trajectory(traj, robot, name="PIECE", move_to_start=False)
        return predict_cycle_time(prog, robot).total_s
    except (ExportError, ValueError):
        return None


def fewest_joint_moves(robot: Robot, traj: Trajectory, verifier: KnownVerifier, *,
                       exempt: frozenset[int], floor: float, target: float, step: float,
                       speed: float | None, label: str, params: JointMoveParams | None = None,
                       screen: KnownVerifier | None = None) -> JointMoveResult:
    """The fewest verified joint moves along `traj`'s dense path (module docstring).

    Args:
        traj: the verified smoothed transfer, or a searched path as joint moves.
        verifier: exact checks against CAD and the recorded collision postures: the
            chosen moves are certified by it.
        screen: the fast conservative model behind the same checks (`CollisionChecker.fast`)
            that scores the candidate moves and measures their clearance (a lower bound of
            the real one); None: the verifier does.
        exempt: recorded collisions the transfer starts in (it must be allowed to leave).
        floor: smallest clearance (m) every move must keep from the known obstacles.
        target: clearance (m) the vias are moved off the path for (>= floor).
        step: arm travel (m) between the dense samples of each move.
        speed: joint speed (fraction of the maximum) of the moves; None: the program's default.
    """
    p = params or JointMoveParams()
    dense = traj.dense_joint_path()
    if len(dense) < 2:
        return JointMoveResult(None, 0, "nothing to move")
    cand = [dense[k] for k in _candidates(robot, dense, p.candidates)]
    moves = _Moves(screen or verifier, exempt, p.clearance_step, p.max_checks,
                   target=target, exact_budget=p.exact_checks if screen is not None else 0)
    rng = np.random.default_rng(p.seed)
    a, b = cand[0], cand[-1]
    best: list[Array] | None = None
    best_c = moves.clearance(a, b)
    if best_c >= floor:
        best = [a, b]
    if best is None and p.max_moves >= 2:
        # one via: the smoothed path's posture best seen from both ends, moved off the
        # path if it is short of the target
        # Lifted postures (an IK each: ~20 ms on a URDF arm) are offered only when no
        # posture of the path itself keeps the target.
        vias = cand[1:-1]
        vmax = np.maximum(robot.limits.velocity, 1e-6)

        def pick(vias: list[Array]) -> tuple[int, float]:
            # the quickest via among those keeping the target, else the clearest: scored
            # quickest first, so the first that keeps the target ends the scoring
            return choose_via([_seconds(a, v, vmax) + _seconds(v, b, vmax) for v in vias],
                              lambda i: min(moves.clearance(a, vias[i]),
                                            moves.clearance(vias[i], b)), target)

        moves.prefetch(_via_moves(a, b, vias, vmax))
        k, c = pick(vias) if vias else (0, -1.0)
        if c < target:
            lifted = _lifted(robot, cand[1:-1:2], p.lifts)
            if lifted:
                moves.prefetch(_via_moves(a, b, lifted, vmax))
                k2, c2 = pick(lifted)
                if c2 > c:
                    vias, k, c = lifted, k2, c2
        if vias:
            chain = [a, vias[k], b]
            if c < target and c >= 0.0:
                chain, c = _push_vias(robot, chain, moves, rng, p, target)
            if c >= floor:
                best, best_c = chain, c
    if best is None and p.max_moves >= 3:
        for demand in (target, floor, 0.0):
            chain = _greedy(cand, moves, demand, p.max_moves)
            if chain is None:
                continue
            c = moves.chain(chain)
            if c < target:
                chain, c = _push_vias(robot, chain, moves, rng, p, target)
            if c >= floor:
                best, best_c = chain, c
                break
    if best is None:
        return JointMoveResult(None, moves.checks, f"no chain of at most {p.max_moves} joint "
                               f"moves keeps {floor * 1000:.1f} mm")
    out = _joint_trajectory(robot, traj, best, step, speed, label, 0.0)
    checked = verify(robot, out, verifier, clearance_step=step_verify(p))
    if screen is None:
        c = checked.report.min_clearance
    else:  # the fast model's, a lower bound, at the verification's step; if that is short
        # of the floor, whether the real shapes keep it
        dense_out = out.dense_joint_path()
        c = float(screen.min_clearance_along(dense_out, max_step=step_verify(p)))
        c = None if not np.isfinite(c) else c
        keeps = getattr(screen.checker, "keeps_clearance", None)
        if c is not None and c < floor and keeps is not None and \
                keeps(dense_out, floor, step_verify(p)):
            c = floor
    if not checked.ok or (c is not None and c < floor):
        return JointMoveResult(None, moves.checks, checked.report.reason or
                               f"clearance {c * 1000:.1f} mm below {floor * 1000:.1f} mm")
    c = best_c if c is None else c
    # Vias need no exact stop: the controller rounds them within a radius of at most half
    # the verified clearance, so the rounded path keeps clear of what the check saw.
    blend = min(p.blend, 0.5 * c)
    if blend > 0.0 and len(best) > 2:
        out = _joint_trajectory(robot, traj, best, step, speed, label, blend)
        checked = replace(checked, trajectory=out)
    return JointMoveResult(checked, moves.checks, clearance=c)


def step_verify(p: JointMoveParams) -> float:
    """Clearance step of the final verification (finer than the search's screening)."""
    return min(0.01, p.clearance_step)


def choose_via(cost: list[float], score: Callable[[int], float], target: float,
               ) -> tuple[int, float]:
    """(index, score) of the quickest via whose score (clearance) keeps `target`, else of
    the clearest (ties: the first). Scored quickest first, so the first that keeps the
    target ends the scoring: each score is two exact motion checks and a clearance scan
    (~0.1 s on a URDF arm), and most transfers have a quick clear via."""
    scores: dict[int, float] = {}
    for i in sorted(range(len(cost)), key=lambda i: cost[i]):
        scores[i] = score(i)
        if scores[i] >= target:
            return i, scores[i]
    k = max(scores, key=lambda i: (scores[i], -i))
    return k, scores[k]


def _greedy(cand: list[Array], moves: _Moves, demand: float, max_moves: int,
            ) -> list[Array] | None:
    """From each kept posture the farthest later candidate one move reaches with `demand`
    clearance; None past `max_moves` moves or when no move leaves a posture."""
    kept = [0]
    while kept[-1] < len(cand) - 1:
        if len(kept) > max_moves:
            return None
        i = kept[-1]
        j = next((j for j in range(len(cand) - 1, i, -1)
                  if moves.clearance(cand[i], cand[j]) >= demand), None)
        if j is None:
            return None
        kept.append(j)
    return [cand[k] for k in kept]


def _push_vias(robot: Robot, chain: list[Array], moves: _Moves, rng: np.random.Generator,
               p: JointMoveParams, target: float) -> tuple[list[Array], float]:
    """Random local search moving each via (ends fixed) until the chain keeps `target`."""
    chain = [np.asarray(q, dtype=float) for q in chain]
    r = np.maximum(robot.arm_radii(), 1e-3)
    n = len(r)
    lo, hi = robot.limits.lower, robot.limits.upper
    c = moves.chain(chain)
    for _ in range(p.rounds):
        if c >= target:
            break
        for k in range(1, len(chain) - 1):
            a, b = chain[k - 1], chain[k + 1]

            def score(v: Array, a: Array = a, b: Array = b) -> float:
                return min(moves.clearance(a, v), moves.clearance(v, b))

            v, sv = chain[k], score(chain[k])
            for scale in p.scales:
                for _ in range(p.samples):
                    if sv >= target:
                        break
                    # a displacement of about `scale` metres of arm travel
                    w = np.clip(v + rng.standard_normal(n) * scale / (n * r), lo, hi)
                    sw = score(w)
                    if sw > sv:
                        v, sv = w, sw
            chain[k] = v
        c = moves.chain(chain)
    return chain, c


def _via_moves(a: Array, b: Array, vias: list[Array], vmax: Array,
               ) -> list[tuple[Array, Array]]:
    """Each via's two moves, the quickest via first (the order `choose_via` asks them)."""
    order = sorted(range(len(vias)),
                   key=lambda i: _seconds(a, vias[i], vmax) + _seconds(vias[i], b, vmax))
    return [m for i in order for m in ((a, vias[i]), (vias[i], b))]


def _seconds(a: Array, b: Array, vmax: Array) -> float:
    """Duration of a synchronised joint move at full speed (the slowest joint decides): the
    cycle-time order of candidate vias, without accelerations."""
    return float(np.max(np.abs(b - a) / vmax))


def _lifted(robot: Robot, postures: list[Array], lifts: tuple[float, ...]) -> list[Array]:
    """The postures with the TCP raised by each lift (base z, same orientation; IK seeded
    by the posture): the via a programmer puts above what is in the way."""
    near = getattr(robot, "ik_near", None)  # a numeric IK: the solution next to q only
    out = []
    for q in postures:
        T = robot.fk(q)
        for dz in lifts:
            U = T.copy()
            U[2, 3] += dz
            if near is not None:
                sol = near(U, q)
                if sol is not None:
                    out.append(np.asarray(sol, dtype=float))
                continue
            res = robot.ik(U, q)
            if res.ok:
                out.append(np.asarray(res.best(q), dtype=float))
    return out


def _candidates(robot: Robot, dense: Array, n: int) -> list[int]:
    """Indices into `dense`, first and last included, evenly spaced by arm travel."""
    travel = np.r_[0.0, np.cumsum(np.abs(np.diff(dense, axis=0)) @ robot.arm_radii())]
    if travel[-1] <= 0.0:
        return [0, len(dense) - 1]
    marks = np.linspace(0.0, travel[-1], max(2, n))
    idx = np.unique(np.searchsorted(travel, marks).clip(0, len(dense) - 1))
    out = [int(k) for k in idx]
    if out[0] != 0:
        out.insert(0, 0)
    if out[-1] != len(dense) - 1:
        out.append(len(dense) - 1)
    return out


def _joint_trajectory(robot: Robot, traj: Trajectory, postures: list[Array], step: float,
                      speed: float | None, label: str, blend: float) -> Trajectory:
    """JOINT motions through `postures`, blended by `blend` (m) at the vias; the last keeps
    the transfer's own target (name, exact joints), blend and tool actions."""
    last = traj.motions[-1]
    motions = []
    prev = np.asarray(postures[0], dtype=float)
    for k, q in enumerate(postures[1:], start=1):
        final = k == len(postures) - 1
        q = np.asarray(last.target.q if final else q, dtype=float)
        target = last.target if final else Waypoint(robot.fk(q), q)
        motions.append(Motion(MotionKind.JOINT, target,
                              joint_path=joint_interpolation(robot, prev, q, step), label=label,
                              speed=speed, blend_radius=last.blend_radius if final else blend,
                              actions_after=last.actions_after if final else ()))
        prev = q
    return Trajectory(traj.start, motions, traj.actions_at_start)


def motions_free(verifier: KnownVerifier, Q0: Array, Q1: Array, exempt: frozenset[int],
                 max_step: float | None = None) -> Array:
    """Whether each straight joint motion Q0[i] -> Q1[i] is free on the verifier's checker
    and clear of the recorded posture boxes (not those in `exempt`), all in one batched
    call (the motions' samples as `check_motion` takes them; with a coarser `max_step` a
    screen: what it calls invalid is, what it passes still needs the fine check)."""
    checker = verifier.checker
    ns = np.ascontiguousarray(checker.motion_samples_between(Q0, Q1, max_step),
                              dtype=np.int64)
    Q, edge, _ = edge_samples(np.ascontiguousarray(Q0), np.ascontiguousarray(Q1), ns)
    world = verifier.world
    near = world.near_recorded_collision(Q, exempt) if world.collisions else None
    ok = checker.is_valid_samples(Q, edge, first_only=True, known_invalid=near)
    bad = np.zeros(len(ns), dtype=bool)
    bad[edge[~ok]] = True
    return ~bad
