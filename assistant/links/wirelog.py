"""The record of what a link said to a controller and heard back: commissioning a cell leaves
a file behind that a service engineer can read.

One line per exchange, ``time  link  channel  > or <  text``, in a rotating file
(``links/wire.log`` in the session folder: 1 MB, three old files kept). Secrets never reach
the file: the link's password wherever it appears, HTTP ``Authorization`` headers and
``password=`` fields are replaced by ``***``. Binary packages are written as their type,
length and first bytes in hex; streams at hundreds of hertz (RTDE data, robot state) are
counted, not written, so the log stays readable.
"""

from __future__ import annotations

import itertools
import logging
import logging.handlers
import re
import threading
from collections.abc import Iterable
from pathlib import Path

MAX_BYTES = 1_000_000
BACKUPS = 3
FILE_NAME = "wire.log"
MASK = "***"
_seq = itertools.count()
_AUTH = re.compile(r"(?im)^(authorization|proxy-authorization|cookie|set-cookie):.*$")
_FIELD = re.compile(r"(?i)(password|passwd|pwd)=[^&\s]*")
_BASIC = re.compile(r"(?i)\b(Basic|Digest)\s+[A-Za-z0-9+/=,\"_:.\- ]{8,}")


class WireLog:
    """Writes a link's traffic to `folder/wire.log` (no folder: records nothing)."""

    def __init__(self, folder: Path | str | None, link: str, *, secrets: Iterable[str] = (),
                 max_bytes: int = MAX_BYTES, backups: int = BACKUPS):
        self.link = link
        self.secrets = sorted({s for s in secrets if s}, key=len, reverse=True)
        self.path: Path | None = None
        self._logger: logging.Logger | None = None
        self._counts: dict[str, int] = {}
        self._lock = threading.Lock()
        if folder is None:
            return
        self.path = Path(folder) / FILE_NAME
        self.path.parent.mkdir(parents=True, exist_ok=True)
        logger = logging.getLogger(f"cellteach.wire.{next(_seq)}")
        logger.propagate = False
        logger.setLevel(logging.INFO)
        handler = logging.handlers.RotatingFileHandler(self.path, maxBytes=max_bytes,
                                                       backupCount=backups, encoding="utf-8")
        handler.setFormatter(logging.Formatter("%(asctime)s  %(message)s"))
        logger.addHandler(handler)
        self._logger = logger

    @property
    def enabled(self) -> bool:
        return self._logger is not None

    def mask(self, text: str) -> str:
        for s in self.secrets:
            text = text.replace(s, MASK)
        text = _AUTH.sub(lambda m: f"{m.group(1)}: {MASK}", text)
        text = _FIELD.sub(lambda m: f"{m.group(1)}={MASK}", text)
        return _BASIC.sub(lambda m: f"{m.group(1)} {MASK}", text)

    def _write(self, channel: str, arrow: str, text: str) -> None:
        if self._logger is None:
            return
        one = text.replace("\r", "\\r").replace("\n", "\\n")
        if len(one) > 2000:
            one = one[:2000] + f"... ({len(one)} characters)"
        self._logger.info("%s  %s %s %s", self.link, channel, arrow, self.mask(one))

    def sent(self, channel: str, data: bytes | str) -> None:
        self._write(channel, ">", _text(data))

    def received(self, channel: str, data: bytes | str) -> None:
        self._write(channel, "<", _text(data))

    def note(self, channel: str, text: str) -> None:
        self._write(channel, "-", text)

    def sent_binary(self, channel: str, kind: int, data: bytes) -> None:
        self._write(channel, ">", _binary(kind, data))

    def received_binary(self, channel: str, kind: int, data: bytes) -> None:
        self._write(channel, "<", _binary(kind, data))

    def count(self, channel: str, every: int = 500) -> None:
        """A frequent package: one line per `every` of them."""
        if self._logger is None:
            return
        with self._lock:
            n = self._counts.get(channel, 0) + 1
            self._counts[channel] = n
        if n == 1 or n % every == 0:
            self._write(channel, "<", f"{n} packages so far")

    def close(self) -> None:
        if self._logger is not None:
            for h in list(self._logger.handlers):
                h.close()
                self._logger.removeHandler(h)
            self._logger = None


def _text(data: bytes | str) -> str:
    return data.decode("utf-8", errors="replace") if isinstance(data, bytes) else data


def _binary(kind: int, data: bytes) -> str:
    head = data[:48].hex(" ")
    return f"type {kind}, {len(data)} bytes: {head}{' ...' if len(data) > 48 else ''}"


NULL = WireLog(None, "")
