"""`roboplan` (PyPI, pinocchio + coal) as a planning peer on the same cells as ours.

How its scene is built from what our checker sees, so the two check the same cell:

- robot: `robot.urdf()` - the same URDF with absolute mesh paths, our joint limits and a fixed
  `tool` frame at the TCP - through `roboplan.core.loadUrdfSceneDescriptionFromXml`; its
  collision geometry is the URDF's own collision meshes (coal BVHs; ours replaces meshes above
  `COLLISION_FACE_LIMIT` faces by their convex hull). Joints our robot locks (the Panda's
  fingers) are held at our locked values; the planner's group is our chain's joints only.
- tool: our tool's collision shapes on the flange frame (`robot.tool_link`) at the same poses;
  a capsule becomes a cylinder and two spheres (coal has no capsule in roboplan's wrappers).
- obstacles: each of our `Obstacle` shapes (boxes here: the table, the wall, the boxes) as a
  roboplan box/sphere/cylinder on the root frame at the same pose and size.
- collision pairs as ours: self-collision only between the links our checker checks
  (`CollisionChecker.self_pairs`: not adjacent, not always or never touching), no obstacle
  against the fixed base link or another obstacle.

Its plan is RRT-Connect with its time limit, then its `PathShortcutter`, both checking edges
every `STEP` = 0.01 rad of joint distance (nearer our checker's 5 mm of arm travel than
roboplan's default 0.05 rad, which skips thin stretches: on the first Panda cell 3 of 10
seeds gave a shortcut through the wall's corner over 0.022 rad, a posture roboplan's own
checker calls a collision when asked). Every path it returns is checked again with OUR
checker (`check_path`): a path ours refuses (a scene mismatch, or a stretch between its edge
samples) counts as a failure and is counted apart.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np
from lxml import etree

try:  # an optional peer: the benchmark runs without it
    from roboplan import core as rp_core
    from roboplan import rrt as rp_rrt
except ImportError as e:  # pragma: no cover - depends on the environment
    rp_core = rp_rrt = None
    IMPORT_ERROR: str | None = f"{e}"
else:
    IMPORT_ERROR = None

from planning import Result, dense_tcp_length

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, Robot, ShapeKind

GROUP = "arm"
STEP = 0.01  # rad of joint distance between edge checks (see the module docstring)
GREY = np.array([0.6, 0.6, 0.6, 1.0])


def available() -> bool:
    return rp_core is not None


def version() -> str:
    return str(getattr(rp_core, "__version__", "?")) if rp_core is not None else "not installed"


def default_step() -> float:
    """roboplan's own default edge-check step (rad of joint distance)."""
    return float(rp_rrt.RRTOptions().collision_check_step_size)


@dataclass
class SceneReport:
    """What went into the roboplan scene (for the benchmark's note)."""

    robot_bodies: int
    tool_pieces: int
    obstacle_pieces: int
    self_pairs_enabled: int
    pairs_disabled: int


def _owner_of_links(robot: Robot) -> dict[str, int]:
    """URDF link name -> our link index (0 = base, k = after chain joint k)."""
    import pinocchio as pin

    m = robot.pinocchio_model  # reduced: locked joints merged, so parentJoint is the owner
    return {f.name: int(f.parentJoint) for f in m.frames if f.type == pin.FrameType.BODY}


