"""Roles and motion authority over real websockets that speak viser's wire format: a viewer's
changing messages never reach the page, only the holder of motion authority moves the robot,
Collision! and Stop work for every operator, uploads are bounded."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
from gate_helpers import (  # noqa: F401
    Page,
    click,
    encode,
    gated_fixture,
    run,
    uuid_of,
    wait_for,
)

from assistant.session import Session
from web.gate import AccessTokens
from web.gate.messages import CHANGING


def _refusals(page: Page) -> int:
    """How many messages to `page` say its motion was refused (authority with another page).
    A refusal shown means the action was turned down: waiting for it replaces a sleep after
    which "nothing moved" could pass only because the click had not been handled yet."""
    return sum(b"Motion authority is with" in m for m in page.received)


def _viewer_messages(app: Any) -> list[bytes]:
    """One message of every changing kind viser's client sends, aimed at real controls."""
    tb = app.toolbar
    jog = app.panels["Jog the robot"]
    cad = app.panels[next(t for t in app.panels if "CAD" in t)]
    up = uuid_of(cad.upload)
    kinds = {
        "GuiUpdateMessage": [click(uuid_of(tb.next)), click(uuid_of(jog.move)),
                             encode({"type": "GuiUpdateMessage", "uuid": uuid_of(jog.sliders[0]),
                                     "updates": {"value": 33.0}})],
        "GuiButtonHoldMessage": [encode({"type": "GuiButtonHoldMessage",
                                         "uuid": uuid_of(tb.next), "frequency": 10.0})],
        "GuiFormSubmitMessage": [encode({"type": "GuiFormSubmitMessage",
                                         "uuid": uuid_of(tb.next)})],
        "GuiFormDirtyMessage": [encode({"type": "GuiFormDirtyMessage",
                                        "uuid": uuid_of(tb.next)})],
        "CommandTriggerMessage": [encode({"type": "CommandTriggerMessage",
                                          "uuid": uuid_of(tb.key_collision)})],
        "FileTransferStartUpload": [encode({
            "type": "FileTransferStartUpload", "source_component_uuid": up,
            "transfer_uuid": "t1", "filename": "x.stl", "mime_type": "model/stl",
            "part_count": 1, "size_bytes": 5})],
        "FileTransferPart": [encode({"type": "FileTransferPart", "source_component_uuid": up,
                                     "transfer_uuid": "t1", "part_index": 0,
                                     "content": b"solid"})],
        "SceneNodeClickMessage": [encode({
            "type": "SceneNodeClickMessage", "name": "/robot", "instance_index": None,
            "ray_origin": [0, 0, 1], "ray_direction": [0, 0, -1], "screen_pos": [0.5, 0.5],
            "modifier": None, "owner": ""})],
        "SceneNodeDragMessage": [encode({"type": "SceneNodeDragMessage", "name": "/robot",
                                         "phase": "start", "owner": ""})],
        "ScenePointerMessage": [encode({"type": "ScenePointerMessage", "event_type": "click",
                                        "ray_origin": [0, 0, 1], "ray_direction": [0, 0, -1],
                                        "screen_pos": [[0.5, 0.5]]})],
        "TransformControlsUpdateMessage": [encode({
            "type": "TransformControlsUpdateMessage", "name": "/gizmo/tcp",
            "wxyz": [1, 0, 0, 0], "position": [0.3, 0.0, 0.3], "owner": ""})],
        "TransformControlsDragStartMessage": [encode({
            "type": "TransformControlsDragStartMessage", "name": "/gizmo/tcp", "owner": ""})],
        "TransformControlsDragEndMessage": [encode({
            "type": "TransformControlsDragEndMessage", "name": "/gizmo/tcp", "owner": ""})],
        "ShareUrlRequest": [encode({"type": "ShareUrlRequest"})],
    }
    assert set(CHANGING) <= set(kinds)
    return [m for ms in kinds.values() for m in ms]


def _snapshot(session: Session, app: Any) -> tuple:
    jog = app.panels["Jog the robot"]
    return (session.machine.state, session.machine.mode.value, dict(session.cell.objects),
            session.counters.collision_indications, tuple(np.round(session.current_joints(), 9)),
            jog.sliders[0].value, session.history.can_undo)


