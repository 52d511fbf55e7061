"""What each page receives, read off the real websockets: a viewer's page never gets the link
password (typed or stored), the session folder's path or the operators' addresses; one
operator's refusal reaches that operator's page only; the password typed on one operator's
page reaches no other page, and the page shows it stored as a mask."""

from __future__ import annotations

from gate_helpers import Page, click, encode, gated_fixture, run, uuid_of, wait_for  # noqa: F401

from assistant.session import Session
from assistant.session.link_secrets import MASK
from web.gate import AccessTokens
from web.panels.setup import LINK_LABELS

PASSWORD = "Rws-pa55word-typed-on-one-page"
OP1, OP2 = "127.0.0.3", "127.0.0.4"  # two operators' computers


def _update(uuid: str, value: object) -> bytes:
    return encode({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}})


def test_viewers_get_what_watching_needs_and_refusals_stay_with_their_page(gated, tmp_path):
    tokens = AccessTokens.new()
    folder = tmp_path / "the-cell-session"
    session = Session(folder)
    session.save(folder)
    app = gated(session, tokens=tokens)
    setup = app.panels["Robot & link"]
    box = app.panels["Session file"]
    jog = app.panels["Jog the robot"]
    saved_to = tmp_path / "saved-copy"

    async def go() -> tuple[Page, Page, Page]:
        async with Page(app, tokens.operator, OP1) as op1, \
                Page(app, tokens.operator, OP2) as op2, Page(app, tokens.viewer) as viewer:
            assert await wait_for(lambda: app.access.authority.holds(op1.client_id))
            # op2 tries to move the robot: refused, on op2's page only.
            await op2.send(click(uuid_of(jog.move)))
            assert await wait_for(lambda: op2.saw("Motion authority is with operator 1"))
            app.access.authority.request(op2.client_id)  # op2 asks for it (op1's page says)
            assert await wait_for(lambda: op1.saw(f"operator 2 ({OP2}) asks for it"))
            # op1 picks the ABB link, types a password on its page and stores it.
            await op1.send(_update(uuid_of(setup.link_kind), LINK_LABELS["abb"]))
            field = setup.rws_password.of(op1.client)
            assert field is not None and setup.rws_password.of(viewer.client) is None
            await op1.send(_update(uuid_of(field), PASSWORD))
            assert await wait_for(lambda: field.value == PASSWORD)
            await op1.send(click(uuid_of(setup.apply_link)))
            assert await wait_for(lambda: session.link_settings.rws_password == PASSWORD)
            assert await wait_for(lambda: viewer.saw(f"password {MASK}"))  # shown masked
            # op1 saves a copy somewhere else from its own "Session file" box.
            mine = box.boxes.of(op1.client)
            assert mine is not None and box.boxes.of(viewer.client) is None
            await op1.send(_update(uuid_of(mine.folder_text), str(saved_to)))
            assert await wait_for(lambda: mine.folder_text.value == str(saved_to))
            await op1.send(click(uuid_of(mine.save)))
            assert await wait_for(lambda: op1.saw(f"Session saved to {saved_to}"))
            assert await wait_for(lambda: viewer.saw("Step 1 of 7"))
            await app_idle()
            return op1, op2, viewer

    async def app_idle() -> None:
        assert await wait_for(lambda: app.wait_idle(0.01))

    op1, op2, viewer = run(go())
    # What the pages needed reached them (so the search below can find such strings) ...
    assert op1.saw(str(folder))
    assert op2.saw(f"operator 1 ({OP1})")
    # ... and what they must not have did not.
    for secret in (PASSWORD, str(folder), str(saved_to), OP1, OP2):
        assert not viewer.saw(secret), secret
    assert not op2.saw(PASSWORD) and not op2.saw(str(saved_to))
    assert not op1.saw("Motion authority is with operator 1")  # op2's refusal stayed there
    assert not viewer.saw("Motion authority is with")
    assert (saved_to / "secrets.json").stat().st_mode & 0o777 == 0o600
    assert PASSWORD not in (saved_to / "session.json").read_text()
