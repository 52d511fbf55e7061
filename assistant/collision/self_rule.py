"""One self-collision rule per robot: which link pairs are checked, and why the others are not.

Teach, plan, jog, execute and the world model all ask `self_collision_rule(robot)` and get
the same answer, so a posture one of them accepts the others accept too. The rule is the
set-up assistant's (MoveIt's SRDF generator's) idea, decided once per robot model:

- **adjacent**: links joined by a joint are never checked (their housings meet by design);
- **always**: pairs touching in every one of `SAMPLES` random postures are built
  overlapping (e.g. a motor housing inside the next link's mesh) and are not checked;
- **never**: pairs that never come within `NEAR` of each other in those postures are not
  checked (a margin instead of a bare miss);
- every other pair is checked, exactly (FCL) by `CollisionChecker`.

The postures are drawn over the model's own joint ranges (the URDF's, the data sheet's),
not over limits the operator narrowed: narrowing the limits never changes which pairs are
checked. The rule is computed once per robot model (shapes, tool, model ranges) and kept
in memory and on disk (`$CELLTEACH_CACHE/self_collision`, default ``~/.cache/cellteach``):
a mesh arm takes seconds to sample, and the same seed gives the same rule every time.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import threading
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import fcl
import numpy as np

from assistant.collision.fcl_shapes import covering_spheres, fcl_geometry, fcl_transform
from assistant.robots.model import Robot

Array = np.ndarray

#: Bump when the rule's computation changes: cached rules of other versions are ignored.
RULE_VERSION = 1
#: Random postures sampled per robot model, and their seed (fixed: the rule is reproducible).
SAMPLES = 1500
SEED = 12345
#: A pair that never comes nearer than this (m) in the samples is not checked.
NEAR = 0.03

_MEMORY: dict[str, SelfCollisionRule] = {}
_LOCK = threading.Lock()


class PairReason(str, Enum):
    CHECKED = "checked"
    ADJACENT = "adjacent"
    ALWAYS = "always"
    NEVER = "never"


@dataclass(frozen=True)
class LinkPair:
    """Two links (indices into `robot.links`, a < b) and what the rule does with them."""

    a: int
    b: int
    reason: PairReason


@dataclass(frozen=True)
class SelfCollisionRule:
    """The pairs of one robot model: per link pair the decision, per checked link pair the
    shape pairs (link a, shape number in a, link b, shape number in b) FCL tests."""

    key: str
    link_names: tuple[str, ...]
    pairs: tuple[LinkPair, ...]
    shape_pairs: tuple[tuple[int, int, int, int], ...]
    samples: int = SAMPLES
    near: float = NEAR

    def reason(self, a: int, b: int) -> PairReason | None:
        a, b = sorted((a, b))
        return next((p.reason for p in self.pairs if p.a == a and p.b == b), None)

    def checked(self) -> list[tuple[int, int]]:
        return [(p.a, p.b) for p in self.pairs if p.reason == PairReason.CHECKED]

    def lines(self, words: list[str] | None = None) -> list[str]:
        """The rule in the operator's words, one line per kind of decision."""
        w = words or list(self.link_names)

        def names(reason: PairReason) -> str:
            got = [f"{w[p.a]} - {w[p.b]}" for p in self.pairs if p.reason == reason]
            return "; ".join(got) if got else "none"

        n_checked = sum(p.reason == PairReason.CHECKED for p in self.pairs)
        return [f"Checked against each other ({n_checked} pairs): {names(PairReason.CHECKED)}",
                f"Not checked, joined by a joint: {names(PairReason.ADJACENT)}",
                f"Not checked, touching in all {self.samples} random postures (built "
                f"overlapping): {names(PairReason.ALWAYS)}",
                f"Not checked, never within {self.near * 1000:.0f} mm in {self.samples} random "
                f"postures: {names(PairReason.NEVER)}"]

    def to_json(self) -> dict:
        return {"version": RULE_VERSION, "key": self.key, "link_names": list(self.link_names),
                "pairs": [[p.a, p.b, p.reason.value] for p in self.pairs],
                "shape_pairs": [list(s) for s in self.shape_pairs],
                "samples": self.samples, "near": self.near}

    @staticmethod
    def from_json(d: dict) -> SelfCollisionRule:
        return SelfCollisionRule(
            str(d["key"]), tuple(str(n) for n in d["link_names"]),
            tuple(LinkPair(int(a), int(b), PairReason(r)) for a, b, r in d["pairs"]),
            tuple(tuple(int(v) for v in s) for s in d["shape_pairs"]),  # type: ignore[misc]
            int(d["samples"]), float(d["near"]))


