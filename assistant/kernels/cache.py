"""Where numba caches the compiled kernels: one folder per version of the kernels' sources.

Why: numba invalidates a cached function when its own file changes, but not when a kernel
it calls changes in another file (a documented limit of its cache). After an update the
stale machine code would keep the old callee's behaviour, or call it with an old layout -
and compiled code that goes wrong crashes the process rather than raising. Keying the
folder by a hash of every kernel module's source makes any change recompile all kernels
once (in the background: `lazy.start`), and never mixes versions.

The folder is `$CELLTEACH_CACHE/numba/<hash>` (default `~/.cache/cellteach`), unless
`NUMBA_CACHE_DIR` is set, which always wins (the tests use it for an empty cache).
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent.parent  # the assistant package


def kernel_source_hash(package: Path = _PACKAGE) -> str:
    """Hash of every module of the package that defines numba kernels (path and text):
    those that use `kernel` (or numba's njit directly)."""
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        text = path.read_bytes()
        if b"@kernel" in text or b"njit" in text:
            h.update(path.relative_to(package).as_posix().encode())
            h.update(text)
    return h.hexdigest()[:16]


def kernel_cache_dir(root: Path | None = None) -> Path:
    """The cache folder for the kernels of this source version."""
    if root is None:
        env = os.environ.get("CELLTEACH_CACHE")
        root = Path(env) if env else Path.home() / ".cache" / "cellteach"
    return root / "numba" / kernel_source_hash()


def configure() -> None:
    """Point numba's cache at `kernel_cache_dir` unless NUMBA_CACHE_DIR is set; before any
    kernel is defined (numba reads the setting when a cached function is created)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    try:
        folder = kernel_cache_dir()
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK):
            return
    except OSError:
        return  # no writable cache home: numba's own default (next to the sources)
    path = str(folder)
    os.environ["NUMBA_CACHE_DIR"] = path
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba already imported: its setting was read from the env
        config.CACHE_DIR = path
