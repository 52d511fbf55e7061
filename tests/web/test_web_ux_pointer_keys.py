"""Feedback and shortcuts in the real page: a pointer dwell shows its progress with the button
waiting (and no seed field in sight), the keyboard moves through the steps and undoes, the
command palette lists those commands, and Undo says what it undoes."""

from __future__ import annotations

import re

import pytest

from assistant.session import Session

pytestmark = pytest.mark.browser


def test_dwell_progress_and_keyboard(serve_session, open_ui, tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                                  with_mission=False)
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("1")
    # Alt+Right arrow is Next, Alt+Left arrow Previous.
    ui.page.keyboard.press("Alt+ArrowRight")
    ui.step("2")
    ui.page.keyboard.press("Alt+ArrowLeft")
    ui.step("1")
    ui.page.keyboard.press("Alt+ArrowRight")
    ui.step("2")
    ui.expand("Add a simple shape", ui.button("Add shape"))
    ui.click("Add shape")
    ui.wait_cell("box")
    # Undo says what it undoes, in the palette (Ctrl+K) and on its button.
    ui.page.keyboard.press("Control+k")
    for name in ("Next step", "Previous step", "Undo: add a box"):
        ui.page.locator(f"text='{name}' >> visible=true").first.wait_for()
    ui.shot("palette")
    ui.page.keyboard.press("Escape")
    ui.page.locator("text='Next step' >> visible=true").wait_for(state="hidden")
    ui.page.evaluate("document.activeElement && document.activeElement.blur()")
    ui.page.keyboard.press("Control+z")  # not in a text field: there it undoes the typing
    ui.wait_text("Undone: add a box")
    assert session.cell.objects == {}
    session.add_primitive("box", (0.1, 0.1, 0.1), name="B")
    session.goto("teach.locations")
    ui.step("4.1")
    # The seed of the synthetic camera is no field the operator has to fill.
    assert not ui.page.get_by_text("Simulation seed").count()
    assert not ui.page.get_by_text("Image noise seed").first.is_visible()
    ui.fill("Name", "P7")
    ui.fill_vec("Point (mm)", (340, -70, 60))
    ball = app.scene_layers.pointer
    drawn: list[bool] = []  # the ball's visibility after each pointer event the page drew
    draw = ball.on_event

    def spy(ev):  # noqa: ANN001, ANN202
        draw(ev)
        if ball._nodes:  # noqa: SLF001
            drawn.append(bool(ball._nodes["ball"].visible))  # noqa: SLF001

    ball.on_event = spy
    ui.button("Teach by pointer dwell").click()
    # While the cameras measure: the ball is in the scene, the dwell counts up to its time,
    # the button waits.
    ui.wait_text(re.compile(r"Hold still\.\.\. \d+\.\d / \d+\.\d s"))
    assert ui.button("Teach by pointer dwell").is_disabled()
    ui.shot("dwell")
    ui.wait_cell("P7")
    ui.wait_enabled("Teach by pointer dwell")
    ui.page.get_by_text(re.compile(r"Hold still")).first.wait_for(state="hidden", timeout=15_000)
    app.wait_idle(10)
    assert any(drawn), "the ball was not drawn while the dwell ran"
    assert drawn[-1] is False  # gone once the point is taught
    assert "P7" in session.locations
