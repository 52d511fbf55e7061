"""The KUKA REST bridge of source 002: endpoints, query parameters, replies, uploads.

Every command is ``POST /krl/<method>`` with query parameters x, y, z (mm), a, b, c (deg,
KUKA convention: A about Z, B about Y, C about X, R = Rz(A) Ry(B) Rx(C)), s, t (Status and
Turn integers); the reply is JSON ``{"statuscode": 1, "position": [x, y, z, a, b, c]}``
(002 §4.1.2, Listing 4.7). Missing coordinates keep their current value (002 §4.1.2.1).

What 002 leaves open, and what we chose (our bridge emulator answers the same way):
- statuscode meanings beyond 1 = done: see `STATUS_TEXT` below; replies may carry an extra
  "message" (and "program" for uploads), which the 002 schema simply does not have.
- circ's auxiliary point: parameters aux_x ... aux_c (002 only says "two points").
- speed: optional ``vel`` (percent of full speed); a bridge without it ignores the parameter.
- ``POST /krl/stop``: abort the running motion (the 002 bridge had no way to stop; a 404
  from a bridge without it is tolerated and the link waits for the current command).
"""

from __future__ import annotations

import json
import re
import uuid
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from assistant.links.errors import ProtocolError
from assistant.transforms import matrix_to_rpy, rpy_to_matrix

Array = np.ndarray

ENDPOINTS = ("ptp", "linmov", "circ", "getpos", "base", "tcp", "gettcp", "uploadfile", "stop")

STATUS_OK = 1
STATUS_STOPPED = 0
STATUS_COLLISION = 2
STATUS_LIMIT = -1
STATUS_UNREACHABLE = -2
STATUS_BAD_REQUEST = -3
STATUS_PROGRAM_ERROR = -4
STATUS_TEXT = {
    STATUS_OK: "done",
    STATUS_STOPPED: "motion stopped on request before the target",
    STATUS_COLLISION: "collision detected; the robot stopped",
    STATUS_LIMIT: "software limit switch: target outside the axis range",
    STATUS_UNREACHABLE: "target cannot be reached",
    STATUS_BAD_REQUEST: "malformed request",
    STATUS_PROGRAM_ERROR: "uploaded program refused or failed",
}


@dataclass(frozen=True)
class BridgeReply:
    statuscode: int
    position: tuple[float, ...]
    message: str
    program: str
    raw: str
    #: The arm's axes in degrees, when the bridge reports them (ours does; 002's did not).
    axes: tuple[float, ...] = ()

    @property
    def ok(self) -> bool:
        return self.statuscode == STATUS_OK

    def describe(self) -> str:
        text = self.message or STATUS_TEXT.get(self.statuscode, "unknown status")
        return f"statuscode {self.statuscode} ({text}); raw reply {self.raw!r}"


def pose_params(T_base_tool: Array, s: int | None = None, t: int | None = None,
                prefix: str = "") -> dict[str, str]:
    """Query parameters of a pose in mm / deg (enough digits that rounding stays < 1e-7)."""
    T = np.asarray(T_base_tool, dtype=float)
    a, b, c = np.degrees(matrix_to_rpy(T[:3, :3]))
    x, y, z = T[:3, 3] * 1000.0
    out = {f"{prefix}x": f"{x:.4f}", f"{prefix}y": f"{y:.4f}", f"{prefix}z": f"{z:.4f}",
           f"{prefix}a": f"{a:.6f}", f"{prefix}b": f"{b:.6f}", f"{prefix}c": f"{c:.6f}"}
    if s is not None:
        out[f"{prefix}s"] = str(int(s))
    if t is not None:
        out[f"{prefix}t"] = str(int(t))
    return out


def position_to_T(position: Sequence[float]) -> Array:
    v = np.asarray(position, dtype=float)
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(*np.radians(v[3:6]))
    T[:3, 3] = v[:3] / 1000.0
    return T


def T_to_position(T: Array) -> list[float]:
    a, b, c = np.degrees(matrix_to_rpy(np.asarray(T)[:3, :3]))
    return [float(v) for v in np.asarray(T)[:3, 3] * 1000.0] + [float(a), float(b), float(c)]


