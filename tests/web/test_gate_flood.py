"""One address floods the front while the operator opens the page: `cellteach serve` runs in
its own process under a real open-files limit of 1024 (soft and hard), another loopback
address holds 1100 idle connections (and opens new ones as the front closes them, up to
3000), and the operator page - sign-in, the viser client, its websocket - loads in real
Chromium. Without the front's per-address cap it does not load at all (the server is out of
files); how fast it loads is the machine's: idle, 2-5 s against the issue's 10 s, but with a
CPU hog beside the test (`stress-ng --cpu 2`) 20 s, the flood's 500 reconnections a second
competing for the same starved cores - so the time is printed, and the test waits for the
page with the generous deadlines of every browser test, never on a time bound."""


from __future__ import annotations

import os
import re
import resource
import select
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from web_ui import CHROMIUM, CHROMIUM_ARGS

pytestmark = [pytest.mark.browser]

ROOT = Path(__file__).resolve().parents[2]
OPEN_FILES = 1024
HELD = 1100
#: The flood re-opens what the front closes, at most this fast and this often in all: it
#: lasts the whole page load (a few seconds), bounded.
MAX_ATTEMPTS = 5000
RATE_PER_S = 500.0
CONNECT_S = 2.0
FLOOD_FROM = "127.0.0.2"
#: The page an operator needs to press Stop: it must load within this deadline while the
#: flood lasts (the issue's figure is 10 s on an idle machine, printed, not asserted).
PAGE_DEADLINE_MS = 90_000
OPERATOR = "operator-code-for-the-flood-test"
VIEWER = "viewer-code-for-the-flood-test"


def _limit_open_files() -> None:  # runs in the server's process before it starts
    resource.setrlimit(resource.RLIMIT_NOFILE, (OPEN_FILES, OPEN_FILES))


class Flood:
    """Holds `HELD` idle connections from one address; replaces those the server closes."""

    def __init__(self, port: int):
        self.port = port
        self.socks: list[socket.socket] = []
        self.attempts = 0
        self.closed_by_server = 0
        self._t0 = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._keep, daemon=True)

    def _open(self) -> None:
        """One connection, completed (a connect that only started would not cost the server
        anything: the flood that locked the page out held finished ones)."""
        s = socket.socket()
        s.bind((FLOOD_FROM, 0))
        s.settimeout(CONNECT_S)
        self.attempts += 1
        try:
            s.connect(("127.0.0.1", self.port))
        except OSError:
            s.close()
            return
        s.setblocking(False)
        self.socks.append(s)

    def start(self) -> None:
        while len(self.socks) < HELD:
            self._open()
        self._t0 = time.monotonic()
        self._thread.start()

    def _keep(self) -> None:
        while not self._stop.is_set():
            poll = select.poll()  # not select(): these descriptors are beyond 1024
            by_fd = {s.fileno(): s for s in self.socks}
            for fd in by_fd:
                poll.register(fd, select.POLLIN | select.POLLHUP | select.POLLERR)
            for fd, _ in poll.poll(50):
                s = by_fd[fd]  # readable and idle: the server closed it
                try:
                    gone = s.recv(1) == b""
                except BlockingIOError:
                    gone = False
                except OSError:
                    gone = True
                if gone:
                    self.closed_by_server += 1
                    self.socks.remove(s)
                    s.close()
            allowed = HELD + (time.monotonic() - self._t0) * RATE_PER_S
            while len(self.socks) < HELD and self.attempts < min(allowed, MAX_ATTEMPTS):
                self._open()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)
        for s in self.socks:
            s.close()


def _load_page(driver, profile: Path, url: str) -> float:
    """Seconds from opening the URL in a fresh browser profile to the signed-in page."""
    ctx = driver.chromium.launch_persistent_context(
        str(profile), executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS,
        viewport={"width": 1400, "height": 950})
    try:
        page = ctx.pages[0] if ctx.pages else ctx.new_page()
        t0 = time.monotonic()
        page.goto(url + "/", timeout=PAGE_DEADLINE_MS)
        page.fill("#code", OPERATOR)
        page.click("button[type=submit]")
        page.get_by_text(re.compile(r"Step \d+(\.\d+)? of 7")).first.wait_for(
            state="visible", timeout=PAGE_DEADLINE_MS)
        return time.monotonic() - t0
    finally:
        ctx.close()


def test_the_operator_page_loads_while_one_address_floods(tmp_path, playwright_driver):
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != resource.RLIM_INFINITY and hard < HELD + 200:
        pytest.skip(f"this process may open only {hard} files: cannot hold {HELD}")
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    tokens = tmp_path / "tokens"
    tokens.write_text(f"{OPERATOR}\n{VIEWER}\n")
    tokens.chmod(0o600)
    proc = subprocess.Popen(
        [sys.executable, "-m", "assistant", "serve", "--cell", "thesis_rv2aj", "--empty",
         "--session", str(tmp_path / "session"), "--port", "0", "--token-file", str(tokens)],
        cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
        preexec_fn=_limit_open_files)
    flood: Flood | None = None
    try:
        assert proc.stderr is not None
        url = None
        for line in proc.stderr:
            m = re.search(r"open (http://127\.0\.0\.1:\d+)/ and enter", line)
            if m:
                url = m.group(1)
                break
        assert url is not None, "cellteach serve did not start"
        with open(f"/proc/{proc.pid}/limits") as f:
            assert re.search(rf"Max open files\s+{OPEN_FILES}\s+{OPEN_FILES}", f.read())
        unflooded = _load_page(playwright_driver, tmp_path / "profile-0", url)
        flood = Flood(int(url.rsplit(":", 1)[1]))
        flood.start()
        took = _load_page(playwright_driver, tmp_path / "profile", url)
        held = len(flood.socks)
        print(f"\nflood: page loaded in {took:.2f} s ({unflooded:.2f} s without the flood) "
              f"under a {OPEN_FILES}-file limit; "
              f"{flood.attempts} connections opened from {FLOOD_FROM}, {held} held open "
              f"from its side, {flood.closed_by_server} closed by the front so far")
        assert flood.attempts >= HELD and proc.poll() is None
        with open(f"/proc/{proc.pid}/status") as f:
            assert proc.poll() is None, f.read()
        fds = len(os.listdir(f"/proc/{proc.pid}/fd"))
        assert fds < OPEN_FILES, fds
    finally:
        if flood is not None:
            flood.stop()
        proc.terminate()
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
