"""The UR primary client interface (TCP 30001; 30002 secondary): what the controller says.

A client may send URScript as text; the controller streams binary packages to it:
``int32 length`` (header included), ``uint8 type``, body (UR's "Client Interfaces" document,
PolyScope 5 / 3.x). Types we read:

- robot state (16), at 10 Hz: a sequence of sub-packages, each ``int32 length, uint8 type``:
  robot mode data (0: ``uint64 timestamp``, eight booleans - real robot connected/enabled,
  power on, emergency stopped, protective stopped, program running, program paused - then
  ``uint8 robot mode, uint8 control mode``, speed fractions) and kinematics info (5:
  ``uint32 checksum[6], double theta[6], a[6], d[6], alpha[6], uint32 calibration status``:
  the controller's *calibrated* DH table);
- robot messages (20): ``uint64 timestamp, int8 source, uint8 message type`` then by type -
  text (0), popup (2: ``uint32 id, uint8 type, bool warning, bool error, bool blocking,
  uint8 title length, title, message``), version (3), safety mode (5: ``int32 code,
  int32 argument, uint8 mode, uint32 data type, uint32 data``, text), error code (6:
  ``int32 code, int32 argument, int32 report level, uint8 data type, uint32 data``, text),
  key message (7, same head as 6, ``uint8 title length, title``, text), runtime exception
  (10: ``int32 line, int32 column``, text).

Any other package type, sub-package type or message type is skipped by its length, as UR
says a client must (new controller versions add them). Only a length no package can have
is garbage: the stream cannot re-synchronise after it, so it ends the connection.
Only the primary interface carries robot messages; the secondary (30002) sends robot state.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from assistant.links.errors import ProtocolError

HEADER = struct.Struct(">iB")
ROBOT_STATE = 16
ROBOT_MESSAGE = 20
MAX_PACKAGE = 1 << 20

# robot message types
MSG_TEXT = 0
MSG_POPUP = 2
MSG_VERSION = 3
MSG_SAFETY_MODE = 5
MSG_ERROR_CODE = 6
MSG_KEY = 7
MSG_RUNTIME_EXCEPTION = 10
_MSG_HEAD = struct.Struct(">QbB")
_CODE_HEAD = struct.Struct(">iiiBI")  # code, argument, report level, data type, data
_SAFETY_HEAD = struct.Struct(">iiBII")  # code, argument, safety mode, data type, data

# robot state sub-package types
SUB_ROBOT_MODE = 0
SUB_KINEMATICS = 5
_MODE = struct.Struct(">Q???????BBddd")
_KIN = struct.Struct(">6I24dI")


@dataclass(frozen=True)
class RobotMessage:
    """A message from the controller; `code` is e.g. "C204A3" for error and key messages."""

    kind: int
    text: str
    line: int = 0
    column: int = 0
    code: str = ""
    title: str = ""
    level: int = 0  # report level (error code messages): 0 info .. 3 fault

    def describe(self) -> str:
        head = " ".join(p for p in (self.code, self.title) if p)
        where = f" (script line {self.line}, column {self.column})" if self.line else ""
        return f"{head}: {self.text}{where}" if head else f"{self.text}{where}"

    @property
    def is_error(self) -> bool:
        """Stops a program: a runtime exception, a fault or violation, an error popup."""
        return self.kind == MSG_RUNTIME_EXCEPTION or \
            (self.kind == MSG_ERROR_CODE and self.level >= 2) or \
            (self.kind == MSG_POPUP and self.level >= 2)


@dataclass(frozen=True)
class RobotModeData:
    power_on: bool
    emergency_stopped: bool
    protective_stopped: bool
    program_running: bool
    robot_mode: int


@dataclass(frozen=True)
class KinematicsInfo:
    """The controller's calibrated DH table (standard DH: Rz(theta+q) Tz(d) Tx(a) Rx(alpha))."""

    checksum: tuple[int, ...]
    theta: tuple[float, ...]
    a: tuple[float, ...]
    d: tuple[float, ...]
    alpha: tuple[float, ...]
    calibration_status: int


