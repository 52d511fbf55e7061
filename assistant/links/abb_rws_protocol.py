"""ABB Robot Web Services 1.0 (IRC5, RobotWare 6) as our link and emulator speak it.

Every resource answers JSON when asked with ``?json=1``: ``{"_links": {...}, "_embedded":
{"_state": [{"_type": "ms-jointtarget", "_title": "ROB_1", "rax_1": "12.5", ...}]}}``, values
as strings in degrees / millimetres / quaternions (w, x, y, z). An error is an HTTP 4xx whose
JSON carries ``_embedded.status`` = ``{"code": <RobotWare return code>, "msg": ...}`` - the
shape `abb-robot-client` parses. Logins are HTTP digest (``Default User`` / ``robotics`` on a
fresh controller), then the session cookie; writes to RAPID take *mastership* (one holder).

What the real controller numbers itself and we chose: the return codes below (RWS lists the
real ones under /rw/retcode; ours are in its 0xC004xxxx style) and the event-log codes we
emit (50204 motion supervision - what a collision triggers, 50027 joint out of range, 50050
position outside reach; 100xx program information).

Also here: the RAPID module our link uploads for an exploration move (MoveAbsJ through
joint targets), since RWS has no "move to" resource of its own.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from assistant.links.errors import ProtocolError

Array = np.ndarray

#: RAPID's "no external axis" placeholder.
NO_AXIS = "9E+09"
EXTERNAL = "[" + ",".join([NO_AXIS] * 6) + "]"

# RobotWare-style return codes (see the module docstring).
RC_BAD_REQUEST = -1073442814
RC_NOT_FOUND = -1073445865
RC_HELD_BY_OTHER = -1073445858
RC_NOT_MASTER = -1073445857
RC_MOTORS_OFF = -1073442811
RC_RUNNING = -1073442810
RC_PP_LOST = -1073442812
RC_LOAD_ERROR = -1073442809

# Event-log message types and the codes the emulator writes.
ELOG_INFO, ELOG_WARNING, ELOG_ERROR = 1, 2, 3
ELOG_MOTION_SUPERVISION = 50204
ELOG_JOINT_OUT_OF_RANGE = 50027
ELOG_OUTSIDE_REACH = 50050
ELOG_PP_RESET = 10002
ELOG_PROGRAM_STARTED = 10010
ELOG_PROGRAM_STOPPED = 10011
#: Event codes that mean "the arm touched something" (collision detection options too).
COLLISION_CODES = frozenset({ELOG_MOTION_SUPERVISION, 50056})

#: The RAPID module name of the link's exploration moves, and its routine: no ``main`` - a
#: controller's task has a main of its own, and RAPID allows one per task; the link sets the
#: program pointer to this routine instead (RWS "set PP to routine").
MOVE_MODULE = "CellMove"
MOVE_ROUTINE = "cellmove"


@dataclass(frozen=True)
class ElogEntry:
    seqnum: int
    msgtype: int
    code: int
    title: str
    desc: str = ""

    def describe(self) -> str:
        kind = {ELOG_INFO: "info", ELOG_WARNING: "warning", ELOG_ERROR: "error"}.get(
            self.msgtype, str(self.msgtype))
        return f"event {self.code} ({kind}) {self.title}" + (f": {self.desc}" if self.desc else "")


# ---------------------------------------------------------------------- replies (both sides)
def envelope(base: str, states: Sequence[dict[str, Any]], version: int = 1) -> str:
    if version == 2:
        return json.dumps({"_links": {"base": {"href": base}}, "state": list(states)})
    return json.dumps({"_links": {"base": {"href": base}},
                       "_embedded": {"_state": list(states)}})


def error_body(base: str, code: int, msg: str, version: int = 1) -> str:
    status = {"code": int(code), "msg": msg}
    if version == 2:
        return json.dumps({"_links": {"base": {"href": base}}, "status": status})
    return json.dumps({"_links": {"base": {"href": base}},
                       "_embedded": {"_state": [], "status": status}})


def _json(raw: bytes, what: str) -> dict:
    text = raw.decode("utf-8", errors="replace")
    try:
        data = json.loads(text)
    except ValueError:
        raise ProtocolError(f"controller answered {what} with {text[:200]!r}, which is not "
                            "JSON", raw=text) from None
    if not isinstance(data, dict):
        raise ProtocolError(f"controller answered {what} with {text[:200]!r}", raw=text)
    return data


def states(raw: bytes, what: str, type_: str | None = None) -> list[dict[str, Any]]:
    """The state list of a reply (``_embedded._state`` on RWS 1.0, ``state`` on 2.0); each
    of `type_` when given."""
    data = _json(raw, what)
    out = data.get("state") if "state" in data else \
        (data.get("_embedded") or {}).get("_state") if isinstance(data.get("_embedded"),
                                                                  dict) else None
    if out is None:
        raise ProtocolError(f"controller reply to {what} has no state list: "
                            f"{raw[:200]!r}", raw=raw.decode(errors="replace"))
    if not isinstance(out, list) or not all(isinstance(s, dict) for s in out):
        raise ProtocolError(f"controller reply to {what} is malformed: {raw[:200]!r}",
                            raw=raw.decode(errors="replace"))
    if type_ is not None and any(s.get("_type") != type_ for s in out):
        raise ProtocolError(f"controller reply to {what} is not {type_}: {raw[:200]!r}",
                            raw=raw.decode(errors="replace"))
    return out


def state(raw: bytes, what: str, type_: str) -> dict[str, Any]:
    out = states(raw, what, type_)
    if not out:
        raise ProtocolError(f"controller reply to {what} is empty: {raw[:200]!r}",
                            raw=raw.decode(errors="replace"))
    return out[0]


def error_status(raw: bytes) -> tuple[int, str] | None:
    """(code, msg) of an RWS error body, or None when the body is not one."""
    try:
        data = json.loads(raw.decode("utf-8", errors="replace"))
        st = data["status"] if "status" in data else data["_embedded"]["status"]
        return int(st["code"]), str(st.get("msg", ""))
    except (ValueError, KeyError, TypeError):
        return None


def numbers(st: dict[str, Any], keys: Sequence[str], what: str) -> Array:
    try:
        return np.array([float(st[k]) for k in keys])
    except (KeyError, TypeError, ValueError):
        raise ProtocolError(f"{what} lacks numbers {list(keys)}: {st!r}"[:300],
                            raw=json.dumps(st)) from None


# ---------------------------------------------------------------------- targets
RAX = tuple(f"rax_{i}" for i in range(1, 7))
EAX = tuple(f"eax_{c}" for c in "abcdef")


def jointtarget_state(q_rad: Array, mechunit: str = "ROB_1") -> dict[str, str]:
    vals = np.zeros(6)
    vals[:len(q_rad)] = np.degrees(q_rad)
    st = {"_type": "ms-jointtarget", "_title": mechunit}
    st.update({k: f"{v:.6f}" for k, v in zip(RAX, vals, strict=True)})
    st.update({k: NO_AXIS for k in EAX})
    return st


def robtarget_state(T: Array, conf: Sequence[int]) -> dict[str, str]:
    w, x, y, z = quaternion_wxyz(T[:3, :3])
    p = T[:3, 3] * 1000.0
    st = {"_type": "ms-robtargets", "_title": "robtarget",
          "x": f"{p[0]:.4f}", "y": f"{p[1]:.4f}", "z": f"{p[2]:.4f}",
          "q1": f"{w:.8f}", "q2": f"{x:.8f}", "q3": f"{y:.8f}", "q4": f"{z:.8f}"}
    st.update({k: str(int(c)) for k, c in zip(("cf1", "cf4", "cf6", "cfx"), conf, strict=True)})
    st.update({f"eax{c}": NO_AXIS for c in "abcdef"})
    return st


def quaternion_wxyz(R: Array) -> Array:
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    q = np.array([w, x, y, z])
    return -q if q[0] < 0.0 else q


def pose_from(trans_mm: Array, quat_wxyz: Array) -> Array:
    w, x, y, z = (float(v) for v in quat_wxyz)
    n = float(np.linalg.norm([w, x, y, z]))
    if n < 1e-9:
        raise ValueError("zero quaternion")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([x / n, y / n, z / n, w / n]).as_matrix()
    T[:3, 3] = np.asarray(trans_mm, dtype=float) / 1000.0
    return T


def parse_elog(raw: bytes) -> list[ElogEntry]:
    out = []
    for s in states(raw, "/rw/elog/0"):
        try:
            seq = int(str(s["_title"]).rstrip("/").split("/")[-1])
            out.append(ElogEntry(seq, int(s["msgtype"]), int(s["code"]), str(s.get("title", "")),
                                 str(s.get("desc", ""))))
        except (KeyError, TypeError, ValueError):
            raise ProtocolError(f"event log entry is malformed: {s!r}"[:300],
                                raw=json.dumps(s)) from None
    return out


# ---------------------------------------------------------------------- RAPID for moves
def joint_move_module(targets_rad: Array, speed_mm_s: float, name: str = MOVE_MODULE,
                      routine: str = MOVE_ROUTINE) -> str:
    """A module whose routine `routine` moves through joint targets with MoveAbsJ, exact
    stops (fine).

    RAPID speeds are TCP speeds also for MoveAbsJ; we use the exporter's convention that
    1000 mm/s is the arm's full joint speed, so `speed_mm_s` = scale x 1000.
    """
    Q = np.atleast_2d(np.asarray(targets_rad, dtype=float))
    if Q.shape[1] > 6:
        raise ValueError(f"RAPID has 6 robot axes, the path has {Q.shape[1]}")
    v = float(np.clip(speed_mm_s, 0.1, 7000.0))
    lines = [f"MODULE {name}", f"    ! cellteach exploration move: {len(Q)} joint targets",
             f"    CONST speeddata vCellMove := [{v:.1f},500,5000,1000];"]
    for k, q in enumerate(Q, start=1):
        vals = np.zeros(6)
        vals[:len(q)] = np.degrees(q)
        axes = ",".join(f"{a:.6f}" for a in vals)
        lines.append(f"    CONST jointtarget cj{k} := [[{axes}],{EXTERNAL}];")
    lines += ["", f"    PROC {routine}()"]
    lines += [f"        MoveAbsJ cj{k}\\NoEOffs, vCellMove, fine, tool0;"
              for k in range(1, len(Q) + 1)]
    lines += ["    ENDPROC", "ENDMODULE", ""]
    return "\r\n".join(lines)


_MODULE = re.compile(r"^\s*MODULE\s+([A-Za-z][A-Za-z0-9_]*)", re.IGNORECASE | re.MULTILINE)
_MAIN = re.compile(r"^\s*PROC\s+main\s*\(\s*\)", re.IGNORECASE | re.MULTILINE)


def module_name(text: str) -> str | None:
    m = _MODULE.search(text)
    return m.group(1) if m else None


def has_main(text: str) -> bool:
    return _MAIN.search(text) is not None


def main_as_routine(text: str, routine: str) -> str:
    """The module with its ``PROC main()`` renamed to `routine` (a task keeps one main)."""
    out, n = re.subn(r"^(\s*PROC\s+)main(\s*\(\s*\))", rf"\g<1>{routine}\g<2>", text,
                     count=1, flags=re.IGNORECASE | re.MULTILINE)
    if n != 1:
        raise ValueError("no PROC main() in the module")
    return out
