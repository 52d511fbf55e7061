"""Errors leave the screen once they are stale: when the operator acts again or the step
changes - not when a failed task merely ends (its error is the news then). What is said to one
page (its own failed action) stays on that page: never in the status line every page shares."""

from __future__ import annotations

from types import SimpleNamespace

from assistant.session import Session
from assistant.session.events import ErrorRaised, StateChanged


class _Page:
    """A client that records its notifications (the real ones live in the browser)."""

    def __init__(self) -> None:
        self.client_id = 1
        self.shown: list[SimpleNamespace] = []

    def add_notification(self, title, body, **kw):  # noqa: ANN001, ANN201
        h = SimpleNamespace(title=title, body=body, _impl=SimpleNamespace(removed=False))
        h.remove = lambda: setattr(h._impl, "removed", True)
        self.shown.append(h)
        return h

    def open_errors(self) -> list[str]:
        return [h.body for h in self.shown
                if h.title == "Could not do that" and not h._impl.removed]


def test_stale_errors_close_when_the_operator_acts_or_the_step_changes():
    from web import serve

    session = Session()
    app = serve(session, port=0)
    page = _Page()
    try:
        app.wait_idle(10)
        status = app.toolbar.status
        # an error stays while nothing happens - on the page that acted, not in the status
        # line every page shares
        app.actions.run(lambda: (_ for _ in ()).throw(ValueError("the point is out of reach")),
                        page)
        assert page.open_errors() and "out of reach" not in status.content
        # the operator acts again (and it works): the old error closes
        app.actions.run(lambda: None, page)
        assert page.open_errors() == [] and "Error:" not in status.content
        # a repeated failure is news: shown again, not swallowed as a duplicate
        for _ in range(2):
            app.actions.run(lambda: (_ for _ in ()).throw(ValueError("still out of reach")),
                            page)
            assert len(page.open_errors()) == 1
        # a failed task ends: the workflow mode changes but the step does not - the error
        # that reports the failure stays
        state = session.machine.state
        session.bus.emit(ErrorRaised("plan the mission: no path", ""))
        session.bus.emit(StateChanged(state, session.machine.number, "", "idle"))
        app.wait_idle(10)
        assert "no path" in status.content and len(page.open_errors()) == 1
        # the step changes: every earlier error is stale
        session.next()
        app.wait_idle(10)
        assert session.machine.state != state
        assert page.open_errors() == [] and "Error:" not in status.content
    finally:
        app.stop()
