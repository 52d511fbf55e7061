"""The UR primary/secondary client interface (TCP 30001/30002): what the controller says back.

A client sends URScript as text; the controller answers, on the same socket, with binary
packages: ``int32 length`` (header included), ``uint8 type``, body. The link needs the
*robot messages* (type 20): ``uint64 timestamp, int8 source, uint8 message type`` then, for
a runtime exception (10), ``int32 line, int32 column`` and the text; for a text message (0)
the text; the version message (3) arrives once on connect. Robot state packages (16) are
skipped. Any other framing is garbage and ends the connection (it cannot re-synchronise).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass

from assistant.links.errors import ProtocolError

HEADER = struct.Struct(">iB")
ROBOT_STATE = 16
ROBOT_MESSAGE = 20
PROGRAM_STATE_MESSAGE = 25
KNOWN_TYPES = frozenset({ROBOT_STATE, ROBOT_MESSAGE, PROGRAM_STATE_MESSAGE, 5, 23, 24})

MSG_TEXT = 0
MSG_VERSION = 3
MSG_SAFETY_MODE = 5
MSG_ERROR_CODE = 6
MSG_RUNTIME_EXCEPTION = 10
_MSG_HEAD = struct.Struct(">QbB")


@dataclass(frozen=True)
class RobotMessage:
    kind: int
    text: str
    line: int = 0
    column: int = 0

    def describe(self) -> str:
        where = f" (script line {self.line}, column {self.column})" if self.line else ""
        return f"{self.text}{where}"


def pack_robot_message(kind: int, body: bytes, timestamp_us: int = 0, source: int = -2) -> bytes:
    payload = _MSG_HEAD.pack(timestamp_us, source, kind) + body
    return HEADER.pack(HEADER.size + len(payload), ROBOT_MESSAGE) + payload


def runtime_exception(text: str, line: int = 0, column: int = 0) -> bytes:
    return pack_robot_message(MSG_RUNTIME_EXCEPTION,
                              struct.pack(">ii", line, column) + text.encode("utf-8"))


def text_message(text: str) -> bytes:
    return pack_robot_message(MSG_TEXT, text.encode("utf-8"))


def version_message(project: str, major: int, minor: int, bugfix: int, build: int,
                    date: str = "") -> bytes:
    name = project.encode()
    body = bytes([len(name)]) + name + bytes([major, minor]) + struct.pack(">ii", bugfix, build)
    return pack_robot_message(MSG_VERSION, body + date.encode())


class PrimaryReader:
    """Splits the controller's byte stream into robot messages; other packages are skipped."""

    def __init__(self) -> None:
        self.buf = b""

    def feed(self, data: bytes) -> Iterator[RobotMessage]:
        self.buf += data
        while len(self.buf) >= HEADER.size:
            size, kind = HEADER.unpack_from(self.buf)
            if size < HEADER.size or size > 1 << 20 or kind not in KNOWN_TYPES:
                raw = self.buf[:64].decode("latin-1")
                self.buf = b""
                raise ProtocolError(f"not a primary-interface package (size {size}, type "
                                    f"{kind}): {raw!r}", raw=raw)
            if len(self.buf) < size:
                return
            body, self.buf = self.buf[HEADER.size:size], self.buf[size:]
            if kind != ROBOT_MESSAGE or len(body) < _MSG_HEAD.size:
                continue
            _, _, mkind = _MSG_HEAD.unpack_from(body)
            rest = body[_MSG_HEAD.size:]
            if mkind == MSG_RUNTIME_EXCEPTION and len(rest) >= 8:
                line, col = struct.unpack_from(">ii", rest)
                yield RobotMessage(mkind, rest[8:].decode("utf-8", errors="replace"), line, col)
            elif mkind == MSG_TEXT:
                yield RobotMessage(mkind, rest.decode("utf-8", errors="replace"))
            elif mkind == MSG_VERSION and rest:
                n = rest[0]
                yield RobotMessage(mkind, rest[1:1 + n].decode("utf-8", errors="replace"))
