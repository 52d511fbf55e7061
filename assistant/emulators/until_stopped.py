"""How an emulator run as a script waits: until Ctrl-C or SIGTERM, then it shuts down cleanly.

Both signals get a handler of their own. A process started in the background of a
non-interactive shell (a CI script's `... &`, `nohup`) inherits SIGINT *ignored*; Python
then never raises KeyboardInterrupt, and the emulator could only be killed - so a test
that stops it with Ctrl-C would fail whenever the test run itself is started that way.
"""

from __future__ import annotations

import signal
import threading

_stop = threading.Event()


def install_stop_handlers() -> None:
    """Take SIGINT and SIGTERM from here on: call it before the line that says the emulator is
    ready, so a Ctrl-C right after that line is a clean stop, not an interrupted start. The
    handlers only note the request (nothing is raised in the middle of the caller's work)."""
    def stop(signum: int, frame: object) -> None:
        _stop.set()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)


def wait_until_stopped() -> None:
    """Block until SIGINT or SIGTERM arrives (the caller's `with` block then closes)."""
    install_stop_handlers()  # idempotent: for a caller that did not install them first
    while not _stop.wait(0.2):
        pass
