"""The session folder: `session.json` (schema-versioned JSON) beside the cell folder `cell/`.

Written after every accepted action. Each file is replaced atomically (temporary name, fsync,
rename, fsync of the folder so the rename itself is on disk), the cell first and
`session.json` last, so a crash or kill at any moment leaves a folder that loads: at worst
without the action that was in flight. Link passwords are kept out of it (`link_secrets.py`).

Loading never unpickles or evaluates anything. The JSON is bounded before anything reads it:
at most `MAX_SESSION_BYTES`, nested at most `MAX_DEPTH` deep (a deeper file would exhaust
the parser's recursion), no NaN or infinity (`1e999` included), no integer beyond 18 digits;
`load_checks.py` then range-checks every field. Unknown versions and malformed content fail
with `SessionFileError`, one sentence naming the file and the field.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
from collections.abc import Iterable
from pathlib import Path
from typing import Any

SESSION_SCHEMA = 1
SESSION_JSON = "session.json"
CELL_DIR = "cell"
MAX_SESSION_BYTES = 256 * 1024 * 1024
#: A session file is at most ~8 levels deep (mission > paths > segments > points); 32 is
#: generous and far below the parser's recursion limit.
MAX_DEPTH = 32
#: Integers the session holds are counts and seeds: 18 digits fit an int64.
MAX_INT_DIGITS = 18


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
_TYPE_WORDS: dict[type | None, str] = {
    int: "a number", float: "a number", dict: "an object", list: "a list", str: "a string",
    None: "null"}


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


def write_json_atomic(path: Path, doc: dict[str, Any], *, mode: int = 0o644) -> None:
    """Replace `path` with `doc` so that a crash leaves either the old or the new file, and
    the new one is on disk when this returns (file and folder fsynced). `mode`: the new
    file's permissions from its creation on (0600 for secrets: never readable by others,
    not even for a moment)."""
    write_bytes_atomic(path, json.dumps(doc, indent=1, allow_nan=False).encode("utf-8"),
                       mode=mode)


def write_bytes_atomic(path: Path, data: bytes, *, mode: int = 0o644) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)  # the umask may have taken bits away (0644 -> 0600 is fine too)
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    fsync_folder(path.parent)


def fsync_folder(folder: Path) -> None:
    """Make the names in `folder` (a rename, a new file) durable. Some file systems cannot
    fsync a folder (EINVAL): there the rename is as durable as the OS makes it."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


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
    doc = parse_json(path.read_bytes(), path)
    if not isinstance(doc, dict):
        raise SessionFileError(f"{path}: expected a JSON object at the top")
    version = doc.get("schema_version")
    if version != SESSION_SCHEMA:
        raise SessionFileError(
            f"{path}: schema version {version!r} is not supported (this cellteach reads "
            f"version {SESSION_SCHEMA}); was it written by another version?")
    return doc


def parse_json(data: bytes, path: Path) -> Any:
    """The JSON in `data`, bounded as the module says; SessionFileError names what is wrong."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SessionFileError(f"{path}: not valid JSON (not UTF-8 text: {exc.reason})"
                               ) from None
    too_deep = SessionFileError(f"{path}: nested deeper than {MAX_DEPTH} levels: not a file "
                                "cellteach wrote")
    try:
        doc = json.loads(text, parse_constant=_reject_constant, parse_float=_finite_float,
                         parse_int=_bounded_int)
    except RecursionError:
        raise too_deep from None
    except json.JSONDecodeError as exc:
        raise SessionFileError(f"{path}: not valid JSON ({exc})") from None
    except ValueError as exc:
        raise SessionFileError(f"{path}: {exc}") from None
    if json_depth(doc) > MAX_DEPTH:
        raise too_deep
    return doc


def json_depth(doc: Any) -> int:
    """How deeply lists and objects nest in `doc` (iteratively: no recursion to exhaust)."""
    deepest, stack = 0, [(doc, 1)]
    while stack:
        node, depth = stack.pop()
        children: Iterable[Any]
        if isinstance(node, dict):
            children = node.values()
        elif isinstance(node, list):
            children = node
        else:
            continue
        deepest = max(deepest, depth)
        if depth > MAX_DEPTH:
            return depth
        stack.extend((c, depth + 1) for c in children)
    return deepest


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not allowed in a session file")


def _finite_float(text: str) -> float:
    v = float(text)
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError(f"the number {text[:30]} is beyond floating-point range")
    return v


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise ValueError(f"the integer {text[:30]}... has more than {MAX_INT_DIGITS} digits")
    return int(text)
