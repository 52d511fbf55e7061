"""The export panel in the real page shows the predicted cycle time: the total (said to be a
prediction) and the seconds of every mission step, as `ExportResult.cycle_time` has them;
`report.json` (`session_report`) carries the same total and per-move times."""

from __future__ import annotations

import pytest

from assistant.session import Session
from assistant.session.report import session_report

#: World model and planning of the thesis cell on a loaded 2-core machine.
LONG_MS = 180_000

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_the_export_panel_shows_the_predicted_cycle_time(serve_session, open_ui, tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    session.goto("explore")
    session.build_world()
    session.goto("plan")
    session.plan()
    session.goto("export")
    result = session.export("melfa")
    ct = result.cycle_time
    assert ct is not None and ct.total_s > 0
    app = serve_session(session)
    ui = open_ui(app.url)
    ui.step("7")
    ui.wait_text(f"Predicted cycle time {ct.total_s:.1f} s.", timeout=LONG_MS)  # the summary
    ui.wait_text("not measured on a controller")
    for step, seconds in ct.by_step():
        row = ui.page.get_by_role("row").filter(has_text=step).filter(
            has_text=f"{seconds:.2f}")
        row.first.wait_for(state="visible")
    ui.shot("7-cycle-time")
    # The program text carries the same total in its header.
    text = result.files[0].data.decode("ascii")
    assert f"predicted cycle time {ct.total_s:.1f} s" in text
    # report.json of the same session: the total and one entry per timed instruction.
    rep = session_report(session, wall_time_s=0.0)
    assert rep["predicted_cycle_time_s"] == round(ct.total_s, 3)
    moves = rep["cycle_time"]["moves"]
    assert len(moves) == len(ct.entries)
    assert sum(m["seconds"] for m in moves) == pytest.approx(ct.total_s, abs=1e-3 * len(moves))