def _pieces(shape: CollisionShape, T: np.ndarray) -> list[tuple[str, object, np.ndarray]]:
    """roboplan geometry for one of our shapes placed at T (its frame -> shape centre)."""
    T = T @ shape.T_link_shape
    k = shape.kind
    if k == ShapeKind.BOX:
        return [("box", rp_core.Box(*map(float, shape.size)), T)]
    if k == ShapeKind.SPHERE:
        return [("sphere", rp_core.Sphere(float(shape.size[0])), T)]
    if k == ShapeKind.CYLINDER:
        return [("cyl", rp_core.Cylinder(float(shape.size[0]), float(shape.size[1])), T)]
    if k == ShapeKind.CAPSULE:
        r, L = float(shape.size[0]), float(shape.size[1])
        out: list[tuple[str, object, np.ndarray]] = [("cyl", rp_core.Cylinder(r, L), T)]
        for s in (-0.5, 0.5):
            Te = T.copy()
            Te[:3, 3] = T[:3, 3] + s * L * T[:3, 2]
            out.append(("sphere", rp_core.Sphere(r), Te))
        return out
    raise ValueError(f"roboplan peer: shape kind {k} is not translated")


def _add(scene, name: str, frame: str, kind: str, geom, T: np.ndarray) -> None:
    T = np.asfortranarray(T, dtype=float)
    add = {"box": scene.addBoxGeometry, "sphere": scene.addSphereGeometry,
           "cyl": scene.addCylinderGeometry}[kind]
    add(name, frame, geom, T, GREY)


def build_scene(robot: Robot, obstacles: list[Obstacle], checker: CollisionChecker,
                name: str = "cell"):
    """A roboplan Scene of the robot, its tool and the obstacles, pairs as our checker's."""
    urdf = robot.urdf()
    scene = rp_core.Scene(name, rp_core.loadUrdfSceneDescriptionFromXml(urdf, []))
    scene.addGroup(GROUP, list(robot.joint_names))
    owner = _owner_of_links(robot)
    # roboplan 0.7 places an added geometry relative to its parent frame's *joint*, not the
    # frame: attach to frames that coincide with their joint (the last chain joint's own
    # frame, the root "universe") so the placement is right whichever way it is read.
    m = robot.pinocchio_model
    T_joint_flange = m.frames[m.getFrameId(robot.tool_link)].placement.homogeneous
    T_root_base = m.frames[m.getFrameId(robot.base_link)].placement.homogeneous
    last_joint = robot.joint_names[-1]
    # Links with collision geometry (the 0.7 bindings lack getCollisionGeometryIds).
    with_geometry = {el.get("name") for el in etree.fromstring(urdf.encode()).findall("link")
                     if el.find("collision") is not None}
    bodies = {link: k for link, k in owner.items() if link in with_geometry}
    tool_pieces = []
    for i, shape in enumerate(robot.tool.collision):
        for j, (kind, geom, T) in enumerate(_pieces(shape, T_joint_flange)):
            n = f"tool_{i}_{j}"
            _add(scene, n, last_joint, kind, geom, T)
            tool_pieces.append(n)
            bodies[n] = robot.dof
    obstacle_pieces = []
    for ob in obstacles:
        for i, shape in enumerate(ob.collision):
            T_ob = T_root_base @ np.asarray(ob.T_base_object)
            for j, (kind, geom, T) in enumerate(_pieces(shape, T_ob)):
                n = f"obs_{ob.name}_{i}_{j}"
                _add(scene, n, "universe", kind, geom, T)
                obstacle_pieces.append(n)
    names = [lk.name for lk in robot.links]
    checked = {tuple(sorted((names.index(a), names.index(b)))) for a, b in checker.self_pairs}
    off: list[tuple[str, str]] = []
    enabled = 0
    for (a, ka), (b, kb) in itertools.combinations(bodies.items(), 2):
        if tuple(sorted((ka, kb))) in checked:
            enabled += 1
        else:
            off.append((a, b))
    off += list(itertools.combinations(obstacle_pieces, 2))
    off += [(a, o) for a, k in bodies.items() if k == 0 for o in obstacle_pieces]
    if off:
        scene.setCollisions(off, False)
    full = scene.getCurrentJointPositions()
    locked = getattr(robot, "locked_positions", {}) or {}
    all_names = scene.getJointNames()
    for jn, v in locked.items():
        if jn in all_names:
            full[scene.getJointPositionIndices([jn])[0]] = float(v)
    scene.setJointPositions(full)
    return scene, SceneReport(len(bodies) - len(tool_pieces), len(tool_pieces),
                              len(obstacle_pieces), enabled, len(off))


