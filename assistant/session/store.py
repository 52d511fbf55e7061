"""The session folder: `session.json` (schema-versioned JSON) beside the cell folder `cell/`.

Written after every accepted action. Each file is replaced atomically (temporary name, fsync,
rename), the cell first and `session.json` last, so a crash or kill at any moment leaves a
folder that loads: at worst without the action that was in flight. Loading never unpickles
or evaluates anything; unknown versions and malformed content fail with `SessionFileError`.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
from pathlib import Path
from typing import Any

SESSION_SCHEMA = 1
SESSION_JSON = "session.json"
CELL_DIR = "cell"
MAX_SESSION_BYTES = 256 * 1024 * 1024


class SessionFileError(ValueError):
    """A session folder that cannot be loaded; names the file and the problem."""


#: The keys of `session.json` and the JSON types each may hold (None: may be null).
SESSION_KEYS: dict[str, tuple[type | None, ...]] = {
    "schema_version": (int,), "saved_at": (int, float), "machine": (dict,),
    "locations": (list,), "mission": (dict,), "link": (dict,), "hidden_obstacles": (list,),
    "pointer": (dict,), "counters": (dict,), "recorded_collisions": (list,),
    "robot_joints": (list, None), "trajectory": (dict, None), "plan_report": (dict, None),
    "export_dialect": (str,), "sample": (str, None),
    "world_settings": (dict,),
}
_TYPE_WORDS = {int: "a number", float: "a number", dict: "an object", list: "a list",
               str: "a string", None: "null"}


def check_session_keys(doc: dict[str, Any], path: Path) -> list[str]:
    """Refuse a key of the wrong JSON type (naming it and what it should be); return one
    sentence per unknown key (a newer version's, or a typo), which loading ignores."""
    for key, types in SESSION_KEYS.items():
        if key not in doc:
            continue
        value = doc[key]
        ok = any((value is None) if t is None else
                 (isinstance(value, t) and not isinstance(value, bool)) for t in types)
        if not ok:
            want = " or ".join(dict.fromkeys(_TYPE_WORDS[t] for t in types))
            raise SessionFileError(f"{path}: {key!r} should be {want}, not "
                                   f"{type(value).__name__} {json.dumps(value)[:40]}")
    return [f"{path}: unknown key {key!r} ignored" for key in doc if key not in SESSION_KEYS]


def write_json_atomic(path: Path, doc: dict[str, Any]) -> None:
    data = json.dumps(doc, indent=1, allow_nan=False).encode("utf-8")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def read_session_json(folder: Path) -> dict[str, Any]:
    if folder.is_file():
        what = "a zip file" if folder.suffix.lower() == ".zip" else "a file"
        raise SessionFileError(
            f"{folder} is {what}, not a session folder: a session is a folder holding "
            f"{SESSION_JSON} and {CELL_DIR}/ (unpack a zip into a folder and give that)")
    path = folder / SESSION_JSON
    if not path.is_file():
        raise SessionFileError(f"{folder}: no {SESSION_JSON} here - is this a session folder?")
    if path.stat().st_size > MAX_SESSION_BYTES:
        raise SessionFileError(f"{path}: file is implausibly large")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"),
                         parse_constant=_reject_constant)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SessionFileError(f"{path}: not valid JSON ({exc})") from None
    except ValueError as exc:
        raise SessionFileError(f"{path}: {exc}") from None
    if not isinstance(doc, dict):
        raise SessionFileError(f"{path}: expected a JSON object at the top")
    version = doc.get("schema_version")
    if version != SESSION_SCHEMA:
        raise SessionFileError(
            f"{path}: schema version {version!r} is not supported (this cellteach reads "
            f"version {SESSION_SCHEMA}); was it written by another version?")
    return doc


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not allowed in a session file")
