"""The MELFA CR-series text protocol: requests, replies, positions, programs, streaming lines.

Sources: the thesis (003 §7.1 Listing 1, Table 3, Appendix C Table 16) for the request
format ``[robot];[slot];<command><argument>`` and the four reply heads; the command set
(OPEN=, CNTLON/OFF, SRVON/OFF, RSTALRM, STOP, SLOTINIT, RUN<name>;<mode>, NEW, LOAD=, ECLR,
EMDAT with vertical-tab separated lines of at most 246 characters, SAVE, EXEC, JPOSF, PPOSF,
DSTATE, ERRORMES, OVRD=, PDIR) as public MELFA drivers use it (e.g. the Robotics Library's
`rl::hal::MitsubishiR3`); MELFA (A, B, C) as rotations about X, Y, Z with R = Rz(C) Ry(B) Rx(A).

Replies end with CR. ``QoK`` = done; ``Qok`` = done but the controller is in an error state;
``QeR`` + 4-digit number = illegal data / refused; ``Qer`` = both.

Error numbers: a real controller's are in its troubleshooting manual. The ones below are the
numbers *our emulator* answers with (MELFA-style, 4 digits); the link only interprets the
collision set (configurable), every other number is shown to the operator with its message.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from assistant.links.arm_config import arm_config, melfa_fl1, melfa_fl2
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.robots.model import Robot
from assistant.transforms import rot_x, rot_y, rot_z

Array = np.ndarray

TERMINATOR = "\r"
WIRE_JOINTS = ("J1", "J2", "J3", "J4", "J5", "J6")
EMDAT_MAX = 246  # 256-byte command buffer minus "1;9;EMDAT" and the terminator
EDIT_SLOT = 9  # TASKMAX (8) + 1 on a CR1 with default parameters (003 Appendix C)

#: The streaming program of the thesis (003 Listing 4) over the Ethernet data link: the PC
#: sends "seq,(j1,...,j6)" lines, the controller moves with CNT blending and answers each
#: accepted target with "seq,J_CURR". A negative seq ends the program cleanly.
STREAM_PROGRAM_NAME = "CTLLINK"
STREAM_COM = 2  # "COM2:" = OPT12 = Ethernet data-link port 10002 with default NETPORT


def streaming_program(com: int = STREAM_COM) -> str:
    return "\n".join([
        "10 ' cellteach: joint targets from the PC, blended with CNT (thesis CONTROLLINK)",
        "20 OVRD 100",
        "30 CNT 1",
        "40 SERVO ON",
        f'50 OPEN "COM{com}:" AS #1',
        "60 DEF JNT JNTPOS",
        "70 INPUT #1, M1, JNTPOS",
        "80 IF M1 < 0 THEN 120",
        "90 MOV JNTPOS",
        "100 PRINT #1, M1, J_CURR",
        "110 GOTO 70",
        "120 CLOSE #1",
        "130 END",
    ])


#: Error numbers of the emulator (and their messages for ERRORMES).
ERR_COLLISION = 1010
ERR_JOINT_RANGE = 2600
ERR_UNREACHABLE = 2700
ERR_SYNTAX = 3100
ERR_NO_PROGRAM = 3200
ERR_NO_OPERATION_RIGHTS = 4200
ERR_SERVO_OFF = 4210
ERR_UNKNOWN_COMMAND = 7000
ERR_ILLEGAL_DATA = 7010
ERR_DATALINK_LOST = 7500
ERROR_MESSAGES = {
    ERR_COLLISION: "Collision detected; the robot stopped",
    ERR_JOINT_RANGE: "Target outside the joint range",
    ERR_UNREACHABLE: "Target position cannot be reached",
    ERR_SYNTAX: "Syntax error in program line",
    ERR_NO_PROGRAM: "Program does not exist",
    ERR_NO_OPERATION_RIGHTS: "No operation rights (CNTLON first)",
    ERR_SERVO_OFF: "Servo is off",
    ERR_UNKNOWN_COMMAND: "Unknown command",
    ERR_ILLEGAL_DATA: "Illegal data",
    ERR_DATALINK_LOST: "Data link disconnected",
}
COLLISION_CODES = frozenset({ERR_COLLISION})


@dataclass(frozen=True)
class Reply:
    head: str  # QoK, Qok, QeR or Qer
    body: str
    raw: str

    @property
    def accepted(self) -> bool:
        return self.head in ("QoK", "Qok")

    @property
    def controller_in_error(self) -> bool:
        return self.head in ("Qok", "Qer")

    @property
    def error_code(self) -> int | None:
        if self.accepted:
            return None
        m = re.match(r"\s*(\d{1,5})", self.body)
        return int(m.group(1)) if m else None


def format_request(robot_no: int, slot: int, command: str) -> bytes:
    if any(c in command for c in "\r\n"):
        raise ValueError("a MELFA command cannot contain CR or LF")
    return f"{robot_no};{slot};{command}{TERMINATOR}".encode("ascii")


def parse_request(line: str) -> tuple[int, int, str]:
    """'1;1;JPOSF' -> (1, 1, 'JPOSF'); empty robot/slot default to 1 (003 Appendix C)."""
    parts = line.split(";", 2)
    if len(parts) != 3:
        raise ValueError(f"not [robot];[slot];command: {line!r}")
    r, s, cmd = parts
    return (int(r) if r.strip() else 1), (int(s) if s.strip() else 1), cmd


def parse_reply(raw: str, command: str) -> Reply:
    """Split a reply into head and body; anything else is a `ProtocolError` quoting it."""
    text = raw.rstrip("\r\n")
    head = text[:3]
    if head not in ("QoK", "Qok", "QeR", "Qer"):
        raise ProtocolError(f"controller answered {command!r} with {raw!r}, which is not a "
                            "MELFA reply (QoK/Qok/QeR/Qer)", raw=raw)
    reply = Reply(head, text[3:], raw)
    if not reply.accepted and reply.error_code is None:
        raise ProtocolError(f"controller refused {command!r} without an error number: {raw!r}",
                            raw=raw)
    return reply


def refusal(reply: Reply, command: str, message: str = "") -> ControllerRefused:
    code = reply.error_code
    text = f"controller refused {command!r}: error {code:04d}" if code is not None else \
        f"controller refused {command!r}"
    if message:
        text += f" ({message})"
    return ControllerRefused(f"{text}; raw reply {reply.raw!r}",
                             code=f"{code:04d}" if code is not None else "", raw=reply.raw)


# ---------------------------------------------------------------------- joints and poses
def wire_index(robot_joint_names: Sequence[str]) -> list[int]:
    """Position of each model joint in the J1..J6 wire tuple (RV-2AJ: J4 stays 0)."""
    names = [n.upper() for n in robot_joint_names]
    if all(n in WIRE_JOINTS for n in names) and len(set(names)) == len(names):
        return [WIRE_JOINTS.index(n) for n in names]
    if len(names) > len(WIRE_JOINTS):
        raise ValueError("MELFA carries at most 6 joints")
    return list(range(len(names)))


def to_wire_deg(q: Array, joint_names: Sequence[str]) -> list[float]:
    out = [0.0] * len(WIRE_JOINTS)
    for i, w in enumerate(wire_index(joint_names)):
        out[w] = float(np.degrees(q[i]))
    return out


def from_wire_deg(values: Sequence[float], joint_names: Sequence[str]) -> Array:
    idx = wire_index(joint_names)
    return np.radians(np.array([values[w] for w in idx], dtype=float))


def format_joint_literal(q: Array, joint_names: Sequence[str], decimals: int = 3) -> str:
    vals = to_wire_deg(np.asarray(q, dtype=float), joint_names)
    return "(" + ",".join(f"{v:.{decimals}f}" for v in vals) + ")"


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_joint_literal(text: str, joint_names: Sequence[str]) -> Array:
    """'(10.00,20.00,...)' (degrees) -> model joints (rad); missing trailing joints are 0."""
    m = re.fullmatch(r"\s*\(([^()]*)\)\s*", text)
    if not m:
        raise ValueError(f"not a joint literal: {text!r}")
    vals = [float(v) for v in m.group(1).split(",") if v.strip()]
    if not vals:
        raise ValueError(f"empty joint literal: {text!r}")
    vals += [0.0] * (len(WIRE_JOINTS) - len(vals))
    return from_wire_deg(vals, joint_names)


def parse_name_value_pairs(body: str, command: str, raw: str) -> dict[str, float]:
    """'J1;10.90;J2;70.76;...;;tail' -> {'J1': 10.9, ...} up to the first empty field."""
    fields = body.split(";")
    out: dict[str, float] = {}
    for i in range(0, len(fields) - 1, 2):
        name, value = fields[i].strip().upper(), fields[i + 1].strip()
        if not name:
            break
        try:
            out[name] = float(value)
        except ValueError:
            if set(value) <= {"*"}:
                continue  # "****": axis not present
            raise ProtocolError(f"reply to {command!r} has a non-numeric {name}: {raw!r}",
                                raw=raw) from None
    return out


def parse_jposf(reply: Reply, joint_names: Sequence[str]) -> Array:
    pairs = parse_name_value_pairs(reply.body, "JPOSF", reply.raw)
    idx = wire_index(joint_names)
    try:
        return np.radians([pairs[WIRE_JOINTS[w]] for w in idx])
    except KeyError as exc:
        raise ProtocolError(f"JPOSF reply lacks joint {exc.args[0]}: {reply.raw!r}",
                            raw=reply.raw) from None


def melfa_abc_to_matrix(a: float, b: float, c: float) -> Array:
    """MELFA (A, B, C) in radians: rotations about X, Y, Z, R = Rz(C) Ry(B) Rx(A)."""
    return rot_z(c) @ rot_y(b) @ rot_x(a)


def matrix_to_melfa_abc(R: Array) -> tuple[float, float, float]:
    sb = float(np.clip(-R[2, 0], -1.0, 1.0))
    b = float(np.arcsin(sb))
    if abs(sb) > 1.0 - 1e-12:
        return 0.0, b, float(np.arctan2(-R[0, 1], R[1, 1]))
    return float(np.arctan2(R[2, 1], R[2, 2])), b, float(np.arctan2(R[1, 0], R[0, 0]))


@dataclass(frozen=True)
class MelfaPose:
    """A MELFA position: T_base_tool plus the structure flags FL1/FL2."""

    T_base_tool: Array
    fl1: int = 7
    fl2: int = 0


def pose_flags(robot: Robot, q: Array) -> tuple[int, int]:
    return melfa_fl1(arm_config(robot, q)), melfa_fl2(q)


def format_pose_literal(pose: MelfaPose, decimals: int = 3) -> str:
    T = pose.T_base_tool
    a, b, c = matrix_to_melfa_abc(T[:3, :3])
    vals = list(T[:3, 3] * 1000.0) + list(np.degrees([a, b, c]))
    return "(" + ",".join(f"{v:.{decimals}f}" for v in vals) + f")({pose.fl1},{pose.fl2})"


def parse_pose_literal(text: str) -> MelfaPose:
    m = re.fullmatch(r"\s*\(([^()]*)\)\s*(?:\(([^()]*)\))?\s*", text)
    if not m:
        raise ValueError(f"not a position literal: {text!r}")
    vals = [float(v) for v in m.group(1).split(",") if v.strip()]
    if len(vals) < 6:
        raise ValueError(f"a position needs X,Y,Z,A,B,C: {text!r}")
    fl1, fl2 = 7, 0
    if m.group(2):
        flags = [f.strip() for f in m.group(2).split(",")]
        fl1 = int(flags[0]) if flags and flags[0] else 7
        fl2 = int(flags[1]) if len(flags) > 1 and flags[1] else 0
    return MelfaPose(_pose_T(vals[:6]), fl1, fl2)


def _pose_T(vals: Sequence[float]) -> Array:
    T = np.eye(4)
    T[:3, :3] = melfa_abc_to_matrix(*np.radians(vals[3:6]))
    T[:3, 3] = np.asarray(vals[:3], dtype=float) / 1000.0
    return T


def parse_pposf(reply: Reply) -> MelfaPose:
    pairs = parse_name_value_pairs(reply.body, "PPOSF", reply.raw)
    try:
        vals = [pairs[k] for k in ("X", "Y", "Z", "A", "B", "C")]
    except KeyError as exc:
        raise ProtocolError(f"PPOSF reply lacks {exc.args[0]}: {reply.raw!r}",
                            raw=reply.raw) from None
    fl1, fl2 = 7, 0
    m = re.search(r";;(-?\d+),(-?\d+)", reply.body)
    if m:
        fl1, fl2 = int(m.group(1)), int(m.group(2))
    return MelfaPose(_pose_T(vals), fl1, fl2)


@dataclass(frozen=True)
class DState:
    run_bits: int
    stop_bits: int
    error_code: int
    step: int

    @property
    def servo_on(self) -> bool:
        return bool(self.run_bits & 0x20)

    @property
    def running(self) -> bool:
        return bool(self.run_bits & 0x40)

    @property
    def operation_enabled(self) -> bool:
        return bool(self.run_bits & 0x80)


def parse_dstate(reply: Reply) -> DState:
    """'QoK' + run status (2 hex) + stop status (2 hex) + error number ';' step ';' mech."""
    m = re.fullmatch(r"([0-9A-Fa-f]{2})([0-9A-Fa-f]{2})(\d+);(-?\d+)(?:;.*)?", reply.body)
    if not m:
        raise ProtocolError(f"DSTATE reply is not run/stop status + error: {reply.raw!r}",
                            raw=reply.raw)
    return DState(int(m.group(1), 16), int(m.group(2), 16), int(m.group(3)), int(m.group(4)))


def format_dstate(st: DState) -> str:
    return f"{st.run_bits:02X}{st.stop_bits:02X}{st.error_code:04d};{st.step};1"


# ---------------------------------------------------------------------- programs
def emdat_chunks(lines: Iterable[str], max_len: int = EMDAT_MAX) -> list[str]:
    """Program lines joined by vertical tabs into EMDAT payloads no longer than `max_len`."""
    chunks: list[str] = []
    cur = ""
    for line in lines:
        line = line.rstrip("\r\n")
        if not line.strip():
            continue
        if "\v" in line or len(line) > max_len:
            raise ValueError(f"program line too long or contains a vertical tab: {line[:40]!r}")
        cand = line if not cur else cur + "\v" + line
        if len(cand) > max_len:
            chunks.append(cur)
            cur = line
        else:
            cur = cand
    if cur:
        chunks.append(cur)
    return chunks


def sanitize_program_name(name: str, max_len: int = 8) -> str:
    base = re.sub(r"[^A-Z0-9]", "", name.upper())
    if not base or not base[0].isalpha():
        base = "P" + base
    return base[:max_len]


def program_lines(files: dict[str, bytes]) -> list[str]:
    """All lines of a program's files: code files first, then position files (.POS)."""
    def is_pos(n: str) -> bool:
        return n.lower().endswith((".pos", ".pts"))

    out: list[str] = []
    for name in sorted(files, key=is_pos):
        text = files[name].decode("ascii", errors="strict")
        out += [ln for ln in text.splitlines() if ln.strip()]
    return out


# ---------------------------------------------------------------------- streaming lines
def format_stream_line(seq: int, q: Array, joint_names: Sequence[str]) -> bytes:
    return f"{seq},{format_joint_literal(q, joint_names)}{TERMINATOR}".encode("ascii")


_FEEDBACK = re.compile(r"\s*(-?\d+)\s*,\s*(\([^()]*\))\s*")


def parse_feedback_line(raw: str, joint_names: Sequence[str]) -> tuple[int, Array]:
    m = _FEEDBACK.fullmatch(raw.strip("\r\n"))
    if not m:
        raise ProtocolError(f"data link answered {raw!r}, expected 'seq,(joints)'", raw=raw)
    try:
        return int(m.group(1)), parse_joint_literal(m.group(2), joint_names)
    except ValueError as exc:
        raise ProtocolError(f"data link answered {raw!r}: {exc}", raw=raw) from None