class RoboplanPlanner:
    """roboplan's RRT-Connect + shortcutting on its own scene; judged by our checker."""

    def __init__(self, robot: Robot, obstacles: list[Obstacle], checker: CollisionChecker,
                 time_limit: float, seed: int = 0, step: float = STEP):
        if rp_core is None:
            raise RuntimeError(f"roboplan is not installed ({IMPORT_ERROR})")
        self.robot, self.checker, self.time_limit = robot, checker, time_limit
        self.scene, self.report = build_scene(robot, obstacles, checker)
        self.scene.setRngSeed(seed)
        self.names = list(robot.joint_names)
        opts = rp_rrt.RRTOptions()
        opts.group_name = GROUP
        opts.rrt_connect = True
        opts.max_planning_time = float(time_limit)
        opts.max_nodes = 1_000_000  # the time limit ends the search, as OMPL's does
        opts.collision_check_step_size = step
        self.rrt = rp_rrt.RRT(self.scene, opts)
        self.rrt.setRngSeed(seed)
        sopts = rp_core.PathShortcuttingOptions()
        sopts.group_name = GROUP
        sopts.max_step_size = step
        sopts.seed = seed
        self.shortcutter = rp_core.PathShortcutter(self.scene, sopts)

    def _full(self, q) -> np.ndarray:
        return self.scene.toFullJointPositions(GROUP, np.asarray(q, float))

    def in_collision(self, q) -> bool:
        """roboplan's own answer for a posture of our chain."""
        return bool(self.scene.hasCollisions(self._full(q)))

    def agreement(self, n: int = 300, seed: int = 0) -> float:
        """Share of uniform postures within the limits where its checker and ours agree:
        the evidence that its scene is the cell ours checks."""
        rng = np.random.default_rng(seed)
        lim = self.robot.limits
        Q = rng.uniform(lim.lower, lim.upper, size=(n, self.robot.dof))
        ours = ~np.asarray(self.checker.is_valid_batch(Q), dtype=bool)
        theirs = np.array([self.in_collision(q) for q in Q])
        return float(np.mean(ours == theirs))

    def plan(self, qa, qb) -> Result:
        start = rp_core.JointConfiguration(self.names, np.asarray(qa, float))
        goal = rp_core.JointConfiguration(self.names, np.asarray(qb, float))
        t0 = time.perf_counter()
        try:
            path = self.rrt.plan(start, goal)
        except Exception as e:  # roboplan raises RuntimeError with its reason
            return Result(False, time.perf_counter() - t0,
                          extra={"status": f"roboplan: {e}".splitlines()[0][:120]})
        t_solve = time.perf_counter() - t0
        if path is None or len(path.positions) < 2:
            return Result(False, t_solve, extra={"status": "roboplan: no path"})
        path = self.shortcutter.shortcut(path)
        dt = time.perf_counter() - t0
        Q = np.array([np.asarray(p, float) for p in path.positions])
        if Q.shape[1] != self.robot.dof:  # a full configuration: keep our chain's joints
            idx = self.scene.getJointPositionIndices(self.names)
            Q = Q[:, np.asarray(idx)]
        ends_ok = (np.allclose(Q[0], qa, atol=1e-6) and np.allclose(Q[-1], qb, atol=1e-6))
        bad = self.checker.check_path(list(Q))
        if bad is not None or not ends_ok:
            return Result(False, dt, extra={"status": "refused by our checker" if ends_ok
                                            else "path ends elsewhere",
                                            "refused": True, "solve_s": t_solve})
        return Result(True, dt, dense_tcp_length(self.robot, Q), len(Q) - 1,
                      self.checker.min_clearance_along(list(Q), 0.01), {"solve_s": t_solve})
