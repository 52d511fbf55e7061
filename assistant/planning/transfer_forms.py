"""A final plan's transfer in its cheapest acceptable form first: one straight joint move, or
the fewest joint moves along the searched path - scored on the fast model, certified exact.

Why: a programmer writes a transfer as one joint move (MOV / PTP / movej), or two round what
is in the way, and the planner ended there for most transfers anyway - after the elastic
net, the line/arc fit and a joint-move search of two exact motion checks and a clearance
scan per candidate (seconds on a URDF arm, 35-40 ms on the RV-2AJ). Here:

1. `direct_move`: the straight joint move from start to goal, if the fast conservative model
   (`CollisionChecker.fast`) finds it free and at least the required clearance from every
   known obstacle, is the transfer after one exact check of its dense path - no roadmap, no
   form search.
2. `via_move` (6- and 7-axis arms): two joint moves through one of the world's valid
   joint positions - the quickest whose two moves the fast model finds free and clear, the
   candidates' moves screened in batched calls, quickest first, until one keeps the
   clearance. A wall between start and goal is passed over or round in two moves, without
   a search.
3. `moves_along`: the searched path's fewest joint moves that keep the clearance
   (`joint_moves.fewest_joint_moves`, every candidate scored on the fast model), certified
   by the exact check of the chosen moves.

Only when neither keeps the clearance does the transfer go through the smoothing (net, fit,
its own joint-move form). The clearance is the requirement; a smoothed path's cycle time is
no longer compared with the joint moves' (on the planning benchmark's cells the joint moves
were the quicker form of nearly every transfer they kept the clearance on). The fast model's
clearance is a lower bound of the real one, so what it keeps, the real path keeps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from assistant.mission.motion import Trajectory
from assistant.planning.joint_moves import (
    JointMoveParams,
    fewest_joint_moves,
    motions_free,
    step_verify,
)
from assistant.planning.known_world import KnownVerifier
from assistant.planning.transfer_ends import _joint_moves
from assistant.robots.model import Robot
from assistant.trajectory.assemble import AssemblyParams, AssemblyResult, verify
from assistant.world.model import WorldModel

Array = np.ndarray

#: Arm travel (m) between the samples of the vias' coarse screen. Twice the moves' screen
#: (`joint_moves.SCREEN_STEP`): most vias fail it by a contact half a move long, found with
#: half the samples; what passes is checked at the checker's own step before it counts. On
#: the arms benchmark's UR5/UR10 via queries: 15-30 % less CPU, the same vias chosen.
VIA_SCREEN_STEP = 0.08


def clearance_kept(screen: KnownVerifier, path: Sequence[Array], target: float,
                   step: float) -> tuple[bool, float]:
    """(whether the path keeps `target` from every known obstacle, its clearance on the fast
    model): the fast model's lower bound decides when it reaches the target; below it, the
    real shapes are measured where the capsules come that close
    (`FastChecker.keeps_clearance`), since the capsules reach beyond a UR's housings by a
    few centimetres."""
    c = float(screen.min_clearance_along(path, max_step=step))
    if c >= target:
        return True, c
    exact = getattr(screen.checker, "keeps_clearance", None)
    return (exact is not None and bool(exact(path, target, step))), c


def direct_move(robot: Robot, q_s: Array, q_g: Array, *, verifier: KnownVerifier,
                screen: KnownVerifier, exempt: frozenset[int], clearance: float,
                assembly: AssemblyParams, label: str, params: JointMoveParams,
                ) -> tuple[AssemblyResult | None, float]:
    """(the certified straight joint move, or None; its clearance on the fast model, -1 if
    it is not free there)."""
    if not verifier.check_motion(q_s, q_g, exempt).valid:
        return None, -1.0
    kept, c = clearance_kept(screen, [q_s, q_g], clearance, step_verify(params))
    if not kept:
        return None, max(c, 0.0)
    traj = _joint_moves(robot, [q_s, q_g], label, assembly)
    # at the program's joint speed, as the joint-move form writes its moves
    traj = Trajectory(traj.start, [replace(m, speed=None) for m in traj.motions])
    checked = verify(robot, traj, verifier, clearance_step=assembly.clearance_step)
    return (checked if checked.ok else None), c


def moves_along(robot: Robot, joint_path: Sequence[Array], *, verifier: KnownVerifier,
                screen: KnownVerifier, exempt: frozenset[int], clearance: float,
                assembly: AssemblyParams, label: str, params: JointMoveParams,
                ) -> tuple[AssemblyResult | None, str]:
    """(the fewest certified joint moves along the searched path that keep `clearance` on
    the fast model, or None; why not)."""
    traj = _joint_moves(robot, list(joint_path), label, assembly)
    jm = fewest_joint_moves(robot, traj, verifier, exempt=exempt, floor=clearance,
                            target=clearance, step=assembly.step, speed=None, label=label,
                            params=params, screen=screen)
    if jm.result is None or jm.result.trajectory is None:
        return None, jm.reason
    return jm.result, ""


def via_move(robot: Robot, world: WorldModel, q_s: Array, q_g: Array, *,
             verifier: KnownVerifier, screen: KnownVerifier, exempt: frozenset[int],
             clearance: float, assembly: AssemblyParams, label: str,
             params: JointMoveParams, vias: int = 96, batch: int = 8, exact_vias: int = 3,
             ) -> AssemblyResult | None:
    """Two certified joint moves through one valid position of the world (the quickest of
    each leaf, the quickest `vias` leaves in order of duration) whose moves keep
    `clearance` on the fast model - or, if none does, measured on the real shapes for the
    `exact_vias` quickest valid ones; None if none keeps it.

    The vias are screened in batches that double from `batch` (one coarse call each), and
    the first via that keeps the clearance ends the search: on the planning benchmark the
    answer is most often among the first ten, and the screen of all 96 with the
    durations' row-wise max took a third of the queries' time (py-spy). Each survivor's
    clearance (one capsule pass) comes before its fine check: most survivors the fine
    check passes are nearer than the clearance, and those only matter for the
    `exact_vias` quickest, checked finely at the end. Every via gets the answers a screen
    of all of them gave it, in the same order: the same via is chosen."""
    _, offsets, Q = world.cell_positions_shared()
    if not len(Q):
        return None
    cand = _quickest_vias(robot, offsets, Q, q_s, q_g, vias)
    step = step_verify(params)
    near: list[Array] = []  # free by the coarse screen, nearer than the clearance
    lo, size = 0, batch
    while lo < len(cand):
        V = Q[cand[lo:lo + size]]
        lo, size = lo + len(V), 2 * size
        # a coarse screen of the batch's first moves in one call drops most; only their
        # survivors' second moves are screened (a via whose first move is in the way costs
        # no second screen)
        free = motions_free(screen, np.repeat(q_s[None], len(V), axis=0), V, exempt,
                            max_step=VIA_SCREEN_STEP)
        on = np.flatnonzero(free)
        if len(on):
            free[on] = motions_free(screen, V[on], np.repeat(q_g[None], len(on), axis=0),
                                    exempt, max_step=VIA_SCREEN_STEP)
        for v in V[free]:  # in order of duration
            if screen.min_clearance_along([q_s, v, q_g], max_step=step) < clearance:
                near.append(v)
                continue
            if not _fine_free(screen, q_s, v, q_g, exempt):
                continue
            got = _certified(robot, [q_s, v, q_g], verifier, assembly, label)
            if got is not None:
                return got
    # none keeps it by the capsules: the quickest few free ones measured on the real shapes
    tried = 0
    for v in near:
        if tried >= exact_vias:
            break
        if not _fine_free(screen, q_s, v, q_g, exempt):
            continue
        tried += 1
        if clearance_kept(screen, [q_s, v, q_g], clearance, step)[0]:
            got = _certified(robot, [q_s, v, q_g], verifier, assembly, label)
            if got is not None:
                return got
    return None


def _fine_free(screen: KnownVerifier, q_s: Array, v: Array, q_g: Array,
               exempt: frozenset[int]) -> bool:
    """Both moves through v free on the fast model at the checker's own step."""
    return bool(motions_free(screen, np.stack([q_s, v]), np.stack([v, q_g]), exempt).all())


