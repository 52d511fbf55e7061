"""Hold-to-run over the network, in the real page: the arm moves only while the page that holds
motion authority is there and answers.

- The holder's tab closes mid-move: the robot's pose updates stop within 300 ms; the other
  operator page's Collision! and Stop start nothing; it moves the robot only after taking
  authority.
- The holder's page stalls (its process frozen with SIGSTOP, as a laptop that sleeps or a
  network that drops without a goodbye): the heartbeat finds it silent and the robot stops;
  when it answers again nothing starts by itself.

The same stop on the UR and MELFA emulators: tests/links/test_links_motion_hold.py.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from web_ui import UI

from assistant.links.settings import LinkSettings
from assistant.session import Session
from assistant.session.events import RobotMoved
from web.heartbeat import PING_S, SILENT_S
from workflow.machine import Mode

pytestmark = pytest.mark.browser

#: The issue's figure: the arm stands this soon after the server knows the holder went.
STOP_S = 0.3
#: How soon the browser and the OS tell the server that a tab closed: ~0.1 s idle, ~0.3 s
#: with the two cores loaded 3.5x (measured); the bound leaves room for a busier machine.
TAB_GONE_S = 2.0
#: A silent page is known SILENT_S after its last answer, one ping period to notice - on an
#: idle machine. The server restarts that clock when its own loop ran late (a stalled server
#: is not a silent page, `web.heartbeat`), so under load it is known later: the bound leaves
#: room for a busy machine, and the 0.3 s stop is measured from when the server knew.
SILENT_KNOWN_S = 3.0


class PoseClock:
    """The monotonic time of every robot pose update the session publishes."""

    def __init__(self, session: Session):
        self.times: list[float] = []
        session.bus.subscribe(self._on)

    def _on(self, ev: object) -> None:
        if isinstance(ev, RobotMoved):
            self.times.append(time.monotonic())

    def wait_moving(self, n: int = 5, deadline_s: float = 60.0) -> None:
        start, end = len(self.times), time.monotonic() + deadline_s
        while len(self.times) < start + n:
            assert time.monotonic() < end, "the robot never moved"
            time.sleep(0.01)

    def after(self, t0: float) -> float:
        """Seconds from t0 to the last pose update (0 if none came after t0)."""
        return max(0.0, max(self.times, default=t0) - t0)


def _wait_mode_not_moving(session: Session) -> None:
    end = time.monotonic() + 30
    while session.machine.mode == Mode.MOVING:
        assert time.monotonic() < end, "the session still says moving"
        time.sleep(0.01)


def _slow_robot() -> Session:
    session = Session()
    session.set_link(LinkSettings(time_scale=0.05))  # a long move: ~15 s for J1 to 120 deg
    return session


def test_the_arm_stops_when_the_holders_page_closes(serve_session, open_ui):
    session = _slow_robot()
    app = serve_session(session)
    a: UI = open_ui(app.url, "holder")
    a.wait_text("You hold motion authority")
    b: UI = open_ui(app.url, "other")
    b.wait_text("holds motion authority")
    poses = PoseClock(session)
    gone: list[float] = []  # when the server knew (its listeners hear it after the stop)
    session.hold.subscribe(lambda st: gone.append(time.monotonic()) if st.holder is None
                           else None)
    a.expand("Jog the robot", a.button("Move to the slider values"))
    a.fill("J1 (deg)", 120.0)
    a.click("Move to the slider values")
    poses.wait_moving()
    t0 = time.monotonic()
    a.page.close()  # the holder's tab goes mid-move
    _wait_mode_not_moving(session)
    b.wait_text("Nobody holds motion authority")
    b.page.wait_for_timeout(1000)  # watch: no pose update may come late
    assert gone
    print(f"the server knew the holder's tab closed after {(gone[0] - t0) * 1000:.0f} ms; "
          f"pose updates stopped {poses.after(t0) * 1000:.0f} ms after the close")
    assert gone[0] - t0 <= TAB_GONE_S
    assert poses.after(gone[0]) <= STOP_S
    # The other operator's Collision! and Stop record and stop - they never start the arm.
    n = len(poses.times)
    b.page.keyboard.press("Space")
    b.page.keyboard.press("Escape")
    b.page.wait_for_timeout(1500)  # watch (an absence: a busy machine only makes it weaker)
    assert len(poses.times) == n
    # Moving needs authority: refused with the way to get it, then allowed once taken.
    b.expand("Jog the robot", b.button("Move to the slider values"))
    b.fill("J1 (deg)", 60.0)
    b.click("Move to the slider values")
    b.wait_text("Nobody holds motion authority: take it")
    assert len(poses.times) == n
    b.click("Take motion authority")
    b.wait_text("You hold motion authority")
    b.click("Move to the slider values")
    poses.wait_moving(n=3)


#: A page in its own process (so it can be frozen): connects as viser's client does (the
#: camera first) and reads everything; the websockets library answers pings as a browser does.
CLIENT = """
import asyncio, sys, websockets
async def main():
    async with websockets.connect(sys.argv[1], subprotocols=[sys.argv[2]],
                                  max_size=None) as ws:
        await ws.send(bytes.fromhex(sys.argv[3]))
        print("connected", flush=True)
        async for _ in ws:
            pass
