"""The gated page in real Chromium: a viewer watches and cannot act, two operators share one
motion authority (asked for and handed over on the page), Collision! works for both, and the
page runs over HTTPS with a self-signed certificate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gate_helpers import gated_fixture, local_url, self_signed_cert  # noqa: F401
from web_ui import CHROMIUM, CHROMIUM_ARGS, UI

from assistant.session import Session
from web.gate import AccessTokens
from web.gate.banner import UNENCRYPTED, VIEW_ONLY

pytestmark = pytest.mark.browser


@pytest.mark.slow
def test_a_viewer_watches_and_cannot_act(gated, open_ui):
    tokens = AccessTokens.new()
    session = Session()
    app = gated(session, host="0.0.0.0", tokens=tokens)  # exposed, plain HTTP
    url = local_url(app)
    op = open_ui(f"{url}/?token={tokens.operator}", "operator")
    viewer = open_ui(f"{url}/?token={tokens.viewer}", "viewer")
    assert "token" not in viewer.page.url  # the link's token left the address bar
    viewer.wait_text(VIEW_ONLY)
    viewer.wait_text(UNENCRYPTED)
    op.wait_text(UNENCRYPTED)
    op.wait_text("You hold motion authority")
    assert viewer.page.get_by_text("Motion authority", exact=True).count() == 0
    joints = session.current_joints().copy()
    viewer.click("Next")
    viewer.expand("Jog the robot", viewer.button("Move to the slider values"))
    viewer.fill("J1 (deg)", 45)
    viewer.click("Move to the slider values")
    viewer.page.keyboard.press("Space")
    viewer.page.wait_for_timeout(1000)  # what got through would have acted by now
    viewer.shot("viewer-tried")
    assert session.machine.state == "setup"
    assert np.allclose(session.current_joints(), joints, atol=1e-9)
    assert session.counters.collision_indications == 0
    assert app.panels["Jog the robot"].sliders[0].value != 45
    viewer.step("1")
    # The operator's page acts, and the viewer sees it live.
    op.click("Next")
    viewer.step("2")
    assert session.machine.state != "setup"


def _https_ui(driver, url: str, tmp: Path, name: str) -> tuple[UI, object]:
    ctx = driver.chromium.launch_persistent_context(
        str(tmp / f"profile-{name}"), executable_path=CHROMIUM, headless=True,
        args=CHROMIUM_ARGS, ignore_https_errors=True, viewport={"width": 1400, "height": 950})
    page = ctx.pages[0] if ctx.pages else ctx.new_page()
    page.set_default_timeout(60_000)  # two software-rendered pages over TLS on a busy CI box
    ui = UI(page, tmp / f"screens-{name}")
    ui.open(url)
    return ui, ctx


@pytest.mark.slow
def test_two_operators_share_one_motion_authority_over_https(gated, playwright_driver,
                                                             tmp_path):
    from assistant.links.settings import LinkSettings

    certfile, keyfile = self_signed_cert(tmp_path)
    tokens = AccessTokens.new()
    session = Session()
    session.set_link(LinkSettings(time_scale=0.1))  # slow: the press lands mid-move
    app = gated(session, tokens=tokens, certfile=certfile, keyfile=keyfile)
    url = local_url(app)
    assert url.startswith("https://")
    contexts = []
    try:
        a, ctx = _https_ui(playwright_driver, f"{url}/?token={tokens.operator}", tmp_path, "a")
        contexts.append(ctx)
        a.wait_text("You hold motion authority")
        b, ctx = _https_ui(playwright_driver, f"{url}/?token={tokens.operator}", tmp_path, "b")
        contexts.append(ctx)
        b.wait_text("holds motion authority")
        start = session.current_joints().copy()
        b.expand("Jog the robot", b.button("Move to the slider values"))
        b.fill("J1 (deg)", 120)
        b.click("Move to the slider values")
        b.wait_text("Motion authority is with operator 1")
        b.shot("refused")
        assert session.machine.mode.value == "idle"
        assert np.allclose(session.current_joints(), start, atol=1e-9)
        b.click("Ask for motion authority")
        a.wait_text("asks for it")
        a.click("Hand over motion authority")
        b.wait_text("You hold motion authority")
        a.wait_text("holds motion authority")
        b.click("Move to the slider values")
        a.wait_text("The robot is moving")
        a.page.keyboard.press("Space")  # Collision! from the page without authority
        a.wait_text("Collision #1 recorded")
        b.wait_text("Collision #1 recorded")
        a.shot("collision-from-a")
        assert session.counters.collision_indications == 1
        assert 0.0 < np.degrees(session.recorded_collisions[0][0]) < 119.0
    finally:
        for c in contexts:
            c.close()