def _msg(kind: int, body: bytes, timestamp_us: int = 0, source: int = -2) -> bytes:
    payload = _MSG_HEAD.pack(timestamp_us, source, kind) + body
    return HEADER.pack(HEADER.size + len(payload), ROBOT_MESSAGE) + payload


def runtime_exception(text: str, line: int = 0, column: int = 0) -> bytes:
    return _msg(MSG_RUNTIME_EXCEPTION, struct.pack(">ii", line, column) + text.encode())


def text_message(text: str) -> bytes:
    return _msg(MSG_TEXT, text.encode("utf-8"))


def version_message(project: str, major: int, minor: int, bugfix: int, build: int,
                    date: str = "") -> bytes:
    name = project.encode()
    body = bytes([len(name)]) + name + bytes([major, minor]) + struct.pack(">ii", bugfix, build)
    return _msg(MSG_VERSION, body + date.encode())


def error_code_message(code: int, argument: int, level: int, text: str) -> bytes:
    """An error code message (C<code>A<argument>); level 0 info, 1 warning, 2 violation,
    3 fault."""
    return _msg(MSG_ERROR_CODE, _CODE_HEAD.pack(code, argument, level, 0, 0) + text.encode())


def safety_mode_message(code: int, argument: int, mode: int, text: str) -> bytes:
    return _msg(MSG_SAFETY_MODE, _SAFETY_HEAD.pack(code, argument, mode, 0, 0) + text.encode())


def popup_message(title: str, text: str, *, error: bool = False, warning: bool = False,
                  blocking: bool = True) -> bytes:
    t = title.encode()[:255]
    body = struct.pack(">IB???B", 0, 0, warning, error, blocking, len(t)) + t + text.encode()
    return _msg(MSG_POPUP, body)


def robot_state(*subpackages: bytes) -> bytes:
    body = b"".join(subpackages)
    return HEADER.pack(HEADER.size + len(body), ROBOT_STATE) + body


def _sub(kind: int, body: bytes) -> bytes:
    return HEADER.pack(HEADER.size + len(body), kind) + body


def robot_mode_sub(mode: RobotModeData, timestamp_us: int = 0) -> bytes:
    return _sub(SUB_ROBOT_MODE, _MODE.pack(timestamp_us, True, True, mode.power_on,
                                           mode.emergency_stopped, mode.protective_stopped,
                                           mode.program_running, False, mode.robot_mode, 0,
                                           1.0, 1.0, 1.0) + b"\x00")


def kinematics_sub(k: KinematicsInfo) -> bytes:
    return _sub(SUB_KINEMATICS, _KIN.pack(*k.checksum, *k.theta, *k.a, *k.d, *k.alpha,
                                          k.calibration_status))


def _text(b: bytes) -> str:
    return b.decode("utf-8", errors="replace")


def _code(code: int, argument: int) -> str:
    return f"C{code}A{argument}"


