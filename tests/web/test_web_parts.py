"""The page's own pieces without a browser: event pump, picking, colours, units, guards."""

from __future__ import annotations

import threading
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import trimesh

from assistant.session import Session
from assistant.session.events import Notice, PointerUpdated, RobotMoved, StateChanged
from web.pump import EventPump, _coalesce
from web.scene.base import node_key
from web.scene.picking import pick
from web.scene.world import probability_colors
from web.units import pose_fields, pose_from_fields


def test_coalescing_keeps_order_and_only_the_newest_pose():
    a, b, c = (RobotMoved(np.full(5, k, float)) for k in (1, 2, 3))
    s = StateChanged("setup", "1", "Set up", "idle")
    n = Notice("x")
    p1, p2 = PointerUpdated(None), PointerUpdated(np.zeros(3))
    out = _coalesce([a, s, b, p1, n, c, p2])
    assert out == [s, n, c, p2]


def test_pump_applies_events_on_its_own_thread_in_order():
    seen: list[tuple[str, str]] = []
    pump = EventPump(lambda ev: seen.append((threading.current_thread().name, ev.message)))
    session = Session()
    pump.attach(session.bus)
    for k in range(20):
        session.bus.emit(Notice(str(k)))
    assert pump.wait_idle(10)
    pump.stop()
    assert [m for _, m in seen] == [str(k) for k in range(20)]
    assert {t for t, _ in seen} == {"cellteach-ui"}


def test_a_failing_redraw_does_not_stop_the_pump():
    calls: list[str] = []

    def dispatch(ev: Notice) -> None:
        calls.append(ev.message)
        if ev.message == "bad":
            raise RuntimeError("boom")

    pump = EventPump(dispatch)
    bus = Session().bus
    pump.attach(bus)
    for m in ("a", "bad", "b"):
        bus.emit(Notice(m))
    assert pump.wait_idle(10)
    pump.stop()
    assert calls == ["a", "bad", "b"] and len(pump.errors) == 1


def test_a_stopped_pump_draws_nothing_more():
    """Items already taken in a batch when the page stops are dropped: after `App.stop` the
    server is gone, and a handle touched then only warns ("closed connection")."""
    ran: list[int] = []
    gate0, gate1, entered1 = threading.Event(), threading.Event(), threading.Event()

    def job(k: int) -> Callable[[], None]:
        def run() -> None:
            ran.append(k)
            if k == 0:
                gate0.wait(10)
            if k == 1:
                entered1.set()
                gate1.wait(10)
        return run

    pump = EventPump(lambda ev: None)
    pump.post(job(0))
    for k in range(1, 6):  # queued while job 0 runs: one batch after it
        pump.post(job(k))
    gate0.set()
    assert entered1.wait(10)
    stopper = threading.Thread(target=pump.stop)
    stopper.start()
    assert pump._halt.wait(30)  # the stop has begun (job 1 still runs): an event, no clock
    gate1.set()
    stopper.join(10)
    assert ran == [0, 1]


def test_pick_finds_the_face_the_ray_meets_first():
    box = trimesh.creation.box((0.1, 0.1, 0.2))  # centred, z from -0.1 to 0.1
    T = np.eye(4)
    T[:3, 3] = (0.3, -0.1, 0.1)
    hit = pick(box, T, np.array([0.31, -0.12, 1.0]), np.array([0.0, 0.0, -1.0]))
    assert hit is not None
    assert np.allclose(hit.point_world, [0.31, -0.12, 0.2])
    assert np.allclose(hit.normal_world, [0, 0, 1])
    assert pick(box, T, np.array([1.0, 1.0, 1.0]), np.array([0.0, 0.0, -1.0])) is None


def test_probability_colours_run_from_pale_to_red():
    c = probability_colors(np.array([0.0, 0.5, 1.0, 2.0]))
    assert c.dtype == np.uint8 and c.shape == (4, 3)
    assert tuple(c[0]) == (250, 230, 120) and tuple(c[2]) == (200, 25, 25)
    assert tuple(c[3]) == tuple(c[2])  # clipped


def test_pose_fields_round_trip_in_mm_and_degrees():
    T = pose_from_fields((220.0, -200.5, 10.0), (30.0, -20.0, 175.0))
    xyz, abc = pose_fields(T)
    assert xyz == (220.0, -200.5, 10.0)
    assert np.allclose(abc, (30.0, -20.0, 175.0))


def test_node_keys_are_safe_and_distinct():
    assert node_key("O1") == "O1"
    assert "/" not in node_key("a/b") and node_key("a/b") != node_key("a_b")


def test_a_click_from_a_stale_page_on_a_disabled_button_does_nothing():
    """viser only greys buttons out in the browser: the server re-checks before acting."""
    from web import serve

    session = Session()
    app = serve(session, port=0)
    try:
        app.wait_idle(10)
        prev = app.toolbar.prev
        assert prev.disabled  # step 1 has no Previous
        fired: list[str] = []
        cb = app.actions.guarded(prev, lambda e: fired.append("x"), None)
        cb(SimpleNamespace(client=SimpleNamespace(add_notification=lambda *a, **k: None)))
        assert fired == [] and session.machine.state == "setup"
        # A programmatic value change (no client) is never an operator action either.
        nxt = app.toolbar.next
        cb = app.actions.guarded(nxt, lambda e: fired.append("y"), None)
        cb(SimpleNamespace(client=None))
        assert fired == []
    finally:
        app.stop()


