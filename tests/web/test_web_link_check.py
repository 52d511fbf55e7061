"""Step 1's "Test connection" in the real page (headless Chromium): the checklist of the
chosen link, one line per item, against a UR emulator as shipped (Local control: the line
says what to switch on the pendant), then after the switch (all checks pass)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "links"))

from ur_fixtures import start_emulator  # noqa: E402

from assistant.links.settings import LinkSettings  # noqa: E402
from assistant.robots.catalog import RobotSpec, installed_robot_urdf  # noqa: E402
from assistant.session import Session  # noqa: E402

pytestmark = pytest.mark.browser


def test_test_connection_shows_the_checklist(serve_session, open_ui, tmp_path):
    emulators: list = []
    try:
        _run(serve_session, open_ui, tmp_path, emulators)
    finally:
        for emu in emulators:
            emu.close()


def _run(serve_session, open_ui, tmp_path, emulators) -> None:  # noqa: ANN001
    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    session = Session(folder=tmp_path / "session")
    session.choose_robot(RobotSpec(kind="urdf", urdf_path=str(urdf), package_dirs=(str(share),),
                                   tool_link="tool0"))
    emu = start_emulator(session.robot, lambda e: emulators.append(e) or e,
                         local_mode=None)  # as shipped: Local
    session.set_link(LinkSettings(kind="ur", host=emu.host, ur_script_port=emu.script_port,
                                  ur_rtde_port=emu.rtde_port,
                                  ur_dashboard_port=emu.dashboard_port,
                                  ur_primary_port=emu.primary_port))
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("1")
    ui.click("Test connection")
    ui.wait_text("Connection test: some checks failed")
    ui.wait_text("[FAIL] remote control: the robot is in Local control", timeout=30_000)
    ui.page.get_by_text("[FAIL] remote control").first.scroll_into_view_if_needed()
    shot = ui.shot("link-check-local")
    emu.set_remote_control(True)  # the operator's toggle on the pendant
    ui.click("Test connection")
    try:
        ui.wait_text("Connection test: all checks passed")
    except Exception as exc:  # name the item that failed (a screenshot may cut it off)
        items = [ln for ln in ui.page.inner_text("body").splitlines() if "[" in ln]
        raise AssertionError(f"the second check did not pass: {items}") from exc
    ui.wait_text("[ok  ] calibration: calibrated UR5")
    ui.page.get_by_text("[ok  ] calibration").first.scroll_into_view_if_needed()
    shot2 = ui.shot("link-check-remote")
    assert ui.errors() == [] and shot.stat().st_size > 0 and shot2.stat().st_size > 0
    log = (tmp_path / "session" / "links" / "wire.log").read_text()
    assert "is in remote control" in log  # the check's traffic is on record
    print(f"screenshots: {shot} {shot2}")
