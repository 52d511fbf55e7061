"""Faults an emulator can be told to produce (drop mid-move, answer late, garble), and its log.

Tests arm a fault, run the real client, and check the client's reaction. The object is shared
between the emulator's threads and the test thread, so every access takes its lock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field


@dataclass
class Received:
    """One request an emulator received: channel/endpoint, monotonic wall time, text."""

    channel: str
    t: float
    text: str


GARBAGE = "#?%GARBLED\x15REPLY%?#"


@dataclass
class Faults:
    """What to break next. All fields may be changed at any time from any thread."""

    #: Once the arm has moved this many robot seconds since arming, drop every connection
    #: and halt the arm (a cable pulled mid-move). None: never.
    drop_after_moving_s: float | None = None
    #: Wall seconds to wait before every reply (command, data link, HTTP).
    reply_delay_s: float = 0.0
    #: The next this-many replies are replaced by `garbage_text`.
    garbage_replies: int = 0
    garbage_text: str = GARBAGE
    #: Count of drops performed (tests read it to know the fault fired).
    drops: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def drop_mid_move(self, after_moving_s: float = 0.05) -> None:
        with self._lock:
            self.drop_after_moving_s = after_moving_s

    def delay_replies(self, seconds: float) -> None:
        with self._lock:
            self.reply_delay_s = float(seconds)

    def garble_next(self, n: int = 1, text: str = GARBAGE) -> None:
        with self._lock:
            self.garbage_replies = int(n)
            self.garbage_text = text

    def clear(self) -> None:
        with self._lock:
            self.drop_after_moving_s = None
            self.reply_delay_s = 0.0
            self.garbage_replies = 0

    # ------------------------------------------------------------------ used by emulators
    def take_reply(self, text: str) -> tuple[str, float]:
        """The reply to actually send (maybe garbled) and the delay before sending it."""
        with self._lock:
            delay = self.reply_delay_s
            if self.garbage_replies > 0:
                self.garbage_replies -= 1
                return self.garbage_text, delay
            return text, delay

    def should_drop(self, moved_s: float) -> bool:
        """True once (then disarmed) when the arm has moved long enough since arming."""
        with self._lock:
            if self.drop_after_moving_s is not None and moved_s >= self.drop_after_moving_s:
                self.drop_after_moving_s = None
                self.drops += 1
                return True
            return False

    @property
    def drop_armed(self) -> bool:
        with self._lock:
            return self.drop_after_moving_s is not None
