"""Bounds at the front: failed token attempts per address, uploads in flight."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass
class FailureLimiter:
    """After `max_failures` wrong tokens within `window_s` an address is refused for `block_s`
    (HTTP 429), whatever it sends. Memory is bounded by `max_addresses`."""

    max_failures: int = 10
    window_s: float = 60.0
    block_s: float = 300.0
    max_addresses: int = 10_000
    clock: Callable[[], float] = time.monotonic
    _fails: dict[str, deque[float]] = field(default_factory=dict, init=False)
    _blocked_until: dict[str, float] = field(default_factory=dict, init=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, init=False)

    def retry_after(self, addr: str) -> float:
        """Seconds until `addr` may try again (0: not blocked)."""
        with self._lock:
            until = self._blocked_until.get(addr)
            if until is None:
                return 0.0
            left = until - self.clock()
            if left <= 0:
                del self._blocked_until[addr]
                return 0.0
            return left

    def failed(self, addr: str) -> bool:
        """Count one wrong token from `addr`; True if that blocks it."""
        now = self.clock()
        with self._lock:
            q = self._fails.get(addr)
            if q is None:
                if len(self._fails) >= self.max_addresses:
                    self._fails.pop(next(iter(self._fails)))  # the oldest address
                q = self._fails[addr] = deque()
            q.append(now)
            while q and q[0] < now - self.window_s:
                q.popleft()
            if len(q) >= self.max_failures:
                self._blocked_until[addr] = now + self.block_s
                del self._fails[addr]
                return True
            return False


@dataclass
class UploadSlots:
    """Uploads in flight over the whole front (each connection has its own smaller bound)."""

    total: int = 4
    _used: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, init=False)

    def take(self) -> bool:
        with self._lock:
            if self._used >= self.total:
                return False
            self._used += 1
            return True

    def give(self, n: int = 1) -> None:
        with self._lock:
            self._used = max(0, self._used - n)

    @property
    def used(self) -> int:
        return self._used
