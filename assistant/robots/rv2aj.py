"""The built-in Mitsubishi RV-2AJ: 5 revolute axes J1, J2, J3, J5, J6 (there is no J4).

Kinematics from the DH table of the thesis (SPEC §2); joint limits and speeds from the
datasheet, both overridable. The arm is planar after J1: J2, J3 and J5 turn about parallel
axes, so the flange position and the approach vector always lie in the vertical plane through
the J1 axis. That gives a short closed form for FK (written out per element for the batch
version) and for IK, and it is why an arbitrary 6-DoF orientation is generally unreachable.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
from dataclasses import dataclass, field, replace

import numpy as np

from assistant.robots.dh import DHChain, DHRow, batch_chain_frames, chain_frames, flange_frame
from assistant.robots.model import (
    BatchPoses,
    CollisionShape,
    IKFailure,
    IKResult,
    JointLimits,
    LinkGeometry,
    Robot,
    ShapeKind,
    Tool,
)
from assistant.robots.rv2aj_fk_batch import tcp_poses
from assistant.robots.rv2aj_pose_batch import (
    PoseBatchModel,
    PoseCandidates,
    joint_limit_message,
    out_of_reach_message,
    pose_batch_model,
    pose_candidates,
)
from assistant.robots.rv2aj_position_ik import planar_position_ik
from assistant.robots.urdf_writer import urdf_from_chain
from assistant.transforms import angle_between, axis_angle, inv_T, rot_y, rot_z, rotation_angle

Array = np.ndarray

L1 = 0.300  # base to shoulder (J2 axis) height
L2 = 0.250  # upper arm
L3 = 0.160  # forearm
L6 = 0.072  # wrist (J5 axis) to flange

RV2AJ_DH = DHChain(
    (
        DHRow(d=L1, theta_offset=np.pi, a=0.0, alpha=np.pi / 2),
        DHRow(d=0.0, theta_offset=np.pi / 2, a=L2, alpha=0.0),
        DHRow(d=0.0, theta_offset=0.0, a=L3, alpha=0.0),
        DHRow(d=0.0, theta_offset=np.pi / 2, a=0.0, alpha=np.pi / 2),
        DHRow(d=L6, theta_offset=np.pi / 2, a=0.0, alpha=0.0),
    )
)

#: Datasheet ranges (deg) of J1, J2, J3, J5, J6 - configurable per `RV2AJConfig`.
DATASHEET_LIMITS_DEG = ((-150.0, 150.0), (-60.0, 120.0), (-110.0, 120.0), (-90.0, 90.0),
                        (-200.0, 200.0))
#: Datasheet maximum joint speeds (deg/s).
DATASHEET_SPEEDS_DEG_S = (180.0, 90.0, 135.0, 180.0, 210.0)

JOINT_NAMES = ["J1", "J2", "J3", "J5", "J6"]

# Orientation of the flange at q = 0: R(q) = Rz(q1) Ry(q2 + q3 + q5) R0 Rz(q6).
_R0 = flange_frame(RV2AJ_DH, np.zeros(5))[:3, :3]
#: (L1, L2, L3, L6) for the compiled TCP poses and position IK.
_ARM = np.array([L1, L2, L3, L6])
#: `RV2AJ.batch_position_ik`'s search for a workable tool pitch around the pulled one (rad)
PITCH_WINDOW = float(np.radians(40.0))
PITCH_STEP = float(np.radians(1.0))


@dataclass(frozen=True)
class RV2AJConfig:
    """Everything about the RV-2AJ that an integrator may need to change."""

    limits_deg: tuple[tuple[float, float], ...] = DATASHEET_LIMITS_DEG
    speeds_deg_s: tuple[float, ...] = DATASHEET_SPEEDS_DEG_S
    tool: Tool = field(default_factory=Tool)
    #: Tolerance (rad) on the 5-axis constraint: approach vector in the arm plane.
    plane_tolerance: float = 1e-6

    def to_json(self) -> dict:
        return {
            "limits_deg": [list(p) for p in self.limits_deg],
            "speeds_deg_s": list(self.speeds_deg_s),
            "tool": {
                "name": self.tool.name,
                "T_flange_tool": np.asarray(self.tool.T_flange_tool).tolist(),
                "has_gripper": self.tool.has_gripper,
            },
        }


def _link_geometry(tool: Tool) -> list[LinkGeometry]:
    """Collision capsules/boxes sized to the real arm (datasheet outline drawing, rounded up)."""
    cap = CollisionShape.capsule_between
    F = [RV2AJ_DH.fixed_part(i) for i in range(5)]
    base = LinkGeometry(
        "base",
        (CollisionShape(ShapeKind.CYLINDER, (0.095, 0.16), _translate(0, 0, 0.08)),),
        color=(90, 90, 100),
    )
    # Link frames are the base-side joint frames rotated by q_i (see dh.chain_frames).
    link1 = LinkGeometry(
        "J1_turret",
        (cap([0, 0, 0.16], [0, 0, L1], 0.075),),
        color=(235, 235, 235),
    )
    next2 = F[1][:3, 3]  # elbow in link-2 frame
    link2 = LinkGeometry("J2_upper_arm", (cap([0, 0, 0], next2, 0.055),), color=(235, 235, 235))
    next3 = F[2][:3, 3]
    link3 = LinkGeometry("J3_forearm", (cap([0, 0, 0], next3, 0.045),), color=(235, 235, 235))
    link5 = LinkGeometry(
        "J5_wrist", (CollisionShape(ShapeKind.SPHERE, (0.042,), np.eye(4)),), color=(200, 200, 200)
    )
    flange_in_6 = F[4]
    shapes6 = [cap([0, 0, 0.0], flange_in_6[:3, 3], 0.032)]
    shapes6 += [s.transformed(flange_in_6) for s in tool.collision]
    link6 = LinkGeometry("J6_flange", tuple(shapes6), color=(60, 60, 60))
    links = [base, link1, link2, link3, link5, link6]
    return [replace(lk, visual=_visual(lk)) for lk in links]


def _visual(link: LinkGeometry):
    import trimesh

    meshes = [s.to_trimesh() for s in link.collision]
    return trimesh.util.concatenate(meshes) if meshes else None


def _translate(x: float, y: float, z: float) -> Array:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


class RV2AJ(Robot):
    """The Mitsubishi RV-2AJ with a configurable tool, limits and speeds."""

    def __init__(self, config: RV2AJConfig | None = None):
        self.config = config or RV2AJConfig()
        self.name = "Mitsubishi RV-2AJ"
        self.joint_names = list(JOINT_NAMES)
        lim = np.radians(np.array(self.config.limits_deg, dtype=float))
        self.limits = JointLimits(lim[:, 0].copy(), lim[:, 1].copy(),
                                  np.radians(np.array(self.config.speeds_deg_s, dtype=float)))
        self.tool = self.config.tool
        self.T_flange_tool = np.asarray(self.tool.T_flange_tool, dtype=float)
        self._T_tool_flange = inv_T(self.T_flange_tool)
        self.links = _link_geometry(self.tool)
        self.chain = RV2AJ_DH
        self._F5 = RV2AJ_DH.fixed_part(4)

    # ----------------------------------------------------------------- forward kinematics
    def flange(self, q: Array) -> Array:
        return flange_frame(self.chain, np.asarray(q, dtype=float))

    def fk(self, q: Array) -> Array:
        return self.flange(q) @ self.T_flange_tool

    def link_poses(self, q: Array) -> Array:
        return chain_frames(self.chain, np.asarray(q, dtype=float))

    def batch_link_poses(self, Q: Array) -> Array:
        frames, _ = batch_chain_frames(self.chain, np.asarray(Q, dtype=float))
        return frames

    def dh_fixed_stack(self) -> Array:
        """The fixed parts of the DH chain whose frames `batch_link_poses` gives, for
        compiled checks that compute the frames themselves (`dh.chain_row`)."""
        return self.chain.fixed_stack

    def batch_fk(self, Q: Array, dtype: type = np.float64) -> BatchPoses:
        """TCP poses of many configurations (closed form, `rv2aj_fk_batch`); float64 inside,
        returned as `dtype`."""
        pos, rot = tcp_poses(np.ascontiguousarray(Q, dtype=float), *self.tcp_kernel_constants)
        if np.dtype(dtype) != np.float64:
            pos, rot = pos.astype(dtype), rot.astype(dtype)
        return BatchPoses(pos, rot)

    @functools.cached_property
    def tcp_kernel_constants(self) -> tuple[Array, Array, Array, Array, Array, bool]:
        """(arm, BP, BM, BK, v, tool offset?): what the compiled TCP FK (`rv2aj_fk_batch`)
        takes besides the joints; compiled planners call it per row."""
        BP, BM, BK, v = self._batch_consts
        return (_ARM, BP, BM, BK, np.zeros(3) if v is None else v, v is not None)

    @functools.cached_property
    def _tcp_on_flange_axis(self) -> bool:
        """With the TCP on the flange axis (the usual tool) the TCP lies in the arm plane
        too, so the plane through the TCP is fixed and one minimal rotation is exact."""
        return bool(np.allclose(self.T_flange_tool[:2, 3], 0.0))

    @functools.cached_property
    def _limit_bounds(self) -> tuple[list[float], list[float]]:
        """`JointLimits.contains`' bounds (limit -+ its 1e-9 tolerance) as floats: the
        scalar IK tests a handful of branches per call, where numpy's per-call cost would be
        a third of its time."""
        return ((self.limits.lower - 1e-9).tolist(), (self.limits.upper + 1e-9).tolist())

    @functools.cached_property
    def _batch_consts(self) -> tuple[Array, Array, Array, Array | None]:
        R_ft = self.T_flange_tool[:3, :3]
        p_ft = self.T_flange_tool[:3, 3]
        P = np.diag([1.0, 1.0, 0.0]) @ R_ft
        M = np.array([[0, -1.0, 0], [1.0, 0, 0], [0, 0, 0]]) @ R_ft
        K = np.diag([0.0, 0.0, 1.0]) @ R_ft
        # TCP = flange + R_flange p_ft = flange + R (R_ft^T p_ft)
        v = R_ft.T @ p_ft if np.any(p_ft != 0.0) else None
        return (np.ascontiguousarray(_R0 @ P), np.ascontiguousarray(_R0 @ M),
                np.ascontiguousarray(_R0 @ K), v)

    # ----------------------------------------------------------------- inverse kinematics
    def ik(
        self,
        T_base_tool: Array,
        seed: Array | None = None,
        *,
        position_only: bool = False,
    ) -> IKResult:
        T_base_tool = np.asarray(T_base_tool, dtype=float)
        if position_only:
            return self._ik_position_only(T_base_tool[:3, 3], seed)
        T_flange = T_base_tool @ self._T_tool_flange
        nearest = self.nearest_reachable_orientation(T_base_tool)
        if nearest is not None:
            angle = rotation_angle(nearest[:3, :3].T @ T_base_tool[:3, :3])
            return IKResult(
                [],
                IKFailure.ORIENTATION,
                "the RV-2AJ has 5 axes: the tool's approach direction must lie in the vertical "
                "plane through the robot's J1 axis and the target; the nearest reachable "
                f"orientation is {np.degrees(angle):.1f} deg away",
                nearest,
            )
        raw, reach_ok, configs = self._ik_flange_all(T_flange)
        if not reach_ok:
            return IKResult([], IKFailure.REACH, out_of_reach_message(T_base_tool))
        inside = [q for q in raw if self._inside(q)]
        if not inside:
            return IKResult([], IKFailure.JOINT_LIMIT,
                            joint_limit_message(configs, self.limits, self.joint_names))
        inside = _sort_by_seed(inside, seed)
        return IKResult(inside)

    def ik_candidates_batch(self, T_base_tool: Array) -> PoseCandidates | None:
        """Every IK branch of many poses at once (see `rv2aj_pose_batch`); None for a tool
        whose TCP is off the flange axis."""
        model = self._pose_batch_model
        return pose_candidates(T_base_tool, model) if model is not None else None

    @functools.cached_property
    def _pose_batch_model(self) -> PoseBatchModel | None:
        """`ik_candidates_batch`'s constants, laid out once (the limits and tool, like the
        robot's other cached constants, are fixed for its lifetime)."""
        return pose_batch_model(self.T_flange_tool, self._T_tool_flange, self.limits,
                                self.config.plane_tolerance, (L1, L2, L3, L6), _R0)

    def nearest_reachable_orientation(self, T_base_tool: Array) -> Array | None:
        """None if the 5-axis constraint holds; else the closest pose that satisfies it.

        The approach vector is rotated by the smallest angle into the arm plane (about the TCP
        point); with an off-axis tool the plane moves with the flange, so a few fixed-point
        passes settle it.
        """
        T = np.asarray(T_base_tool, dtype=float).copy()
        on_axis = self._tcp_on_flange_axis
        for _ in range(20):
            Tf = T @ self._T_tool_flange
            p = T[:3, 3] if on_axis else Tf[:3, 3]
            a = Tf[:3, 2]
            rxy = np.hypot(p[0], p[1])
            if rxy < 1e-9:
                return None if _ == 0 else T  # on the J1 axis: any approach plane works
            n = np.array([-p[1], p[0], 0.0]) / rxy
            off = float(a @ n)
            if abs(off) <= self.config.plane_tolerance:
                return None if _ == 0 else T
            a_proj = a - off * n
            if np.linalg.norm(a_proj) < 1e-9:  # approach perpendicular to the plane
                a_proj = np.array([0.0, 0.0, -1.0])
            a_proj /= np.linalg.norm(a_proj)
            axis = np.cross(a, a_proj)
            ang = angle_between(a, a_proj)
            R_fix = axis_angle(axis, ang)
            Rf_new = R_fix @ Tf[:3, :3]
            T_new = np.eye(4)
            T_new[:3, :3] = Rf_new @ self.T_flange_tool[:3, :3]
            T_new[:3, 3] = T[:3, 3]  # keep the TCP where the operator asked for it
            T = T_new
        return T

    def _ik_flange_all(self, T_flange: Array) -> tuple[list[Array], bool, list[Array]]:
        """All analytic branches (not yet limit-filtered) for a flange pose in the arm plane,
        whether the wrist is in reach, and each arm configuration (J1 side, then elbow
        +-acos) once, its joints wrapped (`rv2aj_pose_batch` keeps the same order)."""
        p = T_flange[:3, 3]
        R = T_flange[:3, :3]
        a = R[:, 2]
        rxy = np.hypot(p[0], p[1])
        if rxy < 1e-9:
            # On the J1 axis: take J1 from the approach direction (or 0 if vertical).
            base = np.arctan2(a[1], a[0]) if np.hypot(a[0], a[1]) > 1e-9 else 0.0
        else:
            base = np.arctan2(p[1], p[0])
        sols: list[Array] = []
        configs: list[Array] = []
        reach_ok = False
        for q1 in (base, base + np.pi):
            u = np.array([np.cos(q1), np.sin(q1), 0.0])
            s_pitch = np.arctan2(a @ u, a[2])
            w = p - L6 * a
            rw = float(w @ u)
            zw = float(w[2] - L1)
            D = (rw * rw + zw * zw - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
            if D > 1.0 + 1e-12 or D < -1.0 - 1e-12:
                continue
            reach_ok = True
            D = float(np.clip(D, -1.0, 1.0))
            # J6 does not depend on the elbow branch: one rotation per J1 side.
            A = rot_z(q1) @ rot_y(s_pitch) @ _R0
            Mz = A.T @ R
            q6 = np.arctan2(Mz[1, 0], Mz[0, 0])
            # atan2 of sin and cos: the elbow angle without arccos's loss near D = +-1
            elbow = float(np.arctan2(np.sqrt(max(0.0, (1.0 - D) * (1.0 + D))), D))
            for q3 in (elbow, -elbow) if elbow != 0.0 else (elbow,):
                q2 = np.arctan2(rw, zw) - np.arctan2(L3 * np.sin(q3), L2 + L3 * np.cos(q3))
                q5 = s_pitch - q2 - q3
                variants = _angle_variants(np.array([q1, q2, q3, q5, q6]), self._limit_bounds)
                sols += variants
                configs.append(variants[0])
        return sols, reach_ok, configs

    def _inside(self, q: Array) -> bool:
        """`self.limits.contains(q)` (default tolerance) on floats."""
        lo, hi = self._limit_bounds
        return all(a <= v <= b for v, a, b in zip(q.tolist(), lo, hi, strict=True))

    def batch_position_ik(self, targets: Array, seeds: Array, reference: Array | None = None,
                          *, gain: float = 0.5, max_jump: float = 0.25,
                          pitch_window: float = PITCH_WINDOW,
                          pitch_step: float = PITCH_STEP) -> tuple[Array, Array] | None:
        """Position-only IK next to seeds for many TCP points at once, in closed form.

        Why: the elastic net asks this for every moved particle in every iteration. After
        J1 the arm is planar, so with the tool on the flange axis a TCP point and a tool
        pitch s = q2 + q3 + q5 fix the arm: J1 faces the point (the seed's side), the wrist
        sits (L6 + tool) back along the pitch, and J2/J3 solve a two-link triangle on the
        seed's elbow branch. The pitch is the position's free joint (J6 too, it does not
        move an on-axis TCP): both are pulled `gain` of the way from the seed's towards the
        reference's, like the null-space pull of a Newton step. If that pitch leaves the
        limits or cannot reach, pitches up to `pitch_window` away are tried, nearest first,
        up to the first that works (one compiled loop over the rows, `rv2aj_position_ik`).

        Args:
            targets: TCP points (N, 3), base frame.
            seeds: the particles' current joints (N, 5): keeps their J1 side and elbow.
            reference: joints (N, 5) the free joints are pulled towards (None: no pull).
            gain: fraction of the pull (0 keeps the seed's pitch and J6).
            max_jump: a solution farther than this (rad, any joint) from its seed is refused.
            pitch_window, pitch_step: the pitch search around the pulled pitch (rad).

        Returns:
            (joints (N, 5), ok (N,)) with refused rows holding their seeds; None when the
            tool's TCP is off the flange axis (the closed form above does not apply: the
            caller uses a general method).
        """
        p_ft = self.T_flange_tool[:3, 3]
        if abs(p_ft[0]) > 1e-12 or abs(p_ft[1]) > 1e-12:
            return None
        targets = np.atleast_2d(np.asarray(targets, dtype=float))
        seeds = np.atleast_2d(np.asarray(seeds, dtype=float))
        s_seed = seeds[:, 1] + seeds[:, 2] + seeds[:, 3]
        pitch = s_seed.copy()
        q6 = seeds[:, 4].copy()
        if reference is not None and gain > 0.0:
            reference = np.atleast_2d(np.asarray(reference, dtype=float))
            s_ref = reference[:, 1] + reference[:, 2] + reference[:, 3]
            pitch += gain * _wrap(s_ref - s_seed)
            q6 += gain * (reference[:, 4] - q6)
        lim = self.limits
        return planar_position_ik(targets, seeds, pitch, q6, _ARM, float(p_ft[2]),
                                  float(max_jump), lim.lower, lim.upper,
                                  int(np.floor(pitch_window / pitch_step))
                                  if pitch_window > 0.0 else 0, float(pitch_step))

    def net_kernel_robot(self) -> tuple | None:
        """The constants `trajectory.net_kernel.check_moves` needs for the elastic net's
        moves (`batch_position_ik` with its default pitch search, `batch_fk`, the link
        frames of `batch_link_poses`); None when the tool is off the flange axis."""
        p_ft = self.T_flange_tool[:3, 3]
        if abs(p_ft[0]) > 1e-12 or abs(p_ft[1]) > 1e-12:
            return None
        BP, BM, BK, v = self._batch_consts
        lim = self.limits
        return (_ARM, float(p_ft[2]), lim.lower, lim.upper,
                int(np.floor(PITCH_WINDOW / PITCH_STEP)), float(PITCH_STEP), BP, BM, BK,
                np.zeros(3) if v is None else v, v is not None,
                np.ascontiguousarray(self.chain.fixed_stack, dtype=float))

    def _ik_position_only(self, p_target: Array, seed: Array | None) -> IKResult:
        """Any orientation: scan the approach pitch in the arm plane, keep solutions in limits.

        Pitches are tried nearest-first to the seed's (so a jog stays smooth) or to "tool
        pointing down" without a seed; the first few pitches that work are returned.
        """
        if seed is not None:
            seed = np.asarray(seed, dtype=float)
            preferred = float(seed[1] + seed[2] + seed[3])
            q6 = float(seed[4])
        else:
            preferred, q6 = np.pi, 0.0
        offsets = np.radians(np.arange(0.0, 180.1, 2.5))
        pitches = [preferred + sgn * o for o in offsets for sgn in ((1,) if o == 0 else (1, -1))]
        found: list[Array] = []
        any_reach = False
        pitches_ok = 0
        for sp in pitches:
            before = len(found)
            for q1 in (np.arctan2(p_target[1], p_target[0]),
                       np.arctan2(p_target[1], p_target[0]) + np.pi):
                T = np.eye(4)
                T[:3, :3] = rot_z(q1) @ rot_y(sp) @ _R0 @ rot_z(q6)
                T[:3, 3] = p_target - T[:3, :3] @ self.T_flange_tool[:3, 3]
                raw, ok, _ = self._ik_flange_all(T)
                any_reach |= ok
                for q in raw:
                    if (self._inside(q)
                            and np.linalg.norm(self.fk(q)[:3, 3] - p_target) < 1e-7):
                        found.append(q)
            if len(found) > before:
                pitches_ok += 1
                if pitches_ok >= 3:
                    break
        if not found:
            if not any_reach:
                return IKResult([], IKFailure.REACH,
                                f"point at {np.linalg.norm(p_target) * 1000:.0f} mm from the base "
                                "is out of the arm's reach")
            return IKResult([], IKFailure.JOINT_LIMIT,
                            "the point is within reach but only with joints outside their limits")
        return IKResult(_dedupe(_sort_by_seed(found, seed)))

    # ----------------------------------------------------------------- description
    def with_tool(self, T_flange_tool: Array | Tool) -> RV2AJ:
        tool = T_flange_tool if isinstance(T_flange_tool, Tool) else Tool(
            "custom", np.asarray(T_flange_tool, dtype=float))
        return RV2AJ(replace(self.config, tool=tool))

    @functools.cached_property
    def pinocchio_model(self):
        """The same arm as a pinocchio model (built from `urdf()`; frame "tool" is the TCP)."""
        import pinocchio as pin

        return pin.buildModelFromXML(self.urdf())

    def urdf(self) -> str:
        return urdf_from_chain("rv2aj", self.chain, self.joint_names, self.limits, self.links,
                               self.T_flange_tool)

    @property
    def model_limits(self) -> JointLimits:
        """The data sheet's ranges, widened to any an integrator configured beyond them."""
        sheet = np.radians(np.array(DATASHEET_LIMITS_DEG))
        return JointLimits(np.minimum(sheet[:, 0], self.limits.lower),
                           np.maximum(sheet[:, 1], self.limits.upper), self.limits.velocity)

    def rule_key(self) -> str:
        lim = self.model_limits
        payload = json.dumps({"robot": "rv2aj", "dh": [list(vars(r).values()) for r in
                                                       self.chain.rows],
                              **self.config.to_json(),
                              "limits_deg": np.degrees(np.column_stack(
                                  [lim.lower, lim.upper])).round(9).tolist(),
                              "tool_shapes": [(s.kind.value, list(s.size),
                                               np.round(s.T_link_shape, 12).tolist())
                                              for s in self.config.tool.collision]},
                             sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def description_hash(self) -> str:
        payload = json.dumps({"robot": "rv2aj", "dh": [list(vars(r).values()) for r in
                                                       self.chain.rows],
                              **self.config.to_json()}, sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]


def _angle_variants(q: Array, bounds: tuple[list[float], list[float]]) -> list[Array]:
    """Each joint wrapped into (-pi, pi] plus the +-2pi copies its range allows (J6 is +-200).

    If a joint has no copy inside its range the wrapped value is kept, so the caller can say
    which limit failed. `bounds`: each joint's limits widened by 1e-9 (`RV2AJ._limit_bounds`).
    """
    q = (q + np.pi) % (2 * np.pi) - np.pi
    lo, hi = bounds
    per_joint = []
    for v, a, b in zip(q.tolist(), lo, hi, strict=True):
        c = [v + k for k in (0.0, -2 * np.pi, 2 * np.pi) if a <= v + k <= b]
        per_joint.append(c or [v])
    if all(len(c) == 1 for c in per_joint):  # the usual case: one copy of every joint
        return [np.array([c[0] for c in per_joint])]
    return [np.array(c) for c in itertools.product(*per_joint)]


def _sort_by_seed(sols: list[Array], seed: Array | None) -> list[Array]:
    if seed is None:
        return sorted(sols, key=lambda q: float(np.abs(q).sum()))
    seed = np.asarray(seed, dtype=float)
    return sorted(sols, key=lambda q: float(np.linalg.norm(q - seed)))


def _dedupe(sols: list[Array]) -> list[Array]:
    out: list[Array] = []
    for q in sols:
        if all(np.linalg.norm(q - o) > 1e-6 for o in out):
            out.append(q)
    return out


def _wrap(a: Array) -> Array:
    """Angles into [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi
