"""Universal Robots RTDE (Real-Time Data Exchange, TCP 30004), protocol version 2: packages,
output variables and their types, robot/safety modes.

Every package is ``uint16 size`` (header included, big endian), ``uint8 type``, payload. A
client negotiates the protocol version (``V``), may ask the controller version (``v``), sets
up an output recipe (``O``: ``double frequency`` + comma-separated names; the reply is a
``uint8`` recipe id + the comma-separated types, ``NOT_FOUND`` for unknown names), then
``S`` starts the stream of ``U`` data packages (``uint8`` recipe id + the values, big endian)
at that frequency; ``P`` pauses it. Source: UR's "Real-Time Data Exchange (RTDE) Guide" and
its reference Python client; the emulator answers the way a controller does, so UR's own
clients (ur-rtde's `RTDEReceiveInterface`) read it unmodified.

Shared by our link's client (`ur_rtde_client`) and the emulator
(`assistant/emulators/ur_rtde_server`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator, Sequence
from enum import IntEnum

from assistant.links.errors import ProtocolError

HEADER = struct.Struct(">HB")
PROTOCOL_VERSION = 2


class Cmd(IntEnum):
    REQUEST_PROTOCOL_VERSION = 86  # 'V'
    GET_URCONTROL_VERSION = 118  # 'v'
    TEXT_MESSAGE = 77  # 'M'
    DATA_PACKAGE = 85  # 'U'
    SETUP_OUTPUTS = 79  # 'O'
    SETUP_INPUTS = 73  # 'I'
    START = 83  # 'S'
    PAUSE = 80  # 'P'


#: struct codes of the RTDE types (all big endian).
TYPE_CODES = {"BOOL": "?", "UINT8": "B", "UINT32": "I", "UINT64": "Q", "INT32": "i",
              "DOUBLE": "d", "VECTOR3D": "3d", "VECTOR6D": "6d", "VECTOR6INT32": "6i",
              "VECTOR6UINT32": "6I"}

_V6 = "VECTOR6D"
#: Controller output variables (RTDE guide, PolyScope 5.x) this controller model knows.
OUTPUTS: dict[str, str] = {
    "timestamp": "DOUBLE", "target_q": _V6, "target_qd": _V6, "target_qdd": _V6,
    "target_current": _V6, "target_moment": _V6, "actual_q": _V6, "actual_qd": _V6,
    "actual_current": _V6, "joint_control_output": _V6, "actual_TCP_pose": _V6,
    "actual_TCP_speed": _V6, "actual_TCP_force": _V6, "target_TCP_pose": _V6,
    "target_TCP_speed": _V6, "actual_digital_input_bits": "UINT64",
    "joint_temperatures": _V6, "actual_execution_time": "DOUBLE", "robot_mode": "INT32",
    "joint_mode": "VECTOR6INT32", "safety_mode": "INT32", "safety_status": "INT32",
    "actual_tool_accelerometer": "VECTOR3D", "speed_scaling": "DOUBLE",
    "target_speed_fraction": "DOUBLE", "actual_momentum": "DOUBLE",
    "actual_main_voltage": "DOUBLE", "actual_robot_voltage": "DOUBLE",
    "actual_robot_current": "DOUBLE", "actual_joint_voltage": _V6,
    "actual_digital_output_bits": "UINT64", "runtime_state": "UINT32",
    "standard_analog_input0": "DOUBLE", "standard_analog_input1": "DOUBLE",
    "standard_analog_output0": "DOUBLE", "standard_analog_output1": "DOUBLE",
    "robot_status_bits": "UINT32", "safety_status_bits": "UINT32", "ft_raw_wrench": _V6,
    "payload": "DOUBLE", "payload_cog": "VECTOR3D", "payload_inertia": _V6,
    "speed_scaling_combined": "DOUBLE",
    **{f"output_int_register_{i}": "INT32" for i in range(48)},
    **{f"output_double_register_{i}": "DOUBLE" for i in range(48)},
    **{f"output_bit_register_{i}": "BOOL" for i in range(64, 128)},
}


class RobotMode(IntEnum):
    NO_CONTROLLER = -1
    DISCONNECTED = 0
    CONFIRM_SAFETY = 1
    BOOTING = 2
    POWER_OFF = 3
    POWER_ON = 4
    IDLE = 5
    BACKDRIVE = 6
    RUNNING = 7
    UPDATING_FIRMWARE = 8


class SafetyMode(IntEnum):
    NORMAL = 1
    REDUCED = 2
    PROTECTIVE_STOP = 3
    RECOVERY = 4
    SAFEGUARD_STOP = 5
    SYSTEM_EMERGENCY_STOP = 6
    ROBOT_EMERGENCY_STOP = 7
    VIOLATION = 8
    FAULT = 9
    VALIDATE_JOINT_ID = 10
    UNDEFINED_SAFETY_MODE = 11
    AUTOMATIC_MODE_SAFEGUARD_STOP = 12
    SYSTEM_THREE_POSITION_ENABLING_STOP = 13


EMERGENCY_STOPS = frozenset({SafetyMode.SYSTEM_EMERGENCY_STOP, SafetyMode.ROBOT_EMERGENCY_STOP})
#: Safety modes in which the arm cannot move until someone acts (besides the e-stops).
HALTING = frozenset({SafetyMode.PROTECTIVE_STOP, SafetyMode.SAFEGUARD_STOP,
                     SafetyMode.AUTOMATIC_MODE_SAFEGUARD_STOP, SafetyMode.VIOLATION,
                     SafetyMode.FAULT, SafetyMode.RECOVERY,
                     SafetyMode.SYSTEM_THREE_POSITION_ENABLING_STOP})


class RuntimeState(IntEnum):
    STOPPING = 0
    STOPPED = 1
    PLAYING = 2
    PAUSING = 3
    PAUSED = 4
    RESUMING = 5


#: safety_status_bits: bit i set <=> the mode (RTDE guide's order).
SAFETY_BIT = {SafetyMode.NORMAL: 0, SafetyMode.REDUCED: 1, SafetyMode.PROTECTIVE_STOP: 2,
              SafetyMode.RECOVERY: 3, SafetyMode.SAFEGUARD_STOP: 4,
              SafetyMode.SYSTEM_EMERGENCY_STOP: 5, SafetyMode.ROBOT_EMERGENCY_STOP: 6,
              SafetyMode.VIOLATION: 8, SafetyMode.FAULT: 9}
SAFETY_STOPPED_BIT = 10
EMERGENCY_STOPPED_BIT = 7


def safety_status_bits(mode: SafetyMode) -> int:
    bits = 1 << SAFETY_BIT.get(mode, 9)
    if mode in EMERGENCY_STOPS:
        bits |= 1 << EMERGENCY_STOPPED_BIT
    if mode != SafetyMode.NORMAL and mode != SafetyMode.REDUCED:
        bits |= 1 << SAFETY_STOPPED_BIT
    return bits


def mode_name(enum: type[IntEnum], value: int) -> str:
    try:
        return enum(value).name
    except ValueError:
        return f"UNKNOWN({value})"


# ---------------------------------------------------------------------- packages
def pack(cmd: int, payload: bytes = b"") -> bytes:
    if len(payload) + HEADER.size > 0xFFFF:
        raise ValueError("RTDE package too large")
    return HEADER.pack(len(payload) + HEADER.size, int(cmd)) + payload


def recipe_struct(types: Sequence[str]) -> struct.Struct:
    """The struct of a data package's values (after the recipe id)."""
    try:
        return struct.Struct(">" + "".join(TYPE_CODES[t] for t in types))
    except KeyError as exc:
        raise ProtocolError(f"unknown RTDE type {exc.args[0]!r}", raw=",".join(types)) from None


