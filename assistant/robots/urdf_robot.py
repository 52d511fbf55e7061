"""Any serial robot described by a URDF: kinematics from pinocchio, geometry from the URDF.

What it owns: reading a URDF and its meshes (``package://``, ``file://`` and relative paths),
choosing the base and tool frames, turning the kinematic tree into the `Robot` interface (one
actuated serial chain, everything else locked), FK (single through pinocchio, batched through
`assistant.robots.batch_chain`) and numeric IK (damped least squares on pinocchio's frame Jacobian).
It does not draw, check collisions or plan; it must not import viser.

Why the split: pinocchio parses the kinematics and is the reference every result is tested
against; lxml reads the XML ourselves because the operator needs an error that names the file,
the line and the element, and because collision/visual geometry is needed as trimesh meshes and
primitives, not as pinocchio geometry objects.
"""
from __future__ import annotations

import hashlib
import json
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import trimesh

from assistant.file_guard import FileRefused, read_file
from assistant.robots.batch_chain import BatchChain, ChainJoint
from assistant.robots.errors import RobotModelError
from assistant.robots.model import (
    BatchPoses,
    CollisionShape,
    JointLimits,
    LinkGeometry,
    Robot,
    Tool,
)
from assistant.robots.urdf_ik import DLSInverseKinematics
from assistant.robots.urdf_meshes import collision_shape, visual_mesh
from assistant.robots.urdf_parse import (
    _ACTUATED,
    COLLISION_FACE_LIMIT,
    MAX_URDF_BYTES,
    TCP_FRAME,
    URDFDocument,
    URDFJoint,
    parse_urdf,
    resolve_mesh_path,
)
from assistant.transforms import inv_T

Array = np.ndarray


# ============================================================================ IK settings
@dataclass(frozen=True)
class IKSettings:
    """Damped least squares parameters; the defaults suit arms of 0.3-2 m."""

    #: Iterations per start configuration (most runs converge in 10-60).
    max_iterations: int = 150
    #: Random starts tried after the seed (or the home configuration without a seed).
    restarts: int = 12
    #: More random starts, only when the first ones found nothing (targets that only one
    #: narrow branch reaches inside the limits).
    extra_restarts: int = 36
    #: Stop once this many distinct solutions are found.
    max_solutions: int = 4
    #: lambda of dq = J^T (J J^T + lambda^2 I)^-1 e: bounded steps near singularities. It is
    #: scaled by min(1, |e| / `damping_error`) (Levenberg-Marquardt style), so the last steps
    #: are Gauss-Newton and converge fast even close to a singular configuration.
    damping: float = 1e-2
    damping_error: float = 0.01
    #: Largest joint step per iteration (rad or m): keeps an iteration inside the linear range.
    max_step: float = 0.4
    position_tolerance: float = 1e-6
    orientation_tolerance: float = 1e-5
    #: Solutions closer than this in joint space (rad/m, Euclidean) count as one.
    distinct: float = 1e-3
    #: Seed of the random restarts: the same call always gives the same answer.
    rng_seed: int = 0