def parse_reply(raw: bytes, endpoint: str) -> BridgeReply:
    """JSON reply -> `BridgeReply`; anything else is a `ProtocolError` quoting it."""
    text = raw.decode("utf-8", errors="replace")
    try:
        data = json.loads(text)
    except ValueError:
        raise ProtocolError(f"bridge answered /{endpoint} with {text[:200]!r}, which is not "
                            "JSON", raw=text) from None
    if not isinstance(data, dict) or "statuscode" not in data:
        raise ProtocolError(f"bridge reply to /{endpoint} has no statuscode: {text[:200]!r}",
                            raw=text)
    try:
        code = int(data["statuscode"])
        pos = tuple(float(v) for v in data.get("position", ()))
        axes = tuple(float(v) for v in data.get("axes", ()))
    except (TypeError, ValueError):
        raise ProtocolError(f"bridge reply to /{endpoint} is malformed: {text[:200]!r}",
                            raw=text) from None
    if code == STATUS_OK and len(pos) != 6:
        raise ProtocolError(f"bridge reply to /{endpoint} lacks a 6-value position: "
                            f"{text[:200]!r}", raw=text)
    return BridgeReply(code, pos, str(data.get("message", "")), str(data.get("program", "")),
                       text, axes)


def reply_json(statuscode: int, position: Sequence[float], message: str = "",
               program: str = "") -> str:
    d: dict = {"statuscode": int(statuscode), "position": [round(float(v), 6) for v in position]}
    if message:
        d["message"] = message
    if program:
        d["program"] = program
    return json.dumps(d)


# ---------------------------------------------------------------------- KRL modules
_KRL_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,23}$")


def krl_module_name(text: str) -> str | None:
    m = re.search(r"^\s*(?:GLOBAL\s+)?(?:DEF|DEFFCT\s+\w+|DEFDAT)\s+([A-Za-z_]\w*)", text,
                  re.IGNORECASE | re.MULTILINE)
    return m.group(1) if m else None


def rename_krl_module(text: str, old: str, new: str) -> str:
    """Rename DEF/DEFFCT/DEFDAT `old` to `new`: KRL needs the module name = file name."""
    if not _KRL_NAME.match(new):
        raise ValueError(f"{new!r} is not a valid KRL name")
    pat = re.compile(rf"^(\s*(?:GLOBAL\s+)?(?:DEF|DEFFCT\s+\w+|DEFDAT)\s+){re.escape(old)}\b",
                     re.IGNORECASE | re.MULTILINE)
    out, n = pat.subn(lambda m: m.group(1) + new, text)
    if n == 0:
        raise ValueError(f"no DEF/DEFDAT {old} in the module")
    return out


def multipart(field: str, filename: str, data: bytes) -> tuple[bytes, str]:
    """A multipart/form-data body with one file (what FastAPI's UploadFile expects)."""
    boundary = f"cellteach-{uuid.uuid4().hex}"
    head = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"{field}\"; "
            f"filename=\"{filename}\"\r\nContent-Type: application/octet-stream\r\n\r\n")
    body = head.encode() + data + f"\r\n--{boundary}--\r\n".encode()
    return body, f"multipart/form-data; boundary={boundary}"


def parse_multipart(body: bytes, content_type: str) -> dict[str, tuple[str, bytes]]:
    """field -> (filename, data) for the simple bodies `multipart` builds (emulator side)."""
    m = re.search(r"boundary=\"?([^\";]+)\"?", content_type)
    if not m:
        raise ValueError("multipart body without boundary")
    sep = b"--" + m.group(1).encode()
    out: dict[str, tuple[str, bytes]] = {}
    for part in body.split(sep)[1:]:
        if part.startswith(b"--"):
            break
        head, _, data = part.partition(b"\r\n\r\n")
        hm = re.search(rb'name="([^"]+)"(?:; filename="([^"]*)")?', head)
        if not hm:
            continue
        out[hm.group(1).decode()] = ((hm.group(2) or b"").decode(),
                                     data[:-2] if data.endswith(b"\r\n") else data)
    return out
