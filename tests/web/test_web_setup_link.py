"""The set-up panel's link choice without a browser: the UR entry asks for an address only
(its ports are the controller's) and stores UR link settings in the session."""

from __future__ import annotations

from assistant.session import Session
from web.panels.setup import FIXED_PORTS, LINK_LABELS


def test_choosing_universal_robots_in_the_setup_panel():
    from web import serve

    session = Session()
    app = serve(session, port=0)
    try:
        assert app.wait_idle(10)
        panel = app.panels["Robot & link"]
        assert LINK_LABELS["ur"] in panel.link_kind.options and "ur" in FIXED_PORTS
        panel.link_kind.value = LINK_LABELS["ur"]
        panel._link_kind_changed()
        assert panel.host.visible and not panel.port.visible and not panel.time_scale.visible
        panel.host.value = "192.168.0.17"
        panel._set_link()
        assert app.wait_idle(10)
        ls = session.link_settings
        assert (ls.kind, ls.host, ls.ur_script_port, ls.ur_rtde_port) == \
            ("ur", "192.168.0.17", 30002, 30004)
        panel.refresh()
        assert "**Link:** Universal Robots (RTDE + URScript) at 192.168.0.17\n" in \
            panel.summary.content + "\n"
        # Back to a link with a port: the field shows again.
        panel.link_kind.value = LINK_LABELS["melfa"]
        panel._link_kind_changed()
        assert panel.port.visible
    finally:
        app.stop()
