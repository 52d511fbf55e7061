"""The page offers what a blocked re-plan says (issue 56): the learnt collision indications,
numbered as a run names them, and a control that forgets one - it leaves the world model and
the saved session, so a plan may pass there again."""

from __future__ import annotations

import time

import pytest

from assistant.session import Session
from assistant.session.commands import PageCommand

pytestmark = pytest.mark.browser


def test_a_learnt_indication_is_listed_and_forgotten_from_the_page(serve_session, open_ui,
                                                                     tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    session.goto("explore")
    session.build_world()
    session.goto("plan")
    session.fire(PageCommand.COLLISION)  # the operator's Collision! with the arm standing
    learnt = session.learnt_indications()
    assert len(learnt) == 1 and learnt[0].startswith("1: tool at (")
    assert len(session.recorded_collisions) == 1
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("6")
    forget = ui.button("Forget this indication")
    ui.expand("Learnt collisions", forget)
    ui.wait_text(learnt[0])
    ui.shot("learnt-collisions")
    ui.click("Forget this indication")
    # the page's click runs as a session action in the server's thread: wait for all of it
    # (the world model forgets first, then the record, then the save), not its first part
    deadline = time.monotonic() + 30
    while session.learnt_indications() or session.recorded_collisions or \
            Session.load(tmp_path / "s", autosave=False).recorded_collisions:
        assert time.monotonic() < deadline, "the indication was not forgotten"
        time.sleep(0.1)
    assert session.recorded_collisions == []  # the saved record too: a rebuild keeps it gone
    assert Session.load(tmp_path / "s", autosave=False).recorded_collisions == []
    ui.page.get_by_text("Learnt collisions", exact=True).first.wait_for(state="hidden")