def test_a_viewer_cannot_change_anything(gated):
    tokens = AccessTokens.new()
    session = Session()
    app = gated(session, tokens=tokens)
    app.wait_idle(10)
    before = _snapshot(session, app)
    msgs = _viewer_messages(app)

    async def go() -> None:
        async with Page(app, tokens.viewer) as viewer:
            for m in msgs:
                await viewer.send(m)
            await asyncio.sleep(1.0)  # anything that got through has acted by now
            # Behind the front too, the page refuses a viewer's client.
            handle = app.server.get_clients()[viewer.client_id]
            assert "view only" in app.access.refusal(handle, motion=False)
            assert app.server.get_clients()  # the viewer is still connected (watching)
        assert await wait_for(lambda: app.access.front.dropped == len(msgs))
        assert _snapshot(session, app) == before
        # The same click from an operator does act (the messages above are well-formed).
        async with Page(app, tokens.operator) as op:
            await op.send(click(uuid_of(app.toolbar.next)))
            assert await wait_for(lambda: session.machine.state != "setup")

    run(go())


def test_only_the_holder_of_motion_authority_moves_the_robot(gated):
    from assistant.links.settings import LinkSettings

    tokens = AccessTokens.new()
    session = Session()
    # Slow (a tenth of real speed): Collision! and Stop land mid-move even on a busy machine.
    session.set_link(LinkSettings(time_scale=0.1))
    app = gated(session, tokens=tokens)
    jog = app.panels["Jog the robot"]
    auth = app.access.authority

    async def set_j1(page: Page, deg: float) -> None:
        # After a move the page puts the sliders back to the robot: let that happen first.
        assert await asyncio.to_thread(app.wait_idle, 10.0)
        await page.send(encode({"type": "GuiUpdateMessage", "uuid": uuid_of(jog.sliders[0]),
                                "updates": {"value": deg}}))
        assert await wait_for(lambda: jog.sliders[0].value == deg)

    def j1() -> float:
        return float(np.degrees(session.current_joints()[0]))

    async def go() -> None:
        async with Page(app, tokens.operator) as a, Page(app, tokens.operator) as b:
            assert await wait_for(lambda: auth.state.holder == a.client_id)  # first arrived
            start = j1()
            # B may edit (an operator) but not move: refused, the robot stays.
            await set_j1(b, 120.0)
            n = _refusals(b)
            await b.send(click(uuid_of(jog.move)))
            assert await wait_for(lambda: _refusals(b) > n)  # turned down, shown to B ...
            assert session.machine.mode.value == "idle" and abs(j1() - start) < 1e-6  # ... still
            # B asks, A hands over; now B moves it.
            auth.request(b.client_id)
            assert auth.hand_over(a.client_id) == b.client_id
            await b.send(click(uuid_of(jog.move)))
            assert await wait_for(lambda: session.machine.mode.value == "moving")
            # A (no authority) presses Collision! (the Space key command) mid-move, once its
            # page offers it (as a person would: the toolbar follows the session's event).
            assert await wait_for(lambda: not app.toolbar.key_collision.disabled)
            await a.send(encode({"type": "CommandTriggerMessage",
                                 "uuid": uuid_of(app.toolbar.key_collision)}))
            assert await wait_for(lambda: session.counters.collision_indications == 1)
            assert await wait_for(lambda: session.machine.mode.value == "idle")
            # Back the other way, and A presses Stop in the toolbar: it stops short of -120.
            # A fiftieth of real speed (the jog takes ~40 s): Stop lands mid-move even when
            # the toolbar enables it seconds late (seen at load 10 with a tenth: the 8 s jog
            # had ended before Stop arrived).
            session.set_simulation_speed(0.02)
            await set_j1(b, -120.0)
            await b.send(click(uuid_of(jog.move)))
            assert await wait_for(lambda: session.machine.mode.value == "moving")
            stop = await _toolbar_button(app, "stop")
            await a.send(click(uuid_of(stop)))
            assert await wait_for(lambda: session.machine.mode.value == "idle")
            assert j1() > -119.0
            # A cannot move while B holds it; B leaves: authority lapses, nobody gets it.
            n = _refusals(a)
            await a.send(click(uuid_of(jog.move)))
            assert await wait_for(lambda: _refusals(a) > n)  # turned down, shown to A
            assert session.machine.mode.value == "idle"
        assert await wait_for(lambda: auth.state.holder is None)

    run(go())


