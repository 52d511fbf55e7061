"""The live marker pointer in the page (synthetic cameras): camera views with the blobs
overlaid, the tracked ball in the scene, dwell-to-teach."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.session import Session

pytestmark = pytest.mark.browser


def test_pointer_dwell_teaches_the_held_point(serve_session, open_ui):
    session = Session()
    session.fire("next")
    session.add_primitive("box", (0.1, 0.1, 0.1), name="crate")
    session.fire("next")
    session.fire("next")  # 3.2 cameras
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("3.2")
    ui.click("Start cameras")
    ui.expand("Simulated hand (synthetic camera)", ui.button("Bring the ball there"))
    ui.fill_vec("Ball at (mm)", (300, 50, 150))
    ui.click("Bring the ball there")
    ui.wait_text("Pointer (stereo)")
    ui.wait_text("pointer held still")
    # Two live camera images are on the page.
    ui.page.wait_for_function(
        "() => [...document.querySelectorAll('img')].filter(i => i.src.startsWith('data:') "
        "|| i.src.startsWith('blob:')).length >= 2")
    ui.shot("cameras")
    ui.click("Next")
    ui.step("4.1")
    ui.fill("Name", "PH")
    ui.wait_enabled("Teach the point just held")
    ui.click("Teach the point just held")
    ui.wait_cell("PH")
    ui.shot("taught-by-pointer")
    loc = session.locations["PH"]
    assert loc.source.value == "pointer"
    assert np.linalg.norm(loc.position - [0.30, 0.05, 0.15]) < 0.01
    session.stop_pointer()
