"""The URScript the UR link sends: motion programs with progress registers, uploads, stops.

Every motion is one program ``def ct_<n>(): ... end`` sent over the secondary interface; a
new program replaces a running one, so ``stopj(a)`` alone is the stop. The program reports
through RTDE output integer registers (24-47 are free for users; 0-23 belong to fieldbus
adapters): register 24 = its number when it starts, 26 = the index of the target it is
moving to, 25 = its number when it has finished. The link thus knows which program runs,
where in the path it is and that it ended normally - RTDE's `runtime_state` alone cannot tell
"finished" from "stopped".

Joint paths become exact-stop ``movej`` through the decimated vertices (`decimate.py`):
``movej`` interpolates in joint space, so the collision-checked path is reproduced within
`decimation_tol_m` on the arm; blending (``r``) would cut corners by an amount the planner did
not check. Poses are ``p[x, y, z, rx, ry, rz]`` in the controller's base frame (the URDF's
fixed ``base`` link when the model has it, see `assistant.export.urscript`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from assistant.robots.model import Robot
from assistant.transforms import inv_T, rotation_vector

Array = np.ndarray

REG_STARTED, REG_DONE, REG_TARGET = 24, 25, 26
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,30}$")


_BASES: dict[int, Array] = {}


def controller_base(robot: Robot) -> Array:
    """Pose of the controller's base frame in the model base: the robot's program frame
    (`Robot.program_frame`, the one URScript programs are written in)."""
    key = id(robot)
    if key not in _BASES:  # robots are immutable; the emulator asks at 500 Hz
        _BASES[key] = np.asarray(robot.program_frame()[0], dtype=float)
    return _BASES[key]


def rotvec(R: Array) -> Array:
    """Rotation vector of R via its quaternion (Shepperd: stable up to and at pi).

    `transforms.rotation_vector` (scipy) costs ~0.3-1 ms a call; the emulator needs one per
    RTDE package at 500 Hz.
    """
    t = R[0, 0] + R[1, 1] + R[2, 2]
    k = int(np.argmax([t, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        w = 0.5 * np.sqrt(1.0 + t)
        v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (4.0 * w)
    else:
        i = k - 1
        j, m = (i + 1) % 3, (i + 2) % 3
        v = np.empty(3)
        v[i] = 0.5 * np.sqrt(max(1.0 + R[i, i] - R[j, j] - R[m, m], 0.0))
        w = (R[m, j] - R[j, m]) / (4.0 * v[i])
        v[j] = (R[j, i] + R[i, j]) / (4.0 * v[i])
        v[m] = (R[m, i] + R[i, m]) / (4.0 * v[i])
    if w < 0.0:
        w, v = -w, -v
    s = float(np.linalg.norm(v))
    if s < 1e-15:
        return np.zeros(3)
    return v * (2.0 * np.arctan2(s, w) / s)


def to_controller_pose(robot: Robot, T_model: Array) -> list[float]:
    """A model-base pose as URScript's [x, y, z, rx, ry, rz] in the controller base."""
    T = inv_T(controller_base(robot)) @ np.asarray(T_model, dtype=float)
    return [float(v) for v in T[:3, 3]] + [float(v) for v in rotvec(T[:3, :3])]


def from_controller_pose(robot: Robot, pose: Sequence[float]) -> Array:
    from scipy.spatial.transform import Rotation

    v = np.asarray(pose, dtype=float)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(v[3:6]).as_matrix()
    T[:3, 3] = v[:3]
    return controller_base(robot) @ T


def joints_literal(q: Array) -> str:
    return "[" + ", ".join(f"{float(v):.7f}" for v in q) + "]"


def pose_literal(pose: Sequence[float]) -> str:
    return "p[" + ", ".join(f"{float(v):.7f}" for v in pose) + "]"


def tcp_line(robot: Robot) -> str:
    """``set_tcp`` of the model's tool (flange frame), so RTDE's TCP pose is the model's."""
    T = np.asarray(robot.T_flange_tool, dtype=float)
    pose = [float(v) for v in T[:3, 3]] + [float(v) for v in rotation_vector(T[:3, :3])]
    return f"set_tcp({pose_literal(pose)})"


def joint_program(name: str, number: int, robot: Robot, targets: Array, speed_rad_s: float,
                  accel_rad_s2: float) -> str:
    """A program that moves through `targets` by exact-stop movej, reporting progress."""
    lines = [f"def {name}():", f"  write_output_integer_register({REG_STARTED}, {number})",
             f"  {tcp_line(robot)}"]
    for k, q in enumerate(targets):
        lines.append(f"  write_output_integer_register({REG_TARGET}, {k})")
        lines.append(f"  movej({joints_literal(q)}, a={accel_rad_s2:.4f}, v={speed_rad_s:.4f})")
    lines += [f"  write_output_integer_register({REG_DONE}, {number})", "end", ""]
    return "\n".join(lines)


def linear_program(name: str, number: int, robot: Robot, kind: str, poses: list[list[float]],
                   speed_m_s: float, accel_m_s2: float) -> str:
    """``movel`` to one pose or ``movec`` through two (via, to), with progress registers."""
    args = ", ".join(pose_literal(p) for p in poses)
    extra = ", mode=0" if kind == "movec" else ""
    return "\n".join([
        f"def {name}():", f"  write_output_integer_register({REG_STARTED}, {number})",
        f"  {tcp_line(robot)}", f"  write_output_integer_register({REG_TARGET}, 0)",
        f"  {kind}({args}, a={accel_m_s2:.4f}, v={speed_m_s:.4f}{extra})",
        f"  write_output_integer_register({REG_DONE}, {number})", "end", ""])


def stop_line(decel_rad_s2: float) -> str:
    return f"stopj({decel_rad_s2:.4f})\n"


def program_name(text: str) -> str | None:
    m = re.search(r"^\s*def\s+([A-Za-z_]\w*)\s*\(\s*\)\s*:", text, re.M)
    return m.group(1) if m else None


def instrument_upload(text: str, new_name: str, number: int) -> str:
    """An uploaded (exported) program renamed to `new_name`, reporting start and end.

    The top-level ``def`` is renamed (and the call after ``end``, if any); the first body
    line writes the started register, the line before the closing ``end`` the done register.
    Raises ValueError if the text is not one ``def name(): ... end`` program.
    """
    if not _NAME.match(new_name):
        raise ValueError(f"{new_name!r} is not a valid URScript name")
    old = program_name(text)
    if old is None:
        raise ValueError("no 'def name():' line in the script")
    lines = text.splitlines()
    i_def = next(i for i, ln in enumerate(lines) if re.match(rf"^\s*def\s+{old}\s*\(", ln))
    i_end = next((i for i in range(len(lines) - 1, i_def, -1)
                  if re.fullmatch(r"end\s*(#.*)?", lines[i].strip())
                  and not lines[i].startswith((" ", "\t"))), None)
    if i_end is None:
        raise ValueError(f"'def {old}():' has no closing 'end' at the start of a line")
    out = lines[:i_def] + [f"def {new_name}():",
                           f"  write_output_integer_register({REG_STARTED}, {number})"]
    out += lines[i_def + 1:i_end]
    out += [f"  write_output_integer_register({REG_DONE}, {number})", "end"]
    for ln in lines[i_end + 1:]:
        if re.fullmatch(rf"\s*{old}\s*\(\s*\)\s*", ln):
            continue  # the call: a def sent alone is run by the controller anyway
        out.append(ln)
    return "\n".join(out) + "\n"