def link_words(robot: Robot) -> list[str]:
    """Each link as the operator knows it: "the base (world)", "the J4 link (link04)"; the
    last link carries the tool when the tool has a body."""
    out = []
    n = len(robot.links)
    tool_body = bool(getattr(getattr(robot, "tool", None), "collision", ()))
    for i, link in enumerate(robot.links):
        if i == 0:
            out.append(f"the base ({link.name})")
            continue
        joint = robot.joint_names[i - 1] if i - 1 < len(robot.joint_names) else ""
        axis = joint if re.fullmatch(r"[JA]\d+", joint) else f"J{i}"
        extra = " and tool" if i == n - 1 and tool_body else ""
        out.append(f"the {axis} link{extra} ({link.name})")
    return out


def rule_robot(robot: Robot) -> Robot:
    """The robot a rule belongs to: a checker's view of some links (`world.chain_levels`)
    uses its whole robot's rule."""
    source = getattr(robot, "rule_robot", None)
    return source() if callable(source) else robot


def self_collision_rule(robot: Robot, *, cache_dir: Path | None = None,
                        compute: bool = True) -> SelfCollisionRule | None:
    """The robot model's rule: from memory, from the disk cache, else computed (and kept).
    With `compute=False` only a rule already known is returned (None otherwise): for a page
    that must not wait seconds."""
    robot = rule_robot(robot)
    key = robot.rule_key()
    with _LOCK:
        if key in _MEMORY:
            return _MEMORY[key]
    path = _cache_file(key, cache_dir)
    rule = _read(path, key) if path is not None else None
    if rule is None:
        if not compute:
            return None
        rule = compute_rule(robot)
        if path is not None:
            _write(path, rule)
    with _LOCK:
        _MEMORY[key] = rule
    return rule


