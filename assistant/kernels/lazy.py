"""Compiled kernels that never make the operator wait for a compile.

numba compiles a kernel on its first call and caches the machine code on disk; on a fresh
install all of ours take ~2 minutes of one core. `kernel` wraps `numba.njit` so that this
time is never on the operator's path:

- By default (the tests, library use) a kernel is plain njit: compiled on first call.
- `start()` (the CLI calls it) looks for the cache's completion marker. If the cache is
  complete, nothing changes: each kernel loads from the cache on first call (milliseconds).
  If not, every kernel is *pending* - its calls run its fallback (a numpy form where the
  kernel names one, else its own Python) - and one background process
  (`python -m assistant.warmup.compile`, lowered priority) compiles every kernel into the
  cache and reports each as it lands; a reported kernel switches to its compiled code at
  once. The process finishes by itself even after the command that started it has exited,
  so the next run starts complete.

A pending kernel is the same numba dispatcher object with another class (`_Pending`), so
compiled callers, numba's typing and `.py_func` see no difference, and the switch back
costs nothing per call.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from assistant.kernels.cache import configure

# Before numba's first import: numba reads NUMBA_CACHE_DIR when its config is imported, and
# every kernel of ours is defined through this module (so no import of the package does it).
configure()

from numba import njit  # noqa: E402
from numba.core.registry import CPUDispatcher  # noqa: E402

log = logging.getLogger(__name__)

#: Every kernel defined through `kernel`, by qualified name (module.function).
REGISTRY: dict[str, CPUDispatcher] = {}

_lock = threading.Lock()
_pending_mode = False  # kernels defined from now on start pending
_process: subprocess.Popen | None = None
_follower: threading.Thread | None = None


class _Pending(CPUDispatcher):
    """A kernel whose machine code is not in the cache yet: calls run its fallback."""

    def __call__(self, *args: Any, **kws: Any) -> Any:
        return self._cellteach_fallback(*args, **kws)


def kernel(fn: Callable | None = None, *, fallback: Callable | None = None,
           **options: Any) -> Any:
    """`numba.njit(cache=True, **options)` whose calls run `fallback` (default: the function's
    own Python) while the kernel is pending. A fallback takes the same arguments, writes the
    same outputs in place and returns the same results (within float rounding)."""
    options.setdefault("cache", True)

    def wrap(f: Callable) -> Any:
        disp = njit(**options)(f)
        if not isinstance(disp, CPUDispatcher):  # NUMBA_DISABLE_JIT: the plain function
            return disp
        disp._cellteach_fallback = fallback if fallback is not None else f
        name = qualified_name(f)
        with _lock:
            REGISTRY[name] = disp
            if _pending_mode:
                disp.__class__ = _Pending
        return disp

    return wrap(fn) if fn is not None else wrap


def qualified_name(f: Callable) -> str:
    return f"{f.__module__}.{f.__qualname__}"


def is_pending(disp: Any) -> bool:
    return isinstance(disp, _Pending)


def pending_names() -> list[str]:
    with _lock:
        return sorted(n for n, d in REGISTRY.items() if isinstance(d, _Pending))


def set_pending(pending: bool) -> None:
    """Every kernel (and every one defined later) pending, or every one compiled on call."""
    global _pending_mode
    with _lock:
        _pending_mode = pending
        for disp in REGISTRY.values():
            disp.__class__ = _Pending if pending else CPUDispatcher


def mark_compiled(name: str) -> None:
    """The kernel's machine code is in the cache: its next call loads and runs it."""
    with _lock:
        disp = REGISTRY.get(name)
        if disp is not None:
            disp.__class__ = CPUDispatcher


def cpu_name() -> str:
    """The CPU numba compiles for (its cache entries are per CPU name and features)."""
    from llvmlite import binding
    from numba.core import config

    return config.CPU_NAME or binding.get_host_cpu_name()


def marker_path() -> Path:
    """The file saying every kernel of this source version is in the cache for this CPU."""
    from numba.core import config

    return Path(config.CACHE_DIR) / f"complete-{cpu_name()}"


def write_marker(kernels: int) -> None:
    """Say that every kernel of this source version is in the cache for this CPU."""
    marker = marker_path()
    marker.parent.mkdir(parents=True, exist_ok=True)
    marker.write_text(f"{cpu_name()}\n{kernels} kernels\n", encoding="utf-8")


def cache_complete() -> bool:
    try:
        return marker_path().is_file()
    except OSError:
        return False


def start(steps: str | None = None) -> bool:
    """Make sure no call waits on a compile. Returns True if a background compile started
    (the cache was not complete), False if the cache is complete or a compile already runs.

    `steps` names the warm-up steps the compile process runs ("module:attribute", default
    the product's); tests pass their own."""
    global _process, _follower
    if os.environ.get("NUMBA_DISABLE_JIT", "0") not in ("", "0"):
        return False
    if _process is not None and _process.poll() is None:
        return False
    if cache_complete():
        return False
    set_pending(True)
    env = dict(os.environ)
    if steps:
        env["CELLTEACH_WARM_STEPS"] = steps
    from numba.core import config

    env["NUMBA_CACHE_DIR"] = str(config.CACHE_DIR)
    try:
        _process = subprocess.Popen(
            [sys.executable, "-m", "assistant.warmup.compile"], env=env,
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL,
            text=True, start_new_session=True)
    except OSError as exc:  # no compile process: compile on call, as plain njit
        log.warning("cannot start the kernel compile process (%s); compiling on use", exc)
        set_pending(False)
        return False
    _follower = threading.Thread(target=_follow, args=(_process,),
                                 name="kernel-compile-follow", daemon=True)
    _follower.start()
    return True


def _follow(proc: subprocess.Popen) -> None:
    """Switch kernels to compiled code as the compile process reports them."""
    assert proc.stdout is not None
    for line in proc.stdout:
        word, _, name = line.strip().partition(" ")
        if word == "ready":
            mark_compiled(name)
    code = proc.wait()
    if code != 0:
        log.warning("the kernel compile process ended with %s; compiling on use", code)
    set_pending(False)


def wait(timeout: float | None = None) -> bool:
    """Wait for a running compile process and the switch of its kernels; True when none
    runs any more."""
    proc, follower = _process, _follower
    if proc is None or follower is None:
        return True
    follower.join(timeout)
    return not follower.is_alive()
