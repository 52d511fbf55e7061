"""Who may use the page and who may move the robot: the authenticating front, the two roles and
the one holder of motion authority. No domain logic.

On loopback (the default) the page is open as before and nothing here runs. On any other
address (or with `--token-file` / `--certfile`) viser listens on 127.0.0.1 only and `Front`
(aiohttp) listens on the exposed address: every HTTP path and the websocket need an access
code (typed once into the sign-in form, never in an address, then an HttpOnly cookie:
`login.py`), failed codes are rate-limited per address, connections are capped per address and
in all and timed out (`connections.py`), request bodies and uploads are bounded, TLS is served
with `--certfile/--keyfile`.

Two tokens, two roles: the *operator* link drives the page, the *viewer* link watches it. A
viewer's websocket messages that would change anything (GUI edits and clicks, commands,
uploads, scene clicks and drags) are dropped at the front; only its own camera and the answers
to the server's requests pass (`messages.py`).

Which browser pressed a button: the front opens one upstream websocket per browser and puts a
fresh random connection id in its handshake header (`X-Cellteach-Conn`). The app reads that
header from viser's connection for the `ClientHandle` of a callback (`Access.peer`), so every
`event.client` maps to its role, without a second channel and without trusting the browser.
A websocket that reaches viser's loopback port without an id the front issued is closed at
once. Motion authority is held by one operator page at a time: the rule is the session's
(`assistant.session.motion_hold`), the gate only says which pages are operators
(`web.authority`); the page also checks it in `web.actions` to word a refusal; Collision! and
Stop stay available to every operator. The front passes websocket pings and pongs through, so
the heartbeat of the holder's page (`web.heartbeat`) reaches the browser, not the front.

    app = web.serve(session, gate=GateConfig(host="0.0.0.0", port=8080,
                                             tokens=AccessTokens.new()))
    print(app.url, app.access.code(Role.OPERATOR), app.access.code(Role.VIEWER))

Imports: aiohttp, viser, the standard library and `web` helpers below it; never `assistant`,
`workflow` or `vision` at run time (it knows nothing of robots beyond "this control moves
it"; the motion hold is a type only).
"""

from web.gate.access import Access
from web.gate.config import GateConfig, is_loopback
from web.gate.tokens import AccessTokens, Role, TokenFileError

__all__ = ["Access", "AccessTokens", "GateConfig", "Role", "TokenFileError", "is_loopback"]