def _quickest_vias(robot: Robot, offsets: Array, Q: Array, q_s: Array, q_g: Array,
                   n: int) -> Array:
    """Indices into Q of each leaf's quickest position through which to go from q_s to
    q_g (two synchronised joint moves at full speed), the `n` quickest leaves in order.

    Joint by joint on the positions' columns (`_columns`): numpy's row-wise max over
    ~36 000 five-joint rows took 3-12 ms (a reduction along the short axis), the columns
    0.6 ms; the values are the same."""
    vmax = np.maximum(robot.limits.velocity, 1e-6)
    C = _columns(Q)
    to = np.abs(C[0] - q_s[0]) / vmax[0]
    fro = np.abs(q_g[0] - C[0]) / vmax[0]
    for j in range(1, len(C)):
        np.maximum(to, np.abs(C[j] - q_s[j]) / vmax[j], out=to)
        np.maximum(fro, np.abs(q_g[j] - C[j]) / vmax[j], out=fro)
    dur = to + fro
    # each leaf's quickest position (the positions are grouped by leaf), the quickest
    # leaves first: a partition, not a sort of every position (~36 000 on the RV-2AJ)
    starts = offsets[:-1][np.diff(offsets) > 0]
    best = np.minimum.reduceat(dur, starts)
    n = min(len(best), n)
    top = np.argpartition(best, n - 1)[:n] if n < len(best) else np.arange(len(best))
    top = top[np.argsort(best[top], kind="stable")]
    ends = np.r_[starts[1:], len(dur)]
    return np.array([starts[i] + int(np.argmin(dur[starts[i]:ends[i]])) for i in top.tolist()],
                    dtype=np.int64)


#: The last positions array `_columns` was asked for and its columns (one slot: a world's
#: positions stay the same array until its selection changes, `WorldModel.cell_positions`).
_COLUMNS: tuple[Array, Array] | None = None


def _columns(Q: Array) -> Array:
    """Q's columns as contiguous rows (Q.T, copied once per positions array)."""
    global _COLUMNS
    got = _COLUMNS
    if got is not None and got[0] is Q:
        return got[1]
    C = np.ascontiguousarray(Q.T)
    _COLUMNS = (Q, C)
    return C


def _certified(robot: Robot, postures: list[Array], verifier: KnownVerifier,
               assembly: AssemblyParams, label: str) -> AssemblyResult | None:
    """Joint moves through the postures at the program's joint speed, if the exact
    verification passes them."""
    traj = _joint_moves(robot, postures, label, assembly)
    traj = Trajectory(traj.start, [replace(m, speed=None) for m in traj.motions])
    checked = verify(robot, traj, verifier, clearance_step=assembly.clearance_step)
    return checked if checked.ok else None
