"""The gate as the page sees it: the role of each viser client, the motion authority, and the
per-browser "Motion authority" panel.

The role of a `ClientHandle` comes from the connection id the front put in the upstream
handshake (see `web.gate`); it is read from viser's live connection (a viser internal, like
`web.uploads`): if that ever moves, every client is unknown and refused - it fails closed.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any

import viser

from web.gate.authority import AuthorityState, MotionAuthority
from web.gate.config import GateConfig
from web.gate.front import CONN_HEADER, Front, Peer
from web.gate.tokens import Role

if TYPE_CHECKING:
    from web.app import App

log = logging.getLogger(__name__)

VIEW_ONLY = "This page is view only: it cannot change or move anything."


class Access:
    def __init__(self, front: Front):
        self.front = front
        self.authority = MotionAuthority()
        self._app: App | None = None
        self._peers: dict[int, Peer] = {}
        self._names: dict[int, str] = {}
        self._panels: dict[int, AuthorityPanel] = {}
        self._count = 0
        self._lock = threading.Lock()
        self.authority.subscribe(self._show)

    @staticmethod
    def create(cfg: GateConfig, upstream_port: int) -> Access:
        """The gate for viser on `upstream_port`; a bad certificate raises ValueError here.
        `open()` it once the page is attached (then the front listens)."""
        return Access(Front(cfg, upstream_port))

    def open(self) -> None:
        """Listen on the exposed address (OSError if it cannot)."""
        self.front.start()

    def stop(self) -> None:
        self.front.stop()

    @property
    def url(self) -> str:
        return self.front.url

    def code(self, role: Role) -> str:
        """The access code of `role` (entered on the sign-in page; print it, never log it)."""
        return self.front.code(role)

    # ------------------------------------------------------------------ clients
    def attach(self, app: App) -> None:
        self._app = app
        app.server._websock_server.on_client_connect(self._admit)  # noqa: SLF001
        app.server.on_client_connect(self._joined)
        app.server.on_client_disconnect(self._left)

    def _connection(self, client_id: int) -> Any:
        assert self._app is not None
        try:
            return self._app.server._websock_server._live_connections.get(client_id)  # noqa: SLF001
        except AttributeError:
            log.error("viser internals changed: no client can be identified (all refused)")
            return None

    def peer(self, client_id: int) -> Peer | None:
        """Who is behind a viser client (None: not admitted by the front)."""
        with self._lock:
            known = self._peers.get(client_id)
        if known is not None:
            return known
        conn = self._connection(client_id)
        try:
            conn_id = conn.request.headers.get(CONN_HEADER) if conn is not None else None
        except AttributeError:
            conn_id = None
        found = self.front.peer(conn_id)
        if found is not None:
            with self._lock:
                self._peers[client_id] = found
        return found

    async def _admit(self, conn: Any) -> None:
        """Every websocket viser accepts: one the front did not open is closed at once."""
        if self.peer(conn.client_id) is None:
            live = self._connection(conn.client_id)
            log.warning("closed a websocket that did not come through the front")
            if live is not None:
                await live.close(1008, "connect through the cellteach front")

    def name(self, client_id: int | None) -> str:
        return "nobody" if client_id is None else self._names.get(client_id, "an operator")

    def _joined(self, client: viser.ClientHandle) -> None:
        peer = self.peer(client.client_id)
        if peer is None or peer.role != Role.OPERATOR:
            return
        with self._lock:
            self._count += 1
            self._names[client.client_id] = f"operator {self._count} ({peer.address})"
            self._panels[client.client_id] = AuthorityPanel(self, client)
        if not self.authority.joined(client.client_id):
            self._show(self.authority.state)

    def _left(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._peers.pop(client.client_id, None)
            self._panels.pop(client.client_id, None)
        self.authority.left(client.client_id)

    def _show(self, state: AuthorityState) -> None:
        with self._lock:
            panels = list(self._panels.values())
        for p in panels:
            p.show(state)

    # ------------------------------------------------------------------ the check
    def refusal(self, client: viser.ClientHandle, *, motion: bool) -> str:
        """Why `client` may not do this ('' if it may)."""
        peer = self.peer(client.client_id)
        if peer is None or peer.role != Role.OPERATOR:
            return VIEW_ONLY
        if motion and not self.authority.holds(client.client_id):
            holder = self.authority.state.holder
            if holder is None:
                return "Nobody holds motion authority: take it under Motion authority, then " \
                    "try again."
            return f"Motion authority is with {self.name(holder)}: ask for it under Motion " \
                "authority (they hand it over), then try again. Collision! and Stop work " \
                "from every operator page."
        return ""


class AuthorityPanel:
    """One operator page's "Motion authority" folder (client-scoped: only that page sees it)."""

    def __init__(self, access: Access, client: viser.ClientHandle):
        self.access = access
        self.me = client.client_id
        gui = client.gui
        auth = access.authority
        with gui.add_folder("Motion authority", order=0.5):
            self.status = gui.add_markdown("")
            self.take = gui.add_button("Take motion authority", visible=False)
            self.ask = gui.add_button("Ask for motion authority", visible=False)
            self.hand = gui.add_button("Hand over motion authority", visible=False)
            self.release = gui.add_button("Release motion authority", visible=False)
        self.take.on_click(lambda e: auth.take(self.me))
        self.ask.on_click(lambda e: auth.request(self.me))
        self.hand.on_click(lambda e: auth.hand_over(self.me))
        self.release.on_click(lambda e: auth.release(self.me))
        self.show(auth.state)

    def show(self, st: AuthorityState) -> None:
        mine, name = st.holder == self.me, self.access.name
        if mine:
            text = "**You hold motion authority**: Move, Execute, Resume and Explore move " \
                "the robot from this page."
            if st.requests:
                text += f"\n\n{name(st.requests[0])} asks for it."
        elif st.holder is None:
            text = "Nobody holds motion authority: take it to move the robot from this page."
        else:
            text = f"{name(st.holder)} holds motion authority. Collision! and Stop work here " \
                "too."
            if self.me in st.requests:
                text += "\n\nYou asked for it: they can hand it over."
        try:
            self.status.content = text
            self.take.visible = st.holder is None
            self.ask.visible = st.holder not in (None, self.me) and self.me not in st.requests
            self.hand.visible = mine and bool(st.requests)
            self.release.visible = mine
        except Exception:  # noqa: BLE001 - the page is closing
            log.debug("authority panel of a closing page", exc_info=True)
