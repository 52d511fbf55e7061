"""A UR arm's kinematics as its controller knows them: the nominal DH tables, the calibrated
table a controller publishes (primary interface, kinematics info), and how far apart they are.

Every UR is calibrated at the factory; the controller computes its TCP (RTDE
``actual_TCP_pose``) and solves ``movel`` targets with the calibrated table, which moves the
TCP by millimetres against the nominal model a planner uses. The link therefore checks the
reported TCP against the *calibrated* chain and reports the deviation from nominal.

Frames: standard DH, ``T = prod Rz(q_i + theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``, from the
controller's base frame to its tool flange (the ROS-Industrial ``base`` and ``tool0`` links;
UR's published DH tables, "DH parameters for calculations of kinematics and dynamics").
`chain_urdf` writes a table as a URDF chain so the emulator and the link can use the
project's `URDFRobot` (FK, IK) on a calibrated arm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from assistant.links.ur_primary import KinematicsInfo
from assistant.robots.model import Robot
from assistant.transforms import inv_T

Array = np.ndarray
_PI2 = math.pi / 2
#: UR's nominal DH tables (d, a, alpha per joint; theta offsets 0), metres and radians.
NOMINAL: dict[str, tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]] = {
    "UR3": ((0.1519, 0, 0, 0.11235, 0.08535, 0.0819), (0, -0.24365, -0.21325, 0, 0, 0),
            (_PI2, 0, 0, _PI2, -_PI2, 0)),
    "UR5": ((0.089159, 0, 0, 0.10915, 0.09465, 0.0823), (0, -0.425, -0.39225, 0, 0, 0),
            (_PI2, 0, 0, _PI2, -_PI2, 0)),
    "UR10": ((0.1273, 0, 0, 0.163941, 0.1157, 0.0922), (0, -0.612, -0.5723, 0, 0, 0),
             (_PI2, 0, 0, _PI2, -_PI2, 0)),
    "UR3e": ((0.15185, 0, 0, 0.13105, 0.08535, 0.0921), (0, -0.24355, -0.2132, 0, 0, 0),
             (_PI2, 0, 0, _PI2, -_PI2, 0)),
    "UR5e": ((0.1625, 0, 0, 0.1333, 0.0997, 0.0996), (0, -0.425, -0.3922, 0, 0, 0),
             (_PI2, 0, 0, _PI2, -_PI2, 0)),
    "UR10e": ((0.1807, 0, 0, 0.17415, 0.11985, 0.11655), (0, -0.6127, -0.57155, 0, 0, 0),
              (_PI2, 0, 0, _PI2, -_PI2, 0)),
    "UR16e": ((0.1807, 0, 0, 0.17415, 0.11985, 0.11655), (0, -0.4784, -0.36, 0, 0, 0),
              (_PI2, 0, 0, _PI2, -_PI2, 0)),
}
FLANGE_TOL_M = 1e-4  # the model's flange must be the controller's within this


def nominal_info(model: str) -> KinematicsInfo:
    d, a, alpha = NOMINAL[model]
    return KinematicsInfo((0,) * 6, (0.0,) * 6, tuple(map(float, a)), tuple(map(float, d)),
                          tuple(map(float, alpha)), 0)


def factory_calibration(model: str) -> KinematicsInfo:
    """A plausible factory calibration of `model`: sub-millimetre to 2 mm link deltas and
    milliradian joint offsets (the emulator's; a real table comes from the controller)."""
    n = nominal_info(model)
    dt = (0.0021, -0.0018, 0.0025, -0.0012, 0.0009, 0.0015)
    da = (0.0004, -0.0021, 0.0017, 0.0, 0.0, 0.0)
    dd = (0.0012, 0.0008, -0.0015, 0.0009, -0.0004, 0.0003)
    dal = (0.0006, -0.0004, 0.0003, 0.0005, -0.0007, 0.0)
    add = lambda x, y: tuple(float(u + v) for u, v in zip(x, y, strict=True))  # noqa: E731
    return KinematicsInfo((0x5EED, 0x5EED + 1, 0x5EED + 2, 0x5EED + 3, 0x5EED + 4, 0x5EED + 5),
                          add(n.theta, dt), add(n.a, da), add(n.d, dd), add(n.alpha, dal), 1)


def dh_fk(k: KinematicsInfo, q: Array) -> Array:
    """Controller base -> tool flange for joints `q` under the table `k`."""
    T = np.eye(4)
    for i in range(6):
        ct, st = math.cos(q[i] + k.theta[i]), math.sin(q[i] + k.theta[i])
        ca, sa = math.cos(k.alpha[i]), math.sin(k.alpha[i])
        T = T @ np.array([[ct, -st * ca, st * sa, k.a[i] * ct],
                          [st, ct * ca, -ct * sa, k.a[i] * st],
                          [0.0, sa, ca, k.d[i]], [0.0, 0.0, 0.0, 1.0]])
    return T


def _rpy(R: Array) -> tuple[float, float, float]:
    """URDF rpy (R = Rz(y) Ry(p) Rx(r)) of a rotation matrix."""
    p = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    return math.atan2(R[2, 1], R[2, 2]), p, math.atan2(R[1, 0], R[0, 0])


def chain_urdf(k: KinematicsInfo, robot: Robot, name: str = "ur_calibrated") -> str:
    """The table as a URDF chain ``base`` -> ``tool0`` with `robot`'s joint limits and speeds.

    Joint i turns about z of its link; the fixed part of DH row i,
    ``Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``, is the origin of joint i+1 (of the flange
    after joint 6).
    """
    def fixed(i: int) -> Array:
        c, s = math.cos(k.theta[i]), math.sin(k.theta[i])
        ca, sa = math.cos(k.alpha[i]), math.sin(k.alpha[i])
        return np.array([[c, -s * ca, s * sa, k.a[i] * c], [s, c * ca, -c * sa, k.a[i] * s],
                         [0.0, sa, ca, k.d[i]], [0.0, 0.0, 0.0, 1.0]])

    def origin(T: Array) -> str:
        r, p, y = _rpy(T[:3, :3])
        x, yy, z = T[:3, 3]
        return f'<origin xyz="{x:.9f} {yy:.9f} {z:.9f}" rpy="{r:.12f} {p:.12f} {y:.12f}"/>'

    lim = robot.limits
    links = ["base"] + [f"link{i}" for i in range(1, 7)] + ["tool0"]
    out = [f'<robot name="{name}">'] + [f'  <link name="{n}"/>' for n in links]
    for i in range(6):
        T = np.eye(4) if i == 0 else fixed(i - 1)
        out.append(f'  <joint name="{robot.joint_names[i]}" type="revolute">'
                   f'<parent link="{links[i]}"/><child link="{links[i + 1]}"/>{origin(T)}'
                   f'<axis xyz="0 0 1"/><limit lower="{lim.lower[i]:.9f}" '
                   f'upper="{lim.upper[i]:.9f}" velocity="{lim.velocity[i]:.6f}" '
                   f'effort="100"/></joint>')
    out.append(f'  <joint name="flange" type="fixed"><parent link="link6"/>'
               f'<child link="tool0"/>{origin(fixed(5))}</joint>')
    out.append("</robot>")
    return "\n".join(out)


def calibrated_robot(k: KinematicsInfo, robot: Robot) -> Robot:
    """A `URDFRobot` of the calibrated chain, base = controller base, flange = tool0."""
    from assistant.robots.urdf_robot import URDFRobot

    return URDFRobot.from_string(chain_urdf(k, robot), base_dir=".", base_link="base",
                                tool_link="tool0", load_visual=False)


def _postures(robot: Robot, n: int, seed: int = 7) -> Array:
    rng = np.random.default_rng(seed)
    lo = np.maximum(robot.limits.lower, -np.pi)
    hi = np.minimum(robot.limits.upper, np.pi)
    return lo + rng.random((n, robot.dof)) * (hi - lo)


def model_flange_in_controller(robot: Robot, q: Array) -> Array:
    """Our model's flange (its tool link, no tool) in the controller's base frame."""
    from assistant.links.ur_script import controller_base

    return inv_T(controller_base(robot)) @ robot.with_tool(np.eye(4)).fk(q)


def identify(robot: Robot) -> tuple[str | None, float, float]:
    """The UR type whose nominal table our model's flange follows (position within 0.1 mm at
    a few postures), the worst position difference to it (m) and the angle between our
    flange and the controller's tool flange (rad; not 0 when the model's tool link is e.g.
    ROS-Industrial's ``ee_link`` instead of ``tool0``)."""
    Q = _postures(robot, 6, seed=3)
    best, best_err, best_ang = None, math.inf, math.pi
    for model in NOMINAL:
        k = nominal_info(model)
        err, ang = 0.0, 0.0
        for q in Q:
            M, D = model_flange_in_controller(robot, q), dh_fk(k, q)
            err = max(err, float(np.linalg.norm(M[:3, 3] - D[:3, 3])))
            R = M[:3, :3].T @ D[:3, :3]
            ang = max(ang, math.atan2(float(np.linalg.norm(R - R.T)) / math.sqrt(2.0),
                                      float(np.trace(R)) - 1.0))
        if err < best_err:
            best, best_err, best_ang = model, err, ang
    return (best if best_err <= FLANGE_TOL_M else None), best_err, best_ang


@dataclass(frozen=True)
class CalibrationReport:
    model: str | None
    #: Largest TCP (flange) distance nominal vs calibrated over sampled postures (m).
    max_deviation_m: float
    #: The same at the arm's current posture (m).
    here_m: float
    calibration_status: int


def compare(k: KinematicsInfo, robot: Robot, q_now: Array, n: int = 200) -> CalibrationReport:
    model, _, _ = identify(robot)
    ref = nominal_info(model) if model else None

    def dev(q: Array) -> float:
        if ref is None:
            return float(np.linalg.norm(model_flange_in_controller(robot, q)[:3, 3]
                                        - dh_fk(k, q)[:3, 3]))
        return float(np.linalg.norm(dh_fk(ref, q)[:3, 3] - dh_fk(k, q)[:3, 3]))

    worst = max(dev(q) for q in _postures(robot, n))
    return CalibrationReport(model, worst, dev(np.asarray(q_now, float)), k.calibration_status)