def test_loading_a_session_replaces_what_every_page_shows(tmp_path):
    from web import serve

    first = Session()
    app = serve(first, port=0)
    try:
        saved = Session()
        saved.fire("next")
        saved.add_primitive("box", (0.1, 0.1, 0.1), name="crate")
        saved.save(tmp_path / "s")
        app.replace_session(Session.load(tmp_path / "s", autosave=False))
        assert app.wait_idle(10)
        assert app.session is not first
        assert "crate" in app.panels["Import CAD"].table.content
        assert "Step 2 of 7" in app.toolbar.heading.content
        assert app.panels["Import CAD"].folder.visible
        # Events of the old session no longer reach the page; the new one's do.
        first.bus.emit(Notice("old"))
        app.session.add_primitive("sphere", (0.05,), name="ball")
        assert app.wait_idle(10)
        assert "ball" in app.panels["Import CAD"].table.content
    finally:
        app.stop()


def test_the_tcp_gizmo_jogs_by_ik_and_says_when_it_turned_the_pose():
    """RV-2AJ, 5 axes: a gizmo pose outside the arm plane is projected, and the page says so."""
    from assistant.transforms import rot_x
    from web import serve
    from web.units import T_from_wxyz_position, wxyz_position

    session = Session()
    notes: list[str] = []
    session.bus.subscribe(lambda ev: notes.append(ev.message) if isinstance(ev, Notice)
                          else None)
    app = serve(session, port=0)
    try:
        app.wait_idle(10)
        jog = app.panels["Jog the robot"]
        assert jog.visible  # step 1 shows jogging
        jog.tcp_gizmo.value = True
        assert jog._gizmo is not None
        T_goal = np.eye(4)  # tool down, tilted 25 deg sideways: out of the arm plane
        T_goal[:3, :3] = rot_x(np.radians(25.0)) @ np.diag([1.0, -1.0, -1.0])
        T_goal[:3, 3] = [0.30, 0.10, 0.20]
        jog._gizmo.wxyz, jog._gizmo.position = wxyz_position(T_goal)
        # the page that drags the gizmo holds motion authority (no browser here: this stand-in
        # takes it, and no heartbeat asks it to answer)
        app.heartbeat.stop()
        client = SimpleNamespace(add_notification=lambda *a, **k: None, client_id=9999)
        assert session.hold.take(client.client_id)
        jog._gizmo_moved(SimpleNamespace(phase="end", client=client))
        session.worker.join(30)
        assert app.wait_idle(10)
        reached = session.tcp_world()
        assert np.linalg.norm(reached[:3, 3] - T_goal[:3, 3]) < 1e-3
        assert any("plane" in n for n in notes), notes
        # The gizmo follows the robot: it now shows the reached (projected) pose.
        shown = T_from_wxyz_position(jog._gizmo.wxyz, jog._gizmo.position)
        assert np.allclose(shown, reached, atol=1e-6)
    finally:
        app.stop()


def test_a_frame_calibrated_from_three_taught_points_places_parts_in_it():
    from web import serve

    session = Session()
    session.fire("next")
    session.add_primitive("box", (0.1, 0.1, 0.02), name="plate")
    session.goto("teach.locations")
    down = np.diag([1.0, -1.0, -1.0])
    for name, p in (("A", (0.25, -0.05, 0.15)), ("B", (0.32, -0.05, 0.15)),
                    ("C", (0.25, 0.05, 0.15))):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = down, p
        session.teach(name, T)
    session.goto("place.objects")
    app = serve(session, port=0)
    try:
        app.wait_idle(10)
        place = app.panels["Place objects"]
        place.frame_name.value = "pallet"
        place.f_origin.value, place.f_x.value = "A", "B"
        place.f_xy.value = "250 50 150"  # typed in mm works as well as a location name
        place._calibrate()
        assert app.wait_idle(10)
        assert "pallet" in session.cell.frames
        assert "pallet" in app.scene_layers.frames._nodes
        assert "pallet" in place.relative.options
        place.pick.value = "plate"
        place.relative.value = "pallet"
        place.xyz.value, place.abc.value = (50.0, 50.0, 10.0), (0.0, 0.0, 0.0)
        place._place()
        assert np.allclose(session.cell.objects["plate"].T_world_object[:3, 3],
                           [0.30, 0.0, 0.16], atol=1e-9)
    finally:
        app.stop()


def test_clicking_a_part_in_click_mode_teaches_the_surface_point():
    """viser reports the click ray; the page finds the surface point and the session teaches
    it with the tool against the surface."""
    from web import serve

    session = Session()
    session.fire("next")
    T = np.eye(4)
    T[:3, 3] = (0.30, 0.0, 0.05)
    session.add_primitive("box", (0.1, 0.1, 0.1), name="crate", T_world_object=T)
    session.goto("teach.locations")
    app = serve(session, port=0)
    try:
        app.wait_idle(10)
        teach = app.panels["Teach locations"]
        teach.name.value = "TOP"
        client = SimpleNamespace(add_notification=lambda *a, **k: None)
        click = SimpleNamespace(client=client, ray_origin=(0.31, 0.01, 1.0),
                                ray_direction=(0.0, 0.0, -1.0))
        app.scene_layers.objects._clicked("crate", click)  # click mode off: nothing
        assert "TOP" not in session.locations
        teach.click_mode.value = True
        app.scene_layers.objects._clicked("crate", click)
        loc = session.locations["TOP"]
        assert loc.source.value == "cad_click"
        assert np.allclose(loc.position, [0.31, 0.01, 0.10], atol=1e-6)
        assert np.allclose(loc.T_world_tool[:3, 2], [0, 0, -1], atol=1e-6)  # tool down
    finally:
        app.stop()
