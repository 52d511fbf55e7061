"""The gated page in real Chromium: signing in leaves no code in the browser's history (its
History database read after the browser closed) and the way back stays on this site; a viewer
watches, cannot act and its controls look inactive; two operators share one motion authority
(asked for and handed over on the page), Collision! works for both, and the page runs over
HTTPS with a self-signed certificate."""

from __future__ import annotations

import re
import sqlite3
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import pytest
from gate_helpers import gated_fixture, local_url, self_signed_cert  # noqa: F401
from web_ui import CHROMIUM, CHROMIUM_ARGS, UI

from assistant.session import Session
from web.gate import AccessTokens
from web.gate.banner import UNENCRYPTED, VIEW_ONLY

pytestmark = pytest.mark.browser

STEP = re.compile(r"Step \d+(\.\d+)? of 7")


def sign_in(page: Any, url: str, code: str) -> None:
    """Open `url` (the sign-in form comes first), type the code, wait for the workflow."""
    page.goto(url)
    page.fill("#code", code)
    page.click("button[type=submit]")
    page.get_by_text(STEP).first.wait_for(state="visible")


@pytest.fixture
def signed_in(playwright_driver, tmp_path):
    """Open a signed-in page in a fresh Chromium profile (closed afterwards)."""
    contexts: list[Any] = []

    def open_(url: str, code: str, name: str, **kw: Any) -> UI:
        ctx = playwright_driver.chromium.launch_persistent_context(
            str(tmp_path / f"profile-{name}"), executable_path=CHROMIUM, headless=True,
            args=CHROMIUM_ARGS, viewport={"width": 1400, "height": 950}, **kw)
        contexts.append(ctx)
        page = ctx.pages[0] if ctx.pages else ctx.new_page()
        page.set_default_timeout(60_000)  # software-rendered pages on a busy CI box
        sign_in(page, url, code)
        return UI(page, tmp_path / f"screens-{name}")

    yield open_
    for ctx in contexts:
        ctx.close()


def _history(profile: Path) -> list[str]:
    """Every address Chromium's History database holds (read after the browser closed)."""
    con = sqlite3.connect(profile / "Default" / "History")
    try:
        return [u for (u,) in con.execute("SELECT url FROM urls")]
    finally:
        con.close()


def test_signing_in_leaves_no_code_in_the_history_and_stays_on_this_site(
        gated, playwright_driver, tmp_path):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens)
    url = local_url(app)
    profile = tmp_path / "profile"
    ctx = playwright_driver.chromium.launch_persistent_context(
        str(profile), executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
    try:
        page = ctx.pages[0] if ctx.pages else ctx.new_page()
        page.set_default_timeout(60_000)
        sign_in(page, url + "/?darkMode", tokens.operator)
        # (viser's client writes its address back as "?darkMode=")
        assert urlsplit(page.url).path == "/" and urlsplit(page.url).query.startswith("darkMode")
        # The reported open redirect: a link to //evil.example/x, signed in with the viewer's
        # code, must land on this site (and must not take the operator's cookie: another
        # profile here, as a victim's browser would be).
        other = playwright_driver.chromium.launch_persistent_context(
            str(tmp_path / "profile-victim"), executable_path=CHROMIUM, headless=True,
            args=CHROMIUM_ARGS)
        try:
            victim = other.pages[0] if other.pages else other.new_page()
            asked: list[str] = []
            victim.on("request", lambda r: asked.append(r.url))
            victim.goto(f"{url}//evil.example/x?token={tokens.viewer}")
            assert victim.get_by_text("not taken from the address").count() == 1
            victim.fill("#code", tokens.viewer)
            with victim.expect_response(lambda r: r.request.method == "GET" and
                                        r.request.is_navigation_request()) as landed:
                victim.click("button[type=submit]")
            assert landed.value.url == f"{url}/evil.example/x"  # a path here (viser: 404)
            assert all(urlsplit(u).netloc == urlsplit(url).netloc for u in asked), asked
        finally:
            other.close()
        back = page.evaluate("history.length")
    finally:
        ctx.close()
    seen = _history(profile)
    assert any(urlsplit(u).netloc == urlsplit(url).netloc for u in seen), seen
    assert not [u for u in seen if tokens.operator in u or "token" in u], seen
    assert back <= 3  # blank tab, the sign-in form, the page: no entry with the code


@pytest.mark.slow
def test_a_viewer_watches_and_cannot_act(gated, signed_in):
    tokens = AccessTokens.new()
    session = Session()
    app = gated(session, host="0.0.0.0", tokens=tokens)  # exposed, plain HTTP
    url = local_url(app)
    op = signed_in(url + "/", tokens.operator, "operator")
    viewer = signed_in(url + "/", tokens.viewer, "viewer")
    viewer.wait_text(VIEW_ONLY)
    viewer.wait_text(UNENCRYPTED)
    op.wait_text(UNENCRYPTED)
    op.wait_text("You hold motion authority")
    assert viewer.page.get_by_text("Motion authority", exact=True).count() == 0
    # Its controls look inactive (greyed, a not-allowed cursor); the operator's do not.
    style = "b => [getComputedStyle(b).opacity, getComputedStyle(b).cursor]"
    assert viewer.button("Next").evaluate(style) == ["0.45", "not-allowed"]
    assert op.button("Next").evaluate(style) == ["1", "pointer"]
    viewer.shot("viewer-page")
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


@pytest.mark.slow
def test_two_operators_share_one_motion_authority_over_https(gated, signed_in, tmp_path):
    from assistant.links.settings import LinkSettings

    certfile, keyfile = self_signed_cert(tmp_path)
    tokens = AccessTokens.new()
    session = Session()
    session.set_link(LinkSettings(time_scale=0.1))  # slow: the press lands mid-move
    app = gated(session, tokens=tokens, certfile=certfile, keyfile=keyfile)
    url = local_url(app)
    assert url.startswith("https://")
    a = signed_in(url + "/", tokens.operator, "a", ignore_https_errors=True)
    a.wait_text("You hold motion authority")
    b = signed_in(url + "/", tokens.operator, "b", ignore_https_errors=True)
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
