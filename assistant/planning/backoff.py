"""Back-off after a collision: return along the executed path to the last point the new plan
shares with it, then continue on the new plan (thesis Listing 6, step 5a-ii).

Two steps. `retreat_index`: the postures around the stop are known to touch something (the
indication's posture box), so the robot first retreats along its executed path - motion it
has just made without contact - to the last posture outside every recorded box, and the
rest of the transfer is re-planned from there; a plan from inside the box may leave it in
any direction, including on into the obstacle. `splice`: if the new plan's first stretch
retraces the way the robot came (to go round the obstacle from the other side), the robot
retraces its executed path instead, up to the last posture the new plan shares with it, and
joins the new plan there. "Shares" means within `tolerance` metres of arm
travel (sum over joints of arm radius x joint difference, an upper bound on how far any point
of the arm is apart). A back-off that would make the motion longer than simply following the
new plan is not taken.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Array = np.ndarray


@dataclass(frozen=True)
class Splice:
    """How to go on after a re-plan: back off along the executed path, then continue."""

    #: Joint path from the stop posture back to the common point (empty: no back-off).
    backoff: Array
    #: Joint path from the common point (or the stop) along the rest of the new plan.
    continuation: Array
    #: Index into the executed path of the common point (-1: none) and into the new plan.
    executed_index: int
    new_index: int

    @property
    def backs_off(self) -> bool:
        return len(self.backoff) > 1

    def path(self) -> Array:
        """The whole joint path to drive: back-off, then the continuation."""
        if not self.backs_off:
            return self.continuation
        return np.concatenate([self.backoff, self.continuation[1:]])


def arm_travel(radii: Array, A: Array, B: Array, chunk: int = 256) -> Array:
    """Pairwise arm-travel distance between the rows of A (n, dof) and B (m, dof): (n, m)."""
    out = np.empty((len(A), len(B)))
    for s in range(0, len(A), chunk):  # bounded temporaries for long paths
        out[s:s + chunk] = np.abs(A[s:s + chunk, None, :] - B[None, :, :]) @ radii
    return out


def path_travel(radii: Array, P: Array) -> float:
    if len(P) < 2:
        return 0.0
    return float((np.abs(np.diff(P, axis=0)) @ radii).sum())


def retreat_index(executed: Array, blocked: Array) -> int:
    """Index of the last executed posture before the trailing run of `blocked` ones
    (0 if the whole executed path is blocked: go back to where this drive began)."""
    blocked = np.asarray(blocked, dtype=bool)
    tail = len(blocked)
    while tail > 0 and blocked[tail - 1]:
        tail -= 1
    return max(0, tail - 1)


def splice(executed: Array, new_path: Array, radii: Array, tolerance: float = 0.02) -> Splice:
    """Where to rejoin the new plan (module docstring).

    Args:
        executed: joint configurations driven since the old plan started, ending at the stop.
        new_path: the new plan's dense joint path, starting at the stop posture.
        radii: the robot's arm radii (`Robot.arm_radii`), the weights of arm travel.
        tolerance: arm travel (m) within which two postures count as the same.
    """
    E = np.atleast_2d(np.asarray(executed, dtype=float))
    N = np.atleast_2d(np.asarray(new_path, dtype=float))
    radii = np.asarray(radii, dtype=float)
    none = Splice(E[-1:].copy(), N, -1, 0)
    if len(E) < 2 or len(N) < 2:
        return none
    D = arm_travel(radii, N, E)  # (len N, len E)
    near = D <= tolerance
    rows = np.flatnonzero(near.any(axis=1))
    if not len(rows) or rows[-1] == 0:
        return none
    j = int(rows[-1])
    # the common point nearest the stop among the executed postures within tolerance
    i = int(np.flatnonzero(near[j])[-1])
    if i >= len(E) - 1:
        return none
    back = E[i:][::-1].copy()
    cont = np.concatenate([E[i][None], N[j:]]) if D[j, i] > 0.0 else N[j:].copy()
    if path_travel(radii, back) + path_travel(radii, cont) > path_travel(radii, N) + tolerance:
        return none
    return Splice(back, cont, i, j)


def retreat_candidates(executed: Array, i_r: int, radii: Array,
                       distances: tuple[float, ...] = (0.05, 0.15)) -> list[int]:
    """Where to re-plan from after an indication, nearest first: the retreat point `i_r`,
    the executed postures `distances` (m of arm travel) further back, and the drive's
    beginning. Why: right at the edge of a recorded posture box a 7-axis re-plan may find
    no verified way that does not graze it; a little further back there is room."""
    E = np.atleast_2d(np.asarray(executed, dtype=float))
    out = [int(i_r)]
    if i_r <= 0:
        return out
    steps = np.abs(np.diff(E[:i_r + 1], axis=0)) @ np.asarray(radii, dtype=float)
    back = np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])  # travel from j to i_r
    for d in distances:
        far = np.flatnonzero(back >= d)
        if len(far) and int(far[-1]) not in out:
            out.append(int(far[-1]))
    if 0 not in out:
        out.append(0)
    return out


def leads_on(executed: Array, new_path: Array, radii: Array, cos_limit: float = 0.5) -> bool:
    """Whether a re-plan from the stopped posture sets off the way the drive was going (its
    first move within ~60 deg of the drive's last direction, arm-radius weighted): into the
    contact that stopped it. Such a re-plan is refused - it would meet the same obstacle at
    once, and the robot would shuttle on the spot until the indication budget ends."""
    E = np.atleast_2d(np.asarray(executed, dtype=float))
    N = np.atleast_2d(np.asarray(new_path, dtype=float))
    w = np.asarray(radii, dtype=float)
    d = next(((E[-1] - E[k]) * w for k in range(len(E) - 2, -1, -1)
              if np.abs(E[-1] - E[k]).max() > 1e-9), None)
    v = next(((N[k] - N[0]) * w for k in range(1, len(N)) if np.abs(N[k] - N[0]).max() > 1e-9),
             None)
    if d is None or v is None:
        return False
    return float(d @ v) > cos_limit * float(np.linalg.norm(d) * np.linalg.norm(v))