asyncio.run(main())
"""


def test_a_silent_holder_page_stops_the_arm_and_nothing_starts_when_it_answers(
        serve_session, tmp_path):
    from gate_helpers import CAMERA, VISER_PROTOCOL, encode

    session = _slow_robot()
    app = serve_session(session)
    script = tmp_path / "page.py"
    script.write_text(CLIENT)
    page = subprocess.Popen([sys.executable, str(script), app.url.replace("http", "ws"),
                             VISER_PROTOCOL, encode(CAMERA).hex()],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert page.stdout is not None and page.stdout.readline().strip() == "connected"
        end = time.monotonic() + 30
        while session.hold.state.holder is None:
            assert time.monotonic() < end, "the page never became the holder"
            time.sleep(0.01)
        holder = session.hold.state.holder
        poses = PoseClock(session)
        silent: list[float] = []  # when the server knew the page was silent
        session.hold.subscribe(lambda st: silent.append(time.monotonic())
                               if st.holder is not None and not st.present else None)
        q = session.current_joints().copy()
        q[0] += 2.0
        with session.hold.acting(holder):  # the holder's click, as `web.actions` runs it
            session.jog_joints(q, wait=False)
        poses.wait_moving()
        t0 = time.monotonic()
        os.kill(page.pid, signal.SIGSTOP)  # the page freezes: no goodbye, no answer
        _wait_mode_not_moving(session)
        time.sleep(1.0)  # watch: no pose update may come late
        assert silent, "the server never counted the frozen page as silent"
        print(f"the server knew the page was silent after {(silent[0] - t0) * 1000:.0f} ms "
              f"(idle: {(SILENT_S + PING_S) * 1000:.0f} ms); pose updates stopped "
              f"{poses.after(t0) * 1000:.0f} ms after the freeze")
        assert silent[0] - t0 <= SILENT_KNOWN_S
        assert poses.after(silent[0]) <= STOP_S
        assert session.hold.state.holder == holder and not session.hold.state.present
        n = len(poses.times)
        os.kill(page.pid, signal.SIGCONT)  # it answers again ...
        end = time.monotonic() + 30
        while not session.hold.state.present:
            assert time.monotonic() < end, "the page never counted as answering again"
            time.sleep(0.01)
        time.sleep(1.0)  # watch (an absence: nothing may start by itself once it answers)
        assert len(poses.times) == n  # ... and nothing started by itself
    finally:
        os.kill(page.pid, signal.SIGCONT)
        page.kill()
        page.wait(10)
        if page.stdout is not None:
            page.stdout.close()
