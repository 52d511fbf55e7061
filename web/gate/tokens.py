"""The two access codes (operator, viewer): made with `secrets`, or kept in a token file so the
codes survive a restart. Compared in constant time; never logged. A token file other users may
read or change is refused (whoever reads the operator code can drive the robot; whoever can
write the file can plant their own)."""

from __future__ import annotations

import enum
import hmac
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

MIN_TOKEN_CHARS = 16


class Role(str, enum.Enum):
    OPERATOR = "operator"
    VIEWER = "viewer"


class TokenFileError(ValueError):
    """A token file that cannot be used (one message, says what to do)."""


@dataclass(frozen=True)
class AccessTokens:
    operator: str
    viewer: str

    def __repr__(self) -> str:  # a token must never end up in a log line or a traceback
        return "AccessTokens(<hidden>)"

    @staticmethod
    def new() -> AccessTokens:
        return AccessTokens(secrets.token_urlsafe(24), secrets.token_urlsafe(24))

    def role_of(self, token: str | None) -> Role | None:
        """The role a token opens, or None (both compared, in constant time)."""
        if not token:
            return None
        given = token.encode("utf-8", "replace")
        op = hmac.compare_digest(given, self.operator.encode())
        vw = hmac.compare_digest(given, self.viewer.encode())
        return Role.OPERATOR if op else Role.VIEWER if vw else None

    @staticmethod
    def from_file(path: Path) -> AccessTokens:
        """Read `path` (line 1 the operator token, line 2 the viewer token; '#' comments);
        create it (mode 0600) with new tokens if it does not exist."""
        path = Path(path)
        if not path.exists():
            tokens = AccessTokens.new()
            try:
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                with os.fdopen(fd, "w", encoding="utf-8") as f:
                    f.write("# cellteach access tokens: operator, then viewer\n"
                            f"{tokens.operator}\n{tokens.viewer}\n")
            except OSError as exc:
                raise TokenFileError(f"cannot create the token file {path}: "
                                     f"{exc.strerror or exc}") from None
            return tokens
        _check_private(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise TokenFileError(f"cannot read the token file {path}: {exc}") from None
        lines = [ln.strip() for ln in text.splitlines()
                 if ln.strip() and not ln.strip().startswith("#")]
        if not lines:
            raise TokenFileError(f"the token file {path} holds no token: put the operator "
                                 "token on the first line (or delete the file to get new ones)")
        if len(lines) > 2 or any(len(t) < MIN_TOKEN_CHARS or any(c.isspace() for c in t)
                                 for t in lines):
            raise TokenFileError(
                f"the token file {path} must hold one or two tokens of at least "
                f"{MIN_TOKEN_CHARS} characters without spaces (operator, then viewer), one "
                "per line")
        viewer = lines[1] if len(lines) == 2 else secrets.token_urlsafe(24)
        if viewer == lines[0]:
            raise TokenFileError(f"the token file {path} gives the same token to both roles")
        return AccessTokens(lines[0], viewer)


def _check_private(path: Path) -> None:
    """TokenFileError unless only its owner may read and write `path` (POSIX permissions)."""
    if os.name != "posix":
        return
    try:
        st = os.stat(path)
    except OSError as exc:
        raise TokenFileError(f"cannot read the token file {path}: {exc.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise TokenFileError(f"the token file {path} is not a regular file")
    mode = stat.S_IMODE(st.st_mode)
    if mode & 0o077:
        who = " and ".join(w for w, bits in (("read", 0o044), ("changed", 0o022))
                           if mode & bits)
        raise TokenFileError(
            f"the token file {path} can be {who} by other users (mode {mode:04o}): whoever "
            f"reads the operator code can drive the robot. Run 'chmod 600 {path}' (or delete "
            "the file to get new codes)")