def compute_rule(robot: Robot, n: int = SAMPLES, near: float = NEAR,
                 seed: int = SEED) -> SelfCollisionRule:
    """Sample `n` postures over the model's ranges and decide every link pair (module doc).

    Each shape's covering spheres give a lower bound on its distance to another shape; only
    the (posture, pair) cases whose bound is below `near` go to FCL, which then answers
    exactly as if every case were asked (a bound >= `near` can neither touch nor come near).
    """
    shapes = [(li, k, s) for li, link in enumerate(robot.links)
              for k, s in enumerate(link.collision)]
    adjacent = {tuple(sorted(p)) for p in robot.adjacent_link_pairs()}
    link_has = sorted({li for li, _, _ in shapes})
    candidates = [(i, j) for i in range(len(shapes)) for j in range(i + 1, len(shapes))
                  if shapes[i][0] != shapes[j][0]
                  and tuple(sorted((shapes[i][0], shapes[j][0]))) not in adjacent]
    hits = np.zeros(len(candidates), dtype=np.int64)
    closest = np.full(len(candidates), np.inf)
    if candidates:
        lim = robot.model_limits
        rng = np.random.default_rng(seed)
        Q = rng.uniform(lim.lower, lim.upper, size=(n, robot.dof))
        frames = robot.batch_link_poses(Q)
        spheres = [covering_spheres(s) for _, _, s in shapes]
        objs = [fcl.CollisionObject(fcl_geometry(s)) for _, _, s in shapes]
        req, dreq = fcl.CollisionRequest(), fcl.DistanceRequest()
        for ci, (i, j) in enumerate(candidates):
            gap = _sphere_gap(frames, shapes[i][0], spheres[i], shapes[j][0], spheres[j])
            for k in np.flatnonzero(gap < near).tolist():
                a, b = objs[i], objs[j]
                a.setTransform(fcl_transform(frames[k, shapes[i][0]] @ shapes[i][2].T_link_shape))
                b.setTransform(fcl_transform(frames[k, shapes[j][0]] @ shapes[j][2].T_link_shape))
                if fcl.collide(a, b, req, fcl.CollisionResult()):
                    hits[ci] += 1
                    closest[ci] = 0.0
                elif closest[ci] >= near:
                    closest[ci] = min(closest[ci], fcl.distance(a, b, dreq, fcl.DistanceResult()))
    shape_pairs = []
    shape_reason: dict[tuple[int, int], list[PairReason]] = {}
    for (i, j), h, d in zip(candidates, hits, closest, strict=True):
        la, lb = shapes[i][0], shapes[j][0]
        reason = (PairReason.ALWAYS if h == n else PairReason.NEVER if d >= near
                  else PairReason.CHECKED)
        shape_reason.setdefault((la, lb), []).append(reason)
        if reason == PairReason.CHECKED:
            shape_pairs.append((la, shapes[i][1], lb, shapes[j][1]))
    pairs = []
    for x, a in enumerate(link_has):
        for b in link_has[x + 1:]:
            if (a, b) in adjacent:
                pairs.append(LinkPair(a, b, PairReason.ADJACENT))
                continue
            got = shape_reason.get((a, b), [])
            reason = (PairReason.CHECKED if PairReason.CHECKED in got else
                      PairReason.ALWAYS if PairReason.ALWAYS in got else PairReason.NEVER)
            pairs.append(LinkPair(a, b, reason))
    return SelfCollisionRule(robot.rule_key(), tuple(lk.name for lk in robot.links),
                             tuple(pairs), tuple(shape_pairs), n, near)


def _sphere_gap(frames: Array, la: int, sa: tuple[Array, Array], lb: int,
                sb: tuple[Array, Array]) -> Array:
    """Per posture, a lower bound (m) on the distance between two shapes: the smallest gap
    between their covering spheres (negative when the spheres overlap)."""
    ca = np.einsum("nij,mj->nmi", frames[:, la, :3, :3], sa[0]) + frames[:, la, None, :3, 3]
    cb = np.einsum("nij,mj->nmi", frames[:, lb, :3, :3], sb[0]) + frames[:, lb, None, :3, 3]
    d = np.linalg.norm(ca[:, :, None, :] - cb[:, None, :, :], axis=-1)
    return np.min(d - sa[1][None, :, None] - sb[1][None, None, :], axis=(1, 2))


# ------------------------------------------------------------------------------ disk cache
def _cache_file(key: str, cache_dir: Path | None) -> Path | None:
    if cache_dir is None:
        env = os.environ.get("CELLTEACH_CACHE")
        cache_dir = (Path(env) if env else Path.home() / ".cache" / "cellteach")
        cache_dir = cache_dir / "self_collision"
    digest = hashlib.sha256(f"{RULE_VERSION}:{key}".encode()).hexdigest()[:24]
    return Path(cache_dir) / f"rule-{digest}.json"


def _read(path: Path, key: str) -> SelfCollisionRule | None:
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
        if d.get("version") != RULE_VERSION or d.get("key") != key:
            return None
        return SelfCollisionRule.from_json(d)
    except (OSError, ValueError, KeyError, TypeError):
        return None  # missing or damaged: computed again


def _write(path: Path, rule: SelfCollisionRule) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
        tmp.write_text(json.dumps(rule.to_json()), encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        pass  # no writable cache: the rule is computed again next run
