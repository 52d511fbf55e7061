"""The elastic net's move test as one compiled pass (numba), FCL aside.

`elastic_net._Net.try_moves` asks, for every proposed particle move of a sweep: are the new
point and its edge midpoints in free leaves, does the local position IK place the arm next
to its joints, is the arm inside its limits, off the recorded collision postures, certified
free by its last exact check's margin or else passed by the broad phase (and far enough,
`min_gap`)? As numpy calls that is ~40 array operations and six module boundaries per call,
~120 us for a few dozen particles and ~2/3 of the net's time; the arithmetic itself is a
few microseconds. `check_moves` does all of it per move in one loop; only the moves whose
broad phase leaves candidate pairs go back to Python for FCL (`ASK_FCL`, rare in the net).

It needs compiled pieces of the robot (position IK, TCP FK, link frames), of the checker
(covering spheres, pruning) and of the world (leaf flags); `elastic_net` uses it when all
three provide them (`NetKernelModel`) and the numpy path otherwise. Both give the same
particles bit for bit (tests/planning/test_net_kernel.py runs both).

Serves (the user-felt figure): the elastic net of every plan and re-plan: 0.7 s in Python in
the thesis run.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from assistant.collision.broad_phase import FREE, _broad_row, _prune_and_flag
from assistant.kernels.helpers import within_limits, wrap_pi
from assistant.kernels.lazy import kernel
from assistant.robots.dh import chain_row
from assistant.robots.rv2aj_fk_batch import tcp_row
from assistant.robots.rv2aj_position_ik import as_tuples, solve_row
from assistant.world.leaf_lookup import leaf_flag

Array = np.ndarray

#: `check_moves` status per move
REFUSED, ACCEPTED, ASK_FCL = 0, 1, 2


@dataclass(frozen=True)
class NetKernelModel:
    """What `check_moves` needs besides the net's own arrays.

    robot: (arm, tool_length, lower, upper, n_pitch_steps, pitch_step, BP, BM, BK, v,
    tool_offset, F) - the RV-2AJ's closed-form position IK and TCP FK constants and the
    DH chain's fixed parts (`RV2AJ.net_kernel_robot`).
    checker: the covering spheres, obstacle boxes, self pairs and pruning segments
    (`CollisionChecker.net_kernel_checker`).
    recorded_q, recorded_half: recorded collision postures (K, dof) and the box half-widths
    around them (dof,), inf for joints the boxes do not limit.
    first_contacts: FCL for the moves the broad phase could not clear (frames, env_c,
    self_c) -> hit per row.
    grid: (origin, leaf, n, free flags) of the world's leaves, or None (no `allowed`).
    """

    robot: tuple
    checker: tuple
    recorded_q: Array
    recorded_half: Array
    first_contacts: Callable[[Array, Array, Array], Array]
    grid: tuple | None


@kernel(cache=True)
def check_moves(P: Array, Q: Array, idx: Array, D: Array, trial: Array, grid_origin: Array,
                leaf: float, n_grid: int, free: Array, use_grid: bool, check_mid: bool,
                robot: tuple, checker: tuple, rec_q: Array, rec_half: Array, gain: float,
                max_jump: float, tol10: float, ref_Q: Array, ref_margin: Array,
                gap_lb: Array, need: float) -> tuple:
    """Test the moves D of particles idx (P, Q their points and joints, trial the
    tentative positions of the sweep) and apply those that pass outright.

    Returns (status, joints Qn, points Pn, margin, gap, frames, env_c, self_c, certified):
    status REFUSED / ACCEPTED (already applied to P, Q and the reference arrays) /
    ASK_FCL (passed everything but the exact check: `apply_moves` once FCL says free);
    margin is the exact check's free margin (NaN when the move was certified), gap a lower
    bound of its sphere gap; frames, env_c, self_c the FCL questions; certified the number
    of moves the margins certified. Every test is the numpy path's (`elastic_net`).
    """
    (arm, tool_length, lower, upper, n_steps, step, BP, BM, BK, v, tool_offset, F) = robot
    (radii, sph_link, sph_local, sph_r, sph_shape, env_lo, env_hi, sp_a, sp_b, sp_pair,
     n_shapes, n_pairs, shape_link, seg_a, seg_b, seg_r, box_R, box_c, box_h, pair_a,
     pair_b, apart) = checker
    m = idx.shape[0]
    dof = Q.shape[1]
    status = np.zeros(m, dtype=np.int8)
    Qn = np.empty((m, dof))
    Pn = np.empty((m, 3))
    margin = np.full(m, np.nan)
    gap = np.full(m, -np.inf)
    frames = np.zeros((m, dof + 1, 4, 4))
    env_c = np.zeros((m, n_shapes, env_lo.shape[0]), dtype=np.bool_)
    self_c = np.zeros((m, n_pairs), dtype=np.bool_)
    centre = np.empty((sph_r.shape[0], 3))
    T = np.empty((4, 4))
    A = np.empty((n_shapes, 3))
    B = np.empty((n_shapes, 3))
    la = np.empty(3)
    lb = np.empty(3)
    q = np.empty(dof)
    ref = np.empty(dof)
    pos = np.empty(3)
    rot = np.empty((3, 3))
    certified = 0
    broad = np.zeros(m, dtype=np.bool_)  # moves for the broad phase
    arm_t, lo, hi = as_tuples(arm, lower, upper)  # the IK's constants, never counted
    for i in range(m):
        k = idx[i]
        x, y, z = P[k, 0] + D[i, 0], P[k, 1] + D[i, 1], P[k, 2] + D[i, 2]
        if use_grid:
            if not leaf_flag(x, y, z, grid_origin, leaf, n_grid, free):
                continue
            if check_mid and not _midpoints_free(x, y, z, k, P, trial, grid_origin, leaf,
                                                 n_grid, free):
                continue
        # Position IK next to the particle's joints, the free joints pulled towards the
        # neighbours' mean (`RV2AJ.batch_position_ik`).
        seed = (Q[k, 0], Q[k, 1], Q[k, 2], Q[k, 3], Q[k, 4])
        for j in range(dof):
            ref[j] = 0.5 * (Q[k - 1, j] + Q[k + 1, j])
        s_seed = seed[1] + seed[2] + seed[3]
        pitch, q6 = s_seed, seed[4]
        if gain > 0.0:
            pitch = s_seed + gain * wrap_pi(ref[1] + ref[2] + ref[3] - s_seed)
            q6 = q6 + gain * (ref[4] - q6)
        if not solve_row(x, y, z, seed, pitch, q6, arm_t, tool_length, max_jump, lo, hi,
                         n_steps, step, q):
            continue
        tcp_row(q, arm, BP, BM, BK, v, tool_offset, pos, rot)
        ex, ey, ez = x - pos[0], y - pos[1], z - pos[2]
        if not np.sqrt(ex * ex + ey * ey + ez * ez) <= tol10:
            continue
        Qn[i] = q
        Pn[i] = pos
        # Validity: certified by the last exact check's margin, or the broad phase.
        travel = 0.0
        for j in range(dof):
            travel += abs(q[j] - ref_Q[k, j]) * radii[j]
        sure = ref_margin[k] > travel + need + 1e-9
        if sure:
            certified += 1
        if not within_limits(q, lower, upper) or _near_recorded(q, rec_q, rec_half):
            continue
        if sure:
            status[i] = ACCEPTED
            gap[i] = ref_margin[k] - travel
            continue
        broad[i] = True
    # The moves left to the broad phase, posed in a pass of their own first (as
    # `broad_phase.certify_samples`: with the DH chain's arithmetic in the same loop, numba
    # left the broad phase's array arguments counted in and out per move).
    for i in range(m):
        if broad[i]:
            chain_row(Qn[i], F, frames[i], T)
    for i in range(m):
        if not broad[i]:
            continue
        g = _broad_row(frames, i, sph_link, sph_local, sph_r, sph_shape, env_lo, env_hi,
                       sp_a, sp_b, sp_pair, centre, env_c, self_c)
        margin[i] = g
        gap[i] = g
        if need > 0.0 and g < need and g < gap_lb[idx[i]]:
            continue  # nearer than min_gap, and nearer than the particle was: refused
        free_row = _prune_and_flag(frames, i, env_c, self_c, shape_link, seg_a, seg_b, seg_r,
                                   box_R, box_c, box_h, pair_a, pair_b, apart, A, B, la,
                                   lb) == FREE
        status[i] = ACCEPTED if free_row else ASK_FCL
    apply_moves(P, Q, idx, status == ACCEPTED, Qn, Pn, margin, gap, ref_Q, ref_margin,
                gap_lb)
    return status, Qn, Pn, margin, gap, frames, env_c, self_c, certified


@kernel(cache=True)
def apply_moves(P: Array, Q: Array, idx: Array, rows: Array, Qn: Array, Pn: Array,
                margin: Array, gap: Array, ref_Q: Array, ref_margin: Array,
                gap_lb: Array) -> None:
    """Move the particles of the flagged rows; an exactly checked move (margin not NaN)
    becomes its particle's new reference for the margin certificates."""
    for i in range(idx.shape[0]):
        if not rows[i]:
            continue
        k = idx[i]
        if not np.isnan(margin[i]):
            ref_Q[k] = Qn[i]
            ref_margin[k] = margin[i]
        gap_lb[k] = gap[i]
        Q[k] = Qn[i]
        P[k] = Pn[i]


@kernel(cache=True, inline="always")
def _midpoints_free(x: float, y: float, z: float, k: int, P: Array, trial: Array,
                    origin: Array, leaf: float, n: int, free: Array) -> bool:
    """The midpoints of particle k's two edges, to each neighbour's old and tentative
    position (the neighbour's own move may be accepted or not), in free leaves."""
    for nb in (k - 1, k + 1):
        for W in (P, trial):
            if not leaf_flag(0.5 * (x + W[nb, 0]), 0.5 * (y + W[nb, 1]), 0.5 * (z + W[nb, 2]),
                             origin, leaf, n, free):
                return False
    return True


@kernel(cache=True, inline="always")
def _near_recorded(q: Array, rec_q: Array, rec_half: Array) -> bool:
    """Inside the posture box of a recorded collision (`indications.near_posture`)."""
    for r in range(rec_q.shape[0]):
        inside = True
        for j in range(q.shape[0]):
            if not abs(q[j] - rec_q[r, j]) <= rec_half[j]:
                inside = False
                break
        if inside:
            return True
    return False