def parse_message(body: bytes) -> RobotMessage | None:
    """One robot message package body; None for message types the link does not use."""
    if len(body) < _MSG_HEAD.size:
        return None
    _, _, kind = _MSG_HEAD.unpack_from(body)
    rest = body[_MSG_HEAD.size:]
    if kind == MSG_RUNTIME_EXCEPTION and len(rest) >= 8:
        line, col = struct.unpack_from(">ii", rest)
        return RobotMessage(kind, _text(rest[8:]), line, col, level=3)
    if kind == MSG_TEXT:
        return RobotMessage(kind, _text(rest))
    if kind == MSG_VERSION and rest:
        n = rest[0]
        name = _text(rest[1:1 + n])
        nums = rest[1 + n:]
        if len(nums) >= 10:
            major, minor = nums[0], nums[1]
            bugfix, build = struct.unpack_from(">ii", nums, 2)
            return RobotMessage(kind, f"{name} {major}.{minor}.{bugfix}.{build}")
        return RobotMessage(kind, name)
    if kind == MSG_ERROR_CODE and len(rest) >= _CODE_HEAD.size:
        code, arg, level, _, _ = _CODE_HEAD.unpack_from(rest)
        return RobotMessage(kind, _text(rest[_CODE_HEAD.size:]), code=_code(code, arg),
                            level=level)
    if kind == MSG_KEY and len(rest) >= _CODE_HEAD.size + 1:
        code, arg, _, _, _ = _CODE_HEAD.unpack_from(rest)
        n = rest[_CODE_HEAD.size]
        title = _text(rest[_CODE_HEAD.size + 1:_CODE_HEAD.size + 1 + n])
        return RobotMessage(kind, _text(rest[_CODE_HEAD.size + 1 + n:]), code=_code(code, arg),
                            title=title)
    if kind == MSG_SAFETY_MODE and len(rest) >= _SAFETY_HEAD.size:
        code, arg, _, _, _ = _SAFETY_HEAD.unpack_from(rest)
        return RobotMessage(kind, _text(rest[_SAFETY_HEAD.size:]), code=_code(code, arg),
                            level=2)
    if kind == MSG_POPUP and len(rest) >= 9:
        _, _, warning, error, _, n = struct.unpack_from(">IB???B", rest)
        title = _text(rest[9:9 + n])
        return RobotMessage(kind, _text(rest[9 + n:]), title=title,
                            level=2 if error else 1 if warning else 0)
    return None


def parse_state(body: bytes) -> Iterator[RobotModeData | KinematicsInfo]:
    """The sub-packages of a robot state package the link uses (others skipped by length)."""
    i = 0
    while i + HEADER.size <= len(body):
        size, kind = HEADER.unpack_from(body, i)
        if size < HEADER.size or i + size > len(body):
            return  # a truncated last sub-package: nothing more to read in this package
        sub = body[i + HEADER.size:i + size]
        i += size
        if kind == SUB_ROBOT_MODE and len(sub) >= _MODE.size:
            v = _MODE.unpack_from(sub)
            yield RobotModeData(power_on=v[3], emergency_stopped=v[4],
                                protective_stopped=v[5], program_running=v[6],
                                robot_mode=v[8])
        elif kind == SUB_KINEMATICS and len(sub) >= _KIN.size:
            v = _KIN.unpack_from(sub)
            yield KinematicsInfo(tuple(v[0:6]), tuple(v[6:12]), tuple(v[12:18]),
                                 tuple(v[18:24]), tuple(v[24:30]), v[30])


class PrimaryReader:
    """Splits the controller's byte stream into messages and the state parts we use."""

    def __init__(self) -> None:
        self.buf = b""
        #: Package types skipped because this reader does not know them (for the wire log).
        self.skipped: dict[int, int] = {}

    def feed(self, data: bytes) -> Iterator[RobotMessage | RobotModeData | KinematicsInfo]:
        self.buf += data
        while len(self.buf) >= HEADER.size:
            size, kind = HEADER.unpack_from(self.buf)
            if size < HEADER.size or size > MAX_PACKAGE:
                raw = self.buf[:64].decode("latin-1")
                self.buf = b""
                raise ProtocolError(f"not a primary-interface package (size {size}, type "
                                    f"{kind}): {raw!r}", raw=raw)
            if len(self.buf) < size:
                return
            body, self.buf = self.buf[HEADER.size:size], self.buf[size:]
            if kind == ROBOT_MESSAGE:
                msg = parse_message(body)
                if msg is not None:
                    yield msg
            elif kind == ROBOT_STATE:
                yield from parse_state(body)
            else:
                self.skipped[kind] = self.skipped.get(kind, 0) + 1


def unknown_package(kind: int, body: bytes) -> bytes:
    """A package of a type the reader does not know (tests: it must be skipped)."""
    return HEADER.pack(HEADER.size + len(body), kind) + body


def dh_lists(k: KinematicsInfo) -> Sequence[tuple[float, float, float, float]]:
    """(d, theta, a, alpha) per joint."""
    return list(zip(k.d, k.theta, k.a, k.alpha, strict=True))
