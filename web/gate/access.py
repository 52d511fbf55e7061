"""The gate as the page sees it: the role of each viser client, and which pages count as
operators for motion authority (the rule is the session's `MotionHold`; the per-page folder is
`web.authority`).

The role of a `ClientHandle` comes from the connection id the front put in the upstream
handshake (see `web.gate`); it is read from viser's live connection (a viser internal, like
`web.uploads`): if that ever moves, every client is unknown and refused - it fails closed.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any

import viser

from web.authority import PageAuthority
from web.gate.config import GateConfig
from web.gate.front import CONN_HEADER, Front, Peer
from web.gate.tokens import Role

if TYPE_CHECKING:
    from assistant.session.motion_hold import MotionHold
    from web.app import App

log = logging.getLogger(__name__)

VIEW_ONLY = "This page is view only: it cannot change or move anything."


class Access:
    def __init__(self, front: Front):
        self.front = front
        self._app: App | None = None
        self._pages: PageAuthority | None = None
        self._peers: dict[int, Peer] = {}
        self._lock = threading.Lock()

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
    def attach(self, app: App) -> PageAuthority:
        """Guard `app`'s server; returns who holds motion authority among its operator pages."""
        self._app = app
        app.server._websock_server.on_client_connect(self._admit)  # noqa: SLF001
        self._pages = PageAuthority(app.session.hold, is_operator=self._is_operator,
                                    where=self._address)
        self._pages.attach(app.server)
        app.server.on_client_disconnect(self._left)
        return self._pages

    @property
    def authority(self) -> MotionHold:
        assert self._pages is not None, "attach() first"
        return self._pages.hold

    def _is_operator(self, client: viser.ClientHandle) -> bool:
        peer = self.peer(client.client_id)
        return peer is not None and peer.role == Role.OPERATOR

    def _address(self, client: viser.ClientHandle) -> str:
        peer = self.peer(client.client_id)
        return "" if peer is None else peer.address

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
        return self._pages.name(client_id) if self._pages is not None else "nobody"

    def _left(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._peers.pop(client.client_id, None)

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
