"""How an emulator run as a script waits: until Ctrl-C or SIGTERM, then it shuts down cleanly.

Both signals get a handler of their own. A process started in the background of a
non-interactive shell (a CI script's `... &`, `nohup`) inherits SIGINT *ignored*; Python
then never raises KeyboardInterrupt, and the emulator could only be killed - so a test
that stops it with Ctrl-C would fail whenever the test run itself is started that way.
"""

from __future__ import annotations

import signal
import time


def wait_until_stopped() -> None:
    """Block until SIGINT or SIGTERM arrives (the caller's `with` block then closes)."""
    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