def group_values(flat: Sequence, types: Sequence[str]) -> list:
    """Flat struct output -> one value (scalar or list) per variable."""
    out, i = [], 0
    for t in types:
        code = TYPE_CODES[t]
        n = int(code[:-1]) if len(code) > 1 else 1
        out.append(flat[i] if n == 1 and len(code) == 1 else list(flat[i:i + n]))
        i += n
    return out


def flatten_values(values: Sequence, types: Sequence[str]) -> list:
    out: list = []
    for v, t in zip(values, types, strict=True):
        if len(TYPE_CODES[t]) > 1:
            out.extend(v)
        else:
            out.append(v)
    return out


def text_message(message: str, source: str = "cellteach", level: int = 0) -> bytes:
    """A v2 ``M`` package: uint8 length + message, uint8 length + source, uint8 level."""
    m, s = message.encode()[:255], source.encode()[:255]
    return pack(Cmd.TEXT_MESSAGE, bytes([len(m)]) + m + bytes([len(s)]) + s + bytes([level]))


def parse_text_message(payload: bytes) -> str:
    if not payload:
        return ""
    n = payload[0]
    return payload[1:1 + n].decode("utf-8", errors="replace")


class PackageReader:
    """Splits a byte stream into (type, payload); anything off the protocol is an error.

    `known` limits the accepted package types (a peer answering with a type it never sends
    is garbage, and the stream cannot be re-synchronised after it).
    """

    def __init__(self, known: frozenset[int] = frozenset(int(c) for c in Cmd)):
        self.buf = b""
        self.known = known

    def feed(self, data: bytes) -> Iterator[tuple[int, bytes]]:
        self.buf += data
        while len(self.buf) >= HEADER.size:
            size, cmd = HEADER.unpack_from(self.buf)
            if size < HEADER.size or cmd not in self.known:
                raw = self.buf[:64].decode("latin-1")
                self.buf = b""
                raise ProtocolError(f"not an RTDE package (size {size}, type {cmd}): "
                                    f"{raw!r}", raw=raw)
            if len(self.buf) < size:
                return
            payload, self.buf = self.buf[HEADER.size:size], self.buf[size:]
            yield cmd, payload
