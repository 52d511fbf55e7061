"""A joint-space RRT-Connect: the transfer's last resort on 6- and 7-axis arms.

Why: the roads live in the TCP's cells. After a collision indication the arm's cells at the
stopped posture are marked occupied (`world.indications`); on a 7-axis arm that is a wall of
some 60 leaves from the shoulder to the hand, and a start or goal tucked next to a fixture
can be cut off from every road although the joint space around the recorded posture is wide
open - the Panda's re-plans failed with "no collision-free connection" and the robot could
only try again from where it stopped. A bidirectional RRT (Kuffner & LaValle 2000) in joint
space needs no cells: it grows a tree from each end with the exact motion check (CAD, joint
limits, recorded collision boxes) and stops when they meet. The path is then shortcut
(`shortcut_joint_path`) and smoothed and verified like a roadmap path.

Deterministic: a seeded generator and budgets in samples and checks (no wall-clock
limit decides the answer), so the same world gives the same path.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from assistant.planning.known_world import KnownVerifier
from assistant.planning.shortcut import shortcut_joint_path
from assistant.progress import Progress
from assistant.roadmap.planner import RoadmapPlan
from assistant.robots.model import Robot
from assistant.world.model import WorldModel

Array = np.ndarray


@dataclass(frozen=True)
class RRTParams:
    """Budgets and step. Defaults are ours: a UR or Panda cell with a recorded box or two
    connects in a few hundred checks."""

    #: Longest tree edge, weighted joint distance (arm radii x radians: ~metres of arm travel).
    step: float = 0.12
    #: Samples drawn before giving up (each grows both trees).
    max_samples: int = 1000
    #: Motion checks before giving up (the cost: each is an exact continuous check, ~5-15
    #: ms on a Panda or UR among boxes: at most ~20 s).
    max_checks: int = 1500
    #: Share of samples that are the other tree's root (goal bias).
    goal_bias: float = 0.1
    seed: int = 0


@dataclass
class RRTResult:
    path: list[Array] | None
    samples: int
    checks: int

    @property
    def found(self) -> bool:
        return self.path is not None


class _Tree:
    def __init__(self, root: Array, capacity: int):
        self.Q = np.empty((capacity, len(root)))
        self.Q[0] = root
        self.parent = np.full(capacity, -1, dtype=np.int64)
        self.n = 1

    def add(self, q: Array, parent: int) -> int:
        if self.n == len(self.Q):
            self.Q = np.concatenate([self.Q, np.empty_like(self.Q)])
            self.parent = np.concatenate([self.parent, np.full(len(self.parent), -1)])
        self.Q[self.n] = q
        self.parent[self.n] = parent
        self.n += 1
        return self.n - 1

    def nearest(self, q: Array, w: Array) -> int:
        d = ((self.Q[:self.n] - q) * w) ** 2
        return int(np.argmin(d.sum(axis=1)))

    def branch(self, i: int) -> list[Array]:
        out = []
        while i >= 0:
            out.append(self.Q[i].copy())
            i = int(self.parent[i])
        return out[::-1]


def rrt_connect(q_start: Array, q_goal: Array, lower: Array, upper: Array,
                motion_free: Callable[[Array, Array], bool], weights: Array,
                params: RRTParams | None = None,
                progress: Callable[[float], None] | None = None) -> RRTResult:
    """Joint path q_start -> q_goal whose every edge passed `motion_free`, or None.

    `weights` (arm radii per joint, 0 for joints that move nothing) scale the distance;
    joints of weight 0 are interpolated but do not count towards the step. `progress` is
    told the share of the check budget used at every sample (it may raise to cancel).
    """
    p = params or RRTParams()
    rng = np.random.default_rng(p.seed)
    q_s = np.asarray(q_start, dtype=float)
    q_g = np.asarray(q_goal, dtype=float)
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    w = np.maximum(np.asarray(weights, dtype=float), 1e-3)
    checks = 0

    def free(a: Array, b: Array) -> bool:
        nonlocal checks
        checks += 1
        return bool(motion_free(a, b))

    if free(q_s, q_g):
        return RRTResult([q_s, q_g], 0, checks)
    trees = (_Tree(q_s, 256), _Tree(q_g, 256))

    def steer(tree: _Tree, target: Array) -> tuple[int, bool]:
        """One step of `tree` towards target: (index of the new or nearest node, reached)."""
        i = tree.nearest(target, w)
        a = tree.Q[i]
        d = float(np.linalg.norm((target - a) * w))
        reached = d <= p.step
        b = target if reached else a + (target - a) * (p.step / d)
        if not free(a, b):
            return -1, False
        return tree.add(b, i), reached

    def connect(tree: _Tree, target: Array) -> int:
        """Step `tree` towards target until it gets there (its index) or is stopped (-1)."""
        while checks < p.max_checks:
            k, reached = steer(tree, target)
            if k < 0:
                return -1
            if reached:
                return k
        return -1

    samples = 0
    while samples < p.max_samples and checks < p.max_checks:
        samples += 1
        if progress is not None:
            progress(checks / p.max_checks)
        a, b = trees if samples % 2 else trees[::-1]
        target = b.Q[0] if rng.random() < p.goal_bias else rng.uniform(lo, hi)
        k, _ = steer(a, target)
        if k < 0:
            continue
        m = connect(b, a.Q[k])
        if m < 0:
            continue
        ta, tb = a.branch(k), b.branch(m)
        path = ta + tb[::-1][1:] if a is trees[0] else tb + ta[::-1][1:]
        short = shortcut_joint_path(path, free)
        return RRTResult(short, samples, checks)
    return RRTResult(None, samples, checks)


def joint_space_plan(robot: Robot, world: WorldModel, verifier: KnownVerifier, q_s: Array,
                     q_g: Array, failed: RoadmapPlan, params: RRTParams,
                     progress: Progress | None = None) -> RoadmapPlan:
    """The roads hold no path on a 6- or 7-axis arm: `rrt_connect` through the known world
    as a roadmap plan ("joint space"), or the roads' own failure with the search's figures.
    Its motion check: the recorded posture boxes exactly first (cheap), then CAD, the boxes
    as the verifier samples them and the recorded hand leaves but those at the query's ends.
    """
    t0 = time.perf_counter()
    exempt = world.recorded_collisions_at(q_s)
    hand_exempt = world.hand_cells_at(np.stack([q_s, q_g]))

    def free(a: Array, b: Array) -> bool:
        return not world.segment_meets_recorded_collision(a, b, exempt) and \
            verifier.check_motion(a, b, exempt, hand_exempt).valid

    tell = None if progress is None else \
        (lambda f: progress.update(f, "searching the joint space"))
    res = rrt_connect(q_s, q_g, robot.limits.lower, robot.limits.upper, free, world.weights,
                      params, tell)
    timings = dict(failed.timings, joint_rrt=time.perf_counter() - t0)
    if res.path is None:
        return replace(failed, reason=f"{failed.reason}; a joint-space search of "
                       f"{res.samples} samples ({res.checks} motion checks) found none "
                       "either", timings=timings)
    cost = float(sum(np.linalg.norm((b - a) * world.weights)
                     for a, b in zip(res.path[:-1], res.path[1:], strict=True)))
    return RoadmapPlan(True, "", None, res.path, cost, searched="joint space",
                       timings=timings)
