"""Link passwords live apart from the session: in `secrets.json` beside `session.json`, mode
0600 from the moment it is created, never in `session.json` (which is copied, zipped and
mailed) and never in a message to a page (`masked` is what a page may show).

A secret is any link setting whose name ends in password, secret, token or passphrase
(today the ABB RWS password; a link added later is covered by its field's name alone).
`session.json` files written before this split carry the password in `link`: loading still
reads it there, says so, and the next save moves it out.

Why a file and not the OS keyring: the assistant runs as a service on a cell computer,
usually without a desktop session and its unlocked keyring; a 0600 file in the session folder
goes wherever the session goes, and the operating system's file permissions guard it.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
from pathlib import Path
from typing import Any

from assistant.session.store import SessionFileError, parse_json, write_json_atomic

SECRETS_JSON = "secrets.json"
SECRETS_SCHEMA = 1
_SECRET_NAME = re.compile(r"(password|secret|token|passphrase)$")
#: What a page shows for a stored secret (never its length).
MASK = "\u25cf" * 8


def is_secret(field: str) -> bool:
    return bool(_SECRET_NAME.search(field))


def split(link_json: dict[str, Any], defaults: dict[str, Any]
          ) -> tuple[dict[str, Any], dict[str, str]]:
    """(what session.json may hold, the secrets). A secret left at its default (the
    controller's documented factory password) is no secret and is not written."""
    public = {k: v for k, v in link_json.items() if not is_secret(k)}
    secret = {k: str(v) for k, v in link_json.items()
              if is_secret(k) and v != defaults.get(k)}
    return public, secret


def masked(value: str) -> str:
    """A stored secret as a page shows it: that there is one, not what or how long."""
    return MASK if value else "(none)"


def write(folder: Path, secret: dict[str, str]) -> None:
    """Replace `secrets.json` (0600, fsynced); none left: the file goes."""
    path = folder / SECRETS_JSON
    if not secret:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        return
    write_json_atomic(path, {"schema_version": SECRETS_SCHEMA, "link": secret}, mode=0o600)


def read(folder: Path) -> tuple[dict[str, str], list[str]]:
    """The secrets kept beside a session (empty if none) and notes on what was fixed.

    A file others may write is refused (someone could have put their own password there); one
    others may read is made private again, and said so (the password may be known)."""
    path = folder / SECRETS_JSON
    try:
        st = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return {}, []
    if not stat.S_ISREG(st.st_mode):
        raise SessionFileError(f"{path}: not a regular file")
    notes = []
    if st.st_mode & 0o022:
        raise SessionFileError(
            f"{path}: other users may change it (mode {stat.S_IMODE(st.st_mode):04o}): run "
            f"'chmod 600 {path}' if its passwords are yours, then load again")
    if st.st_mode & 0o044:
        os.chmod(path, 0o600)
        notes.append(f"{path} was readable by other users (mode "
                     f"{stat.S_IMODE(st.st_mode):04o}): it is private now (0600); change "
                     "the link passwords in it if others could log in here")
    if st.st_size > 1 << 20:
        raise SessionFileError(f"{path}: implausibly large")
    doc = parse_json(path.read_bytes(), path)
    link = doc.get("link") if isinstance(doc, dict) else None
    if not isinstance(link, dict) or doc.get("schema_version") != SECRETS_SCHEMA or \
            not all(is_secret(k) and isinstance(v, str) for k, v in link.items()):
        raise SessionFileError(f"{path}: expected {{\"schema_version\": {SECRETS_SCHEMA}, "
                               "\"link\": {\"<name>_password\": \"...\"}}")
    return dict(link), notes