def test_the_jog_gizmo_needs_motion_authority_too(gated):
    tokens = AccessTokens.new()
    session = Session()
    app = gated(session, tokens=tokens)
    jog = app.panels["Jog the robot"]

    def drag(to: list[float]) -> list[bytes]:
        name = "/gizmo/tcp"
        return [encode({"type": "TransformControlsDragStartMessage", "name": name, "owner": ""}),
                encode({"type": "TransformControlsUpdateMessage", "name": name,
                        "wxyz": [float(v) for v in jog._gizmo.wxyz], "position": to,
                        "owner": ""}),
                encode({"type": "TransformControlsDragEndMessage", "name": name, "owner": ""})]

    async def go() -> None:
        async with Page(app, tokens.operator) as a, Page(app, tokens.operator) as b:
            assert await wait_for(lambda: app.access.authority.holds(a.client_id))
            await b.send(encode({"type": "GuiUpdateMessage", "uuid": uuid_of(jog.tcp_gizmo),
                                 "updates": {"value": True}}))
            assert await wait_for(lambda: jog._gizmo is not None)
            q0 = session.current_joints().copy()
            target = [float(v) for v in np.asarray(jog._gizmo.position) + [0.0, 0.0, -0.03]]
            n = _refusals(b)
            for m in drag(target):
                await b.send(m)
            assert await wait_for(lambda: _refusals(b) > n)  # turned down, shown to B
            # The drag is three messages: a second more shows no later one moved it either
            # (an absence, so a deliberate wait: a slow machine only makes it pass later).
            await asyncio.sleep(1.0)
            assert session.machine.mode.value == "idle"
            assert np.allclose(session.current_joints(), q0, atol=1e-9)
            for m in drag(target):  # the holder's drag does move it
                await a.send(m)
            assert await wait_for(
                lambda: not np.allclose(session.current_joints(), q0, atol=1e-4))

    run(go())


async def _toolbar_button(app: Any, event: str) -> Any:
    assert await wait_for(lambda: app.toolbar.button(event) is not None)
    btn = app.toolbar.button(event)
    assert await wait_for(lambda: not btn.disabled)
    return btn


def test_uploads_are_bounded_at_the_front(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens, max_upload_mb=1.0)
    cad = app.panels[next(t for t in app.panels if "CAD" in t)]

    def start(uuid: str, size: int) -> bytes:
        return encode({"type": "FileTransferStartUpload", "source_component_uuid":
                       uuid_of(cad.upload), "transfer_uuid": uuid, "filename": "x.stl",
                       "mime_type": "model/stl", "part_count": 1, "size_bytes": size})

    async def closed_with(page: Page) -> int | None:
        await wait_for(lambda: page.ws.closed, 10)
        return page.ws.close_code

    async def go() -> None:
        # A third upload at once from one page: the front closes that page's socket.
        async with Page(app, tokens.operator) as p:
            for i in range(3):
                await p.send(start(f"u{i}", 10))
            assert await closed_with(p) == 1008
        # More bytes than announced: closed too.
        async with Page(app, tokens.operator) as p:
            await p.send(start("big", 10))
            await p.send(encode({"type": "FileTransferPart", "source_component_uuid":
                                 uuid_of(cad.upload), "transfer_uuid": "big",
                                 "part_index": 0, "content": b"x" * 1000}))
            assert await closed_with(p) == 1008
        # One message larger than the front takes (viser sends 512 KiB parts).
        async with Page(app, tokens.operator) as p:
            await p.send(b"\x00" * (3 * 2**20))
            # 1009 (too big) when the close frame reaches the page; on a busy machine the
            # front's close can reset the socket while the page still sends its 3 MiB, and
            # the page then sees the connection drop (1006) - refused either way
            assert await closed_with(p) in (1009, 1006)
        assert await wait_for(lambda: app.access.front._slots.used == 0)  # noqa: SLF001

    run(go())
