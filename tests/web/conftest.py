"""Browser fixtures: a real viser server (in-process `web.serve`) on a free port and the
system Chromium driven by Playwright. Missing browser: skip, or FAIL under
CELLTEACH_REQUIRE_BROWSER=1 (CI)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from web_ui import CHROMIUM, CHROMIUM_ARGS, UI

REQUIRE = os.environ.get("CELLTEACH_REQUIRE_BROWSER") == "1"


def _no_browser(reason: str) -> None:
    if REQUIRE:
        pytest.fail(f"CELLTEACH_REQUIRE_BROWSER=1 but the browser cannot run: {reason}",
                    pytrace=False)
    pytest.skip(f"browser tests need Playwright and {CHROMIUM}: {reason}")


@pytest.fixture(scope="session")
def playwright_driver() -> Iterator[Any]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        _no_browser(f"playwright is not installed ({exc})")
    if not os.access(CHROMIUM, os.X_OK):
        _no_browser(f"{CHROMIUM} is missing (apt-get install chromium)")
    driver = sync_playwright().start()
    try:
        yield driver
    finally:
        driver.stop()


FAILED = pytest.StashKey[bool]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: Any) -> Any:
    rep = yield
    if rep.when == "call":
        item.stash[FAILED] = rep.failed
    return rep



@pytest.fixture
def open_ui(request: pytest.FixtureRequest, playwright_driver: Any, tmp_path: Path
            ) -> Iterator[Callable[..., UI]]:
    """Open a page on a URL in a fresh Chromium profile; screenshots go under tmp_path
    (one per step, plus every page as it was when a test failed)."""
    contexts: list[Any] = []
    uis: list[UI] = []

    def open_(url: str, name: str = "a") -> UI:
        try:
            ctx = playwright_driver.chromium.launch_persistent_context(
                str(tmp_path / f"profile-{name}"), executable_path=CHROMIUM, headless=True,
                args=CHROMIUM_ARGS, accept_downloads=True,
                viewport={"width": 1400, "height": 950})
        except Exception as exc:  # noqa: BLE001 - a broken browser install
            _no_browser(f"Chromium did not start: {exc}")
        contexts.append(ctx)
        page = ctx.pages[0] if ctx.pages else ctx.new_page()
        # Generous: a software-rendered page on a machine loaded 5x waits tens of seconds
        # for a stable element (seen: 30 s exceeded at load 11); a broken page still fails.
        page.set_default_timeout(90_000)
        ui = UI(page, tmp_path / f"screens-{name}")
        ui.open(url)
        uis.append(ui)
        return ui

    yield open_
    if request.node.stash.get(FAILED, False):
        for ui in uis:
            with contextlib.suppress(Exception):  # the page may be gone
                print(f"failure screenshot: {ui.shot('FAILED')}")
    for ctx in contexts:
        ctx.close()


@pytest.fixture
def serve_session() -> Iterator[Callable[..., Any]]:
    """Start the real page over a session on a free localhost port; stopped afterwards."""
    from web import serve

    apps: list[Any] = []

    def start(session: Any, **kw: Any) -> Any:
        app = serve(session, host="127.0.0.1", port=0, **kw)
        apps.append(app)
        return app

    yield start
    for app in apps:
        app.stop()
