"""Reading files we did not write without letting them take the process: the rule, once.

Every reader of operator-supplied files goes through here - CAD uploads and paths, a
script's `import_cad`, URDF text and its meshes, saved cells and their zips:

- **Regular files only.** Devices (`/dev/zero`), named pipes, sockets and folders are refused
  by what they are before a byte is read; a FIFO is opened without blocking, so naming one
  cannot hang the session either.
- **A size cap before reading**, and reading stops at the cap plus one byte whatever the file
  claimed (files under /proc say 0 bytes).
- **Archives are judged by their directory before anything is inflated**: the number of
  members, the total expanded size and each member's expansion ratio. Python's zipfile never
  inflates a member past its declared size (it fails the CRC check instead), so a directory
  that passes bounds the memory an archive can take.
- **Nesting depth is bounded**: JSON's is measured on the raw bytes before parsing (the
  parser recurses); XML goes through a parser without entities, DTDs, network access or
  libxml2's huge-tree mode, which refuses documents nested deeper than `XML_MAX_DEPTH`.

What breaks a rule raises `FileRefused` (a ValueError) saying what the file is and what to
do; each reader wraps it in its own error so the operator sees the file's name.
Imports only the standard library and numpy (lxml when an XML parser is asked for).
"""

from __future__ import annotations

import json
import os
import re
import stat
import zipfile
from collections.abc import Iterable
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np

#: An archive member expanding more than this many times its compressed size is a bomb
#: (ordinary CAD XML and JSON compress 5-20 times; generated meshes up to ~100).
MAX_EXPANSION_RATIO = 200
#: ... judged only for members expanding to more than this (tiny members may compress a lot).
RATIO_FLOOR_BYTES = 1024 * 1024
#: More members than this is not a cell or a 3MF; the directory alone would cost memory.
MAX_ARCHIVE_MEMBERS = 10_000
#: JSON nested deeper than this is refused before parsing (glTF and cell files need < 10).
JSON_MAX_DEPTH = 64
#: libxml2's own depth limit without XML_PARSE_HUGE (lxml's `huge_tree=False`).
XML_MAX_DEPTH = 256

_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISDIR, "a folder"))


class FileRefused(ValueError):
    """A file that is not read: what it is (or would become) and what to do instead."""

    def __init__(self, problem: str, advice: str = ""):
        self.problem = problem
        self.advice = advice
        super().__init__(f"{problem} — {advice}" if advice else problem)


def _mib(n: int) -> str:
    return f"{n / 2**20:,.0f} MiB" if n >= 2**20 else f"{n:,} bytes"


def read_file(path: str | Path, *, limit: int, what: str = "file") -> bytes:
    """The bytes of a regular file of at most `limit` bytes.

    Raises:
        FileRefused: missing or unreadable, not a regular file (device, FIFO, socket,
            folder), or larger than `limit` (by its size, or by what it yields when read).
    """
    name = os.fspath(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(name, flags)
    except OSError as exc:
        raise FileRefused(f"{name}: cannot be opened ({exc.strerror})",
                          "check the path and that the file is readable") from None
    try:
        st = os.fstat(fd)
        for test, kind in _KINDS:
            if test(st.st_mode):
                raise FileRefused(f"{name} is {kind}, not a {what}",
                                  f"give the path of the {what} itself")
        if not stat.S_ISREG(st.st_mode):
            raise FileRefused(f"{name} is not a regular file", f"give a {what} on disk")
        if st.st_size > limit:
            raise FileRefused(f"{name} is {_mib(st.st_size)}, more than the {_mib(limit)} a "
                              f"{what} may be", "simplify or split it")
        # One buffer: a buffered read of n bytes fills one object (untouched pages of a
        # short file are never resident), instead of blocks joined into a second copy.
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(limit + 1)
    finally:
        os.close(fd)
    if len(data) > limit:
        raise FileRefused(f"{name} yields more than the {_mib(limit)} a {what} may be",
                          "give an ordinary file")
    return data


def check_archive(infos: Iterable[zipfile.ZipInfo], *, what: str, max_total: int,
                  max_ratio: float = MAX_EXPANSION_RATIO,
                  max_members: int = MAX_ARCHIVE_MEMBERS) -> list[zipfile.ZipInfo]:
    """Judge a zip by its directory before inflating anything (see the module doc).

    Returns the members; raises `FileRefused` naming the member that breaks a rule."""
    members, total = [], 0
    for info in infos:
        members.append(info)
        if len(members) > max_members:
            raise FileRefused(f"the {what} holds more than {max_members:,} members",
                              "it is not an archive this program writes or reads")
        total += info.file_size
        if info.file_size > RATIO_FLOOR_BYTES and \
                info.file_size > max_ratio * max(info.compress_size, 1):
            raise FileRefused(
                f"member {info.filename!r} of the {what} would expand from "
                f"{_mib(info.compress_size)} to {_mib(info.file_size)} (more than "
                f"{max_ratio:g} times: a zip bomb?)", "it was not inflated; export it again")
        if total > max_total:
            raise FileRefused(f"the {what} would expand to more than {_mib(max_total)}",
                              "it was not inflated; export a smaller file")
    return members


def open_zip(data: bytes, *, what: str, max_total: int,
             max_ratio: float = MAX_EXPANSION_RATIO) -> zipfile.ZipFile:
    """A zip held in memory, its directory checked by `check_archive`."""
    try:
        zf = zipfile.ZipFile(BytesIO(data))
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise FileRefused(f"the {what} is not a valid zip archive ({exc})",
                          "export it again") from None
    try:
        check_archive(zf.infolist(), what=what, max_total=max_total, max_ratio=max_ratio)
    except FileRefused:
        zf.close()
        raise
    return zf


_JSON_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"', re.S)


def json_depth(data: bytes) -> int:
    """How deeply the arrays and objects of a JSON text nest (strings skipped), in linear
    time and without recursion."""
    skeleton = np.frombuffer(_JSON_STRING.sub(b'""', data), dtype=np.uint8)
    opens = (skeleton == ord("[")) | (skeleton == ord("{"))
    brackets = opens | (skeleton == ord("]")) | (skeleton == ord("}"))
    step = np.where(opens[brackets], 1, -1).astype(np.int32)
    return int(max(0, np.cumsum(step).max())) if len(step) else 0


def load_json(data: bytes, *, what: str, limit: int,
              max_depth: int = JSON_MAX_DEPTH) -> Any:
    """Parse JSON of at most `limit` bytes nested at most `max_depth` deep; NaN/Infinity are
    refused. Raises `FileRefused` with the reason."""
    if len(data) > limit:
        raise FileRefused(f"the {what} is {_mib(len(data))}, more than the {_mib(limit)} "
                          "allowed", "it is not a file this program reads")
    depth = json_depth(data)
    if depth > max_depth:
        raise FileRefused(f"the {what} nests {depth} levels deep, more than the {max_depth} "
                          "allowed", "it is not a file this program reads")

    def constant(name: str) -> float:
        raise ValueError(f"{name} is not a number")

    try:
        return json.loads(data.decode("utf-8"), parse_constant=constant)
    except (UnicodeDecodeError, ValueError) as exc:
        raise FileRefused(f"the {what} is not valid JSON ({exc})", "export it again") from None


def xml_parser() -> Any:
    """An lxml parser for untrusted XML: no entity expansion, DTD loading or network access,
    and no huge-tree mode (libxml2 then refuses nesting beyond `XML_MAX_DEPTH` and text
    nodes beyond 10 MB)."""
    from lxml import etree

    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                           huge_tree=False, dtd_validation=False)