# ============================================================================ the robot
class URDFRobot(DLSInverseKinematics, Robot):
    """A serial chain from `base_link` to `tool_link` of a URDF; other joints are locked.

    Link frames are URDF link frames, i.e. each moving link's frame is its joint frame and
    lies on the joint axis. Bodies that do not move relative to a chain link (fixed joints,
    locked joints such as gripper fingers, anything above the base) are merged into it, their
    shapes re-expressed in its frame. Collision meshes above `COLLISION_FACE_LIMIT` faces are
    replaced by their convex hull.

    Build one with `from_file` / `from_string`; the constructor takes an already parsed
    document and is what `with_tool` / `with_limits` use to share it (meshes load once).
    """

    def __init__(self, doc: URDFDocument, *, base_link: str | None = None,
                 tool_link: str | None = None, tool: Tool | None = None,
                 limits: Array | None = None,
                 locked_positions: Mapping[str, float] | None = None,
                 load_visual: bool = True, ik_settings: IKSettings | None = None,
                 program_frame: str | None = None):
        self._doc = doc
        self.name = doc.name
        self.base_link = base_link or doc.root
        self._check_link(self.base_link, "base")
        self.tool_link = tool_link or _default_tool_link(doc, self.base_link)
        self._check_link(self.tool_link, "tool")
        self.tool = tool or Tool()
        self.T_flange_tool = np.asarray(self.tool.T_flange_tool, dtype=float)
        if self.T_flange_tool.shape != (4, 4):
            raise RobotModelError(f"tool {self.tool.name!r}: T_flange_tool must be 4x4")
        self.ik_settings = ik_settings or IKSettings()
        self._load_visual = load_visual

        path = self._path()
        chain = [j for j in path if j.type in _ACTUATED]
        if not chain:
            raise RobotModelError(f"{doc.source}: no actuated joint between base link "
                                  f"{self.base_link!r} and tool link {self.tool_link!r}")
        self._chain_joints = chain
        self.joint_names = [j.name for j in chain]
        self.locked_positions = self._locked(locked_positions, {j.name for j in chain})
        self._build_model()
        self._build_chain()
        lower = np.array([j.lower for j in chain])
        upper = np.array([j.upper for j in chain])
        if limits is not None:
            lower, upper = limits[:, 0].copy(), limits[:, 1].copy()
        self.limits = JointLimits(lower, upper, np.array([j.velocity for j in chain]))
        self.links = self._build_links(path)
        self._local = threading.local()
        self._program_frame = program_frame
        if program_frame is not None and self.fixed_frame(program_frame) is None:
            fixed = [n for n in doc.links if self.fixed_frame(n) is not None]
            raise RobotModelError(f"{doc.source}: the program frame {program_frame!r} is not "
                                  "a link fixed to the robot base (those are: "
                                  f"{', '.join(sorted(fixed))})")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_file(cls, path: Path | str, *, package_dirs: Sequence[str | Path] = (),
                  base_link: str | None = None, tool_link: str | None = None,
                  tool: Tool | None = None, locked_positions: Mapping[str, float] | None = None,
                  load_visual: bool = True, ik_settings: IKSettings | None = None,
                  program_frame: str | None = None) -> URDFRobot:
        """Load a URDF file and its meshes.

        Args:
            path: the .urdf file (xacro must be expanded first).
            package_dirs: folders that contain ROS packages (or are one) for package:// URIs.
            base_link: the robot base frame; default the URDF's root link.
            tool_link: the flange; default the end of the chain with the most actuated joints.
            tool: TCP offset and tool shapes relative to `tool_link`.
            locked_positions: values of joints off the chain (e.g. gripper opening); default
                0 clamped into the joint's range.
            load_visual: False skips visual meshes (batch tools that never draw).
            program_frame: the link programs write poses in (`program_frame`).
        Returns:
            The robot. Raises `RobotModelError` naming the file and element on bad input.
        """
        path = Path(path)
        try:
            text = read_file(path, limit=MAX_URDF_BYTES, what="URDF file").decode("utf-8")
        except (FileRefused, UnicodeDecodeError) as e:
            raise RobotModelError(f"{path}: cannot read the URDF: {e}") from None
        doc = parse_urdf(text, str(path), path.resolve().parent, package_dirs)
        return cls(doc, base_link=base_link, tool_link=tool_link, tool=tool,
                   locked_positions=locked_positions, load_visual=load_visual,
                   ik_settings=ik_settings, program_frame=program_frame)

    @classmethod
    def from_string(cls, xml: str, *, base_dir: Path | str,
                    package_dirs: Sequence[str | Path] = (), base_link: str | None = None,
                    tool_link: str | None = None, tool: Tool | None = None,
                    locked_positions: Mapping[str, float] | None = None,
                    load_visual: bool = True, ik_settings: IKSettings | None = None,
                    source: str = "<URDF string>", program_frame: str | None = None,
                    ) -> URDFRobot:
        """Like `from_file` for URDF text; relative mesh paths are resolved against base_dir."""
        doc = parse_urdf(xml, source, Path(base_dir).resolve(), package_dirs)
        return cls(doc, base_link=base_link, tool_link=tool_link, tool=tool,
                   locked_positions=locked_positions, load_visual=load_visual,
                   ik_settings=ik_settings, program_frame=program_frame)

    def _derive(self, **changes) -> URDFRobot:
        kw = dict(base_link=self.base_link, tool_link=self.tool_link, tool=self.tool,
                  limits=np.column_stack([self.limits.lower, self.limits.upper]),
                  locked_positions=self.locked_positions, load_visual=self._load_visual,
                  ik_settings=self.ik_settings, program_frame=self._program_frame)
        kw.update(changes)
        return URDFRobot(self._doc, **kw)

    def with_tool(self, T_flange_tool: Array | Tool) -> URDFRobot:
        tool = T_flange_tool if isinstance(T_flange_tool, Tool) else Tool(
            "custom", np.asarray(T_flange_tool, dtype=float))
        return self._derive(tool=tool)

    def with_limits(self, limits_rad: Array) -> URDFRobot:
        """The same robot with other position limits, shape (dof, 2) = (lower, upper) in rad/m."""
        lim = np.asarray(limits_rad, dtype=float)
        if lim.shape != (self.dof, 2):
            raise RobotModelError(f"{self._doc.source}: limits for {self.dof} joints "
                                  f"({', '.join(self.joint_names)}) need shape ({self.dof}, 2), "
                                  f"got {lim.shape}")
        bad = [n for n, (lo, hi) in zip(self.joint_names, lim, strict=True)
               if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi)]
        if bad:
            raise RobotModelError(f"{self._doc.source}: limits of joint {bad[0]!r} are not a "
                                  "finite range with lower <= upper")
        return self._derive(limits=lim)

    def with_ik_settings(self, settings: IKSettings) -> URDFRobot:
        return self._derive(ik_settings=settings)

    def _check_link(self, name: str, role: str) -> None:
        if name not in self._doc.links:
            known = ", ".join(list(self._doc.links)[:20])
            raise RobotModelError(f"{self._doc.source}: {role} link {name!r} is not in the URDF "
                                  f"(links: {known}{' ...' if len(self._doc.links) > 20 else ''})")

    def _path(self) -> list[URDFJoint]:
        """Joints from base to tool, in order; refuses a tool that is not below the base."""
        doc, out, link = self._doc, [], self.tool_link
        while link != self.base_link:
            j = doc.parent_joint.get(link)
            if j is None:
                raise RobotModelError(f"{doc.source}: tool link {self.tool_link!r} is not below "
                                      f"base link {self.base_link!r}")
            if j.type in ("floating", "planar"):
                raise RobotModelError(f"{doc.where(j.line)}: joint {j.name!r} of type {j.type} "
                                      "lies between base and tool; only revolute, continuous, "
                                      "prismatic and fixed joints can form the arm")
            out.append(j)
            link = j.parent
        return out[::-1]

    def _locked(self, given: Mapping[str, float] | None, chain: set[str]) -> dict[str, float]:
        doc = self._doc
        out = {}
        for j in doc.joints.values():
            if j.name not in chain and j.type in _ACTUATED:
                out[j.name] = float(np.clip(0.0, j.lower, j.upper))
        for name, v in (given or {}).items():
            if name not in out:
                raise RobotModelError(f"{doc.source}: cannot lock joint {name!r}: it is "
                                      + ("in the arm's chain" if name in chain
                                         else "not a movable joint of the URDF"))
            j = doc.joints[name]
            if not (j.lower - 1e-12 <= float(v) <= j.upper + 1e-12):
                raise RobotModelError(f"{doc.where(j.line)}: locked joint {name!r}: {v} is "
                                      f"outside [{j.lower}, {j.upper}]")
            out[name] = float(v)
        return out

    def _build_model(self) -> None:
        """Reduced pinocchio model: only the chain joints, the rest locked; plus a TCP frame."""
        full = self._doc.model
        q_ref = pin.neutral(full)
        for name, v in self.locked_positions.items():
            _set_pin_q(full, full.getJointId(name), q_ref, v)
        chain_names = set(self.joint_names)
        lock_ids = [i for i in range(1, full.njoints) if full.names[i] not in chain_names]
        model = pin.buildReducedModel(full, lock_ids, q_ref) if lock_ids else pin.Model(full)
        if list(model.names)[1:] != self.joint_names:
            raise RobotModelError(f"{self._doc.source}: pinocchio's joint order "
                                  f"{list(model.names)[1:]} differs from the chain "
                                  f"{self.joint_names}")
        data = model.createData()
        self._q_zero_pin = pin.neutral(model)
        pin.framesForwardKinematics(model, data, self._q_zero_pin)
        base_fid = model.getFrameId(self.base_link, pin.BODY)
        tool_fid = model.getFrameId(self.tool_link, pin.BODY)
        self.T_root_base = data.oMf[base_fid].homogeneous.copy()
        self._T_base_root = inv_T(self.T_root_base)
        self._base_is_root = bool(np.allclose(self.T_root_base, np.eye(4), atol=0, rtol=0))
        dof = len(self.joint_names)
        frame = model.frames[tool_fid]
        if frame.parentJoint != dof:
            raise RobotModelError(f"{self._doc.source}: tool link {self.tool_link!r} does not "
                                  "move with the last joint of the chain")
        self._T_last_flange = frame.placement.homogeneous.copy()
        self._T_last_tcp = self._T_last_flange @ self.T_flange_tool
        self._tcp_fid = model.addFrame(pin.Frame(TCP_FRAME, dof, tool_fid,
                                                 pin.SE3(self._T_last_tcp), pin.FrameType.OP_FRAME))
        self._model = model
        self._idx_q = [model.joints[k].idx_q for k in range(1, dof + 1)]
        self._unbounded = [model.joints[k].nq == 2 for k in range(1, dof + 1)]
        self._simple_q = not any(self._unbounded)
        # World (= URDF root) poses of every body at chain q = 0: placing merged geometry.
        self._T_root_body = {n: data.oMf[model.getFrameId(n, pin.BODY)].homogeneous.copy()
                             for n in self._doc.links}
        self._T_root_joint0 = [np.eye(4)] + [data.oMi[k].homogeneous.copy()
                                             for k in range(1, dof + 1)]

    def _build_chain(self) -> None:
        m = self._model
        joints = []
        for k, j in enumerate(self._chain_joints, start=1):
            T = m.jointPlacements[k].homogeneous.copy()
            if k == 1:
                T = self._T_base_root @ T
            joints.append(ChainJoint(j.name, _ACTUATED[j.type], T, j.axis.copy()))
        self._chain = BatchChain(tuple(joints), self._T_last_tcp.copy())
        # Reach bound: joint 1's origin does not move (revolute) and every later segment
        # has a fixed length, plus prismatic travel. Used to answer REACH honestly.
        self._reach_centre = joints[0].T_prev_joint[:3, 3].copy()
        self._reach = float(sum(np.linalg.norm(j.T_prev_joint[:3, 3]) for j in joints[1:])
                            + np.linalg.norm(self._T_last_tcp[:3, 3])
                            + sum(max(abs(c.lower), abs(c.upper)) for c in self._chain_joints
                                  if c.type == "prismatic"))

    def _build_links(self, path: list[URDFJoint]) -> list[LinkGeometry]:
        """dof + 1 bodies: every URDF link merged into the chain link it is rigidly fixed to."""
        doc = self._doc
        owner_of_path = {self.base_link: 0}
        k = 0
        for j in path:
            k += j.type in _ACTUATED
            owner_of_path[j.child] = k
        chain_link_names = [self.base_link] + [j.child for j in self._chain_joints]
        members: list[list[str]] = [[] for _ in chain_link_names]
        for name in doc.links:
            link = name
            while link not in owner_of_path and link in doc.parent_joint:
                link = doc.parent_joint[link].parent
            members[owner_of_path.get(link, 0)].append(name)
        T_root_owner = [self.T_root_base] + self._T_root_joint0[1:]
        out = []
        for idx, names in enumerate(members):
            T_owner_root = inv_T(T_root_owner[idx])
            shapes: list[CollisionShape] = []
            visuals: list[trimesh.Trimesh] = []
            color = None
            for name in names:
                T_owner_link = T_owner_root @ self._T_root_body[name]
                link = doc.links[name]
                for g in link.collisions:
                    shapes.append(collision_shape(doc, g, link, T_owner_link))
                if self._load_visual:
                    for g in link.visuals:
                        visuals.append(visual_mesh(doc, g, link, T_owner_link))
                        if color is None and g.rgba is not None:
                            color = tuple(int(round(255 * float(np.clip(c, 0, 1))))
                                          for c in g.rgba[:3])
            if idx == len(members) - 1:
                shapes += [s.transformed(self._T_last_flange) for s in self.tool.collision]
                visuals += [s.to_trimesh() for s in (s.transformed(self._T_last_flange)
                                                     for s in self.tool.collision)]
            if self._load_visual and not visuals:
                visuals = [s.to_trimesh() for s in shapes]
            visual = trimesh.util.concatenate(visuals) if visuals else None
            out.append(LinkGeometry(chain_link_names[idx], tuple(shapes), visual,
                                    color or (220, 220, 220)))
        return out

    # ------------------------------------------------------------------ kinematics
    @property
    def pinocchio_model(self) -> pin.Model:
        """A copy of the reduced model (chain joints only) with the TCP frame `TCP_FRAME`.

        Its world frame is the URDF root; `T_root_base` places the base in it.
        """
        return pin.Model(self._model)

    def to_pinocchio_q(self, q: Array) -> Array:
        """Joint angles -> pinocchio's configuration (continuous joints are (cos, sin))."""
        q = np.asarray(q, dtype=float)
        if self._simple_q:
            return q
        out = np.empty(self._model.nq)
        for k, (iq, unb) in enumerate(zip(self._idx_q, self._unbounded, strict=True)):
            if unb:
                out[iq], out[iq + 1] = np.cos(q[k]), np.sin(q[k])
            else:
                out[iq] = q[k]
        return out

    def _data(self) -> pin.Data:
        """Per-thread scratch (pinocchio's Data is mutable; the robot is shared)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = self._model.createData()
        return d

    def _check_q(self, q: Array) -> Array:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.dof,):
            raise ValueError(f"{self.name}: expected {self.dof} joint values "
                             f"({', '.join(self.joint_names)}), got shape {q.shape}")
        return q

    def fk(self, q: Array) -> Array:
        q = self._check_q(q)
        data = self._data()
        pin.forwardKinematics(self._model, data, self.to_pinocchio_q(q))
        T = data.oMi[self.dof].homogeneous @ self._T_last_tcp
        return T if self._base_is_root else self._T_base_root @ T

    def fixed_frame(self, name: str) -> Array | None:
        """A URDF link rigidly attached above the chain (fixed joints only), e.g. the UR
        descriptions' ``base``, in the base frame; None for a missing or moving link."""
        if name not in self._T_root_body or not self._model.existBodyName(name):
            return None
        if self._model.frames[self._model.getFrameId(name, pin.BODY)].parentJoint != 0:
            return None
        return self._T_base_root @ self._T_root_body[name]

    def program_frame(self) -> tuple[Array, str]:
        """The frame programs for this robot write poses in: the link set for it (RobotSpec
        ``program_frame``), else the controller's base of a ROS-Industrial description (a
        fixed leaf link ``base`` under ``base_link``, as the UR descriptions carry it turned
        180 deg about z), else the mounting frame - the model base. A link that merely is
        called "base" (Kinova's mounting block, SO-100's base) is the mounting frame."""
        name, why = self._program_frame, "this robot's program frame setting"
        if name is None and self._ros_industrial_base():
            name, why = "base", "the controller's base frame, ROS-Industrial convention"
        if name is None or name == self.base_link:
            return np.eye(4), f"the robot's mounting frame (URDF link '{self.base_link}')"
        T = self.fixed_frame(name)
        assert T is not None  # checked when the robot was built
        return np.asarray(T, dtype=float), f"URDF link '{name}' ({why})"

    def _ros_industrial_base(self) -> bool:
        doc = self._doc
        joint = doc.parent_joint.get("base")
        return (joint is not None and joint.type == "fixed" and joint.parent == "base_link"
                and not doc.children.get("base") and self.fixed_frame("base") is not None)

    def link_poses(self, q: Array) -> Array:
        q = self._check_q(q)
        data = self._data()
        pin.forwardKinematics(self._model, data, self.to_pinocchio_q(q))
        out = np.empty((self.dof + 1, 4, 4))
        out[0] = np.eye(4)
        for k in range(1, self.dof + 1):
            out[k] = self._T_base_root @ data.oMi[k].homogeneous
        return out

    def batch_fk(self, Q: Array, dtype: type = np.float64) -> BatchPoses:
        """TCP poses of Q (N, dof), vectorised in numpy (see `assistant.robots.batch_chain`)."""
        return self._chain.tip_poses(Q, dtype=dtype)

    def batch_link_poses(self, Q: Array, dtype: type = np.float64) -> Array:
        return self._chain.link_poses(Q, dtype=dtype)

    @property
    def batch_chain(self) -> BatchChain:
        """The chain in base coordinates, TCP as tip (for vectorised users)."""
        return self._chain

    # ------------------------------------------------------------------ description
    def urdf(self) -> str:
        """The URDF with absolute mesh paths, the current limits and a fixed `tool` frame
        (`urdf_export.robot_urdf`)."""
        from assistant.robots.urdf_export import robot_urdf

        return robot_urdf(self._doc, self.joint_names, self.limits, self.T_flange_tool,
                          self.tool_link)

    @property
    def model_limits(self) -> JointLimits:
        """The URDF's own joint ranges, whatever `with_limits` narrowed them to."""
        return JointLimits(np.array([j.lower for j in self._chain_joints]),
                           np.array([j.upper for j in self._chain_joints]),
                           self.limits.velocity)

    def rule_key(self) -> str:
        """`description_hash` over the URDF's own ranges instead of the operator's."""
        lim = self.model_limits
        return self._hash(np.column_stack([lim.lower, lim.upper]))

    def description_hash(self) -> str:
        """sha256 of the URDF text, mesh contents, frames, tool, limits and locked joints."""
        return self._hash(np.column_stack([self.limits.lower, self.limits.upper]))

    def _hash(self, limits: Array) -> str:
        payload = json.dumps({
            "urdf": hashlib.sha256(self._doc.text.encode()).hexdigest(),
            "meshes": self._doc.mesh_digests,
            "base": self.base_link, "tool_link": self.tool_link,
            "T_flange_tool": np.round(self.T_flange_tool, 12).tolist(),
            "tool_shapes": [(s.kind.value, list(s.size), np.round(s.T_link_shape, 12).tolist())
                            for s in self.tool.collision],
            "limits": np.round(limits, 12).tolist(),
            "locked": self.locked_positions,
        }, sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]


def _set_pin_q(model: pin.Model, jid: int, q: Array, value: float) -> None:
    j = model.joints[jid]
    if j.nq == 1:
        q[j.idx_q] = value
    elif j.nq == 2:
        q[j.idx_q], q[j.idx_q + 1] = np.cos(value), np.sin(value)


def _default_tool_link(doc: URDFDocument, base: str) -> str:
    """The end of the longest chain below `base`: most actuated joints, then most joints."""
    best, best_key = base, (-1, -1)
    stack = [(base, 0, 0)]
    order = {n: i for i, n in enumerate(doc.links)}
    leaves = []
    while stack:
        link, act, total = stack.pop()
        kids = doc.children[link]
        if not kids:
            leaves.append((link, act, total))
        for j in kids:
            stack.append((j.child, act + (j.type in _ACTUATED), total + 1))
    for link, act, total in sorted(leaves, key=lambda t: order[t[0]]):
        if (act, total) > best_key:
            best, best_key = link, (act, total)
    return best


__all__ = ["COLLISION_FACE_LIMIT", "IKSettings", "TCP_FRAME", "URDFRobot", "resolve_mesh_path"]
