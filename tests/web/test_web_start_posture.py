"""The page without a browser: the robot's self-collision rule in the set-up panel, a start
posture that touches the cell drawn red with the jog panel's way out."""

from __future__ import annotations

import time

import numpy as np

from assistant.session import Session
from assistant.transforms import make_T
from web.scene.robot import TOUCHING

PAGE = 1  # a page's id, as web.authority gives them


def wait_for(cond, timeout: float = 60.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.05)
    return cond()


def test_the_rule_is_shown_and_a_touching_start_is_red_with_a_way_out(tmp_path):
    from web import serve

    session = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                                  with_mission=False)
    app = serve(session, port=0)
    try:
        assert app.wait_idle(30)
        setup = app.panels["Robot & link"]
        app.pump.post(setup.refresh)
        assert wait_for(lambda: "Checked against each other" in setup.rule_text.content)
        assert "joined by a joint: the base (base) - the J1 link (J1_turret)" in \
            setup.rule_text.content
        jog = app.panels["Jog the robot"]
        assert not jog.free.visible
        frames = session.link_poses_world(session.current_joints())
        session.next()
        session.add_primitive("box", (0.3, 0.02, 0.3), name="wall", T_world_object=make_T(
            np.eye(3), 0.5 * (frames[3][:3, 3] + frames[4][:3, 3])))
        assert app.wait_idle(30)
        assert jog.free.visible and "touches wall" in jog.touching.content
        layer = app.scene_layers.robot
        red = {n for n, h in layer._nodes.items() if tuple(getattr(h, "color", ())) == TOUCHING}
        assert red and red <= set(session.start_posture_links())
        # the way out is motion: only the page holding motion authority starts it (no
        # browser here: a stand-in page takes it, and no heartbeat asks it to answer)
        app.heartbeat.stop()
        assert session.hold.take(PAGE)
        with session.hold.acting(PAGE):
            session.move_to_free_posture()
        assert app.wait_idle(30)
        assert not jog.free.visible
    finally:
        app.stop()
