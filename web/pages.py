"""Controls each open page gets for itself (viser's client-scoped handles), by role.

Everything else on the page is server-wide: every browser, a viewer's too, receives every
value of it. What only the page that typed or asked may see lives here instead - a password as
it is typed, the session folder's path, the page's own status line - built once per page when
it connects (`add`) and dropped when it leaves. A builder marked `operators_only` never runs
for a viewer's page, so its values are never sent there at all.

The role comes from the gate (`web.gate.Access`); without a gate (loopback) every page is an
operator's.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import viser

from web.notify import OPERATOR, VIEWER

if TYPE_CHECKING:
    from web.app import App

log = logging.getLogger(__name__)

T = TypeVar("T")


@dataclass
class PerPage(Generic[T]):
    """What one builder made for each page that has it, by viser client id."""

    build: Callable[[viser.ClientHandle], T]
    operators_only: bool
    made: dict[int, T]

    def of(self, client: viser.ClientHandle | None) -> T | None:
        """What this page has (None: not built for it, or not a page of this server)."""
        return self.made.get(getattr(client, "client_id", None))  # type: ignore[arg-type]

    def all(self) -> list[T]:
        return list(self.made.values())


class Pages:
    def __init__(self, app: App):
        self._app = app
        self._lock = threading.Lock()
        self._builders: list[PerPage[Any]] = []
        app.server.on_client_connect(self._joined)
        app.server.on_client_disconnect(self._left)

    def role(self, client: viser.ClientHandle) -> str:
        """OPERATOR or VIEWER (behind the gate: a client the front did not admit is a
        viewer - it may see nothing private)."""
        access = getattr(self._app, "access", None)
        if access is None:
            return OPERATOR
        from web.gate.tokens import Role

        peer = access.peer(client.client_id)
        return OPERATOR if peer is not None and peer.role == Role.OPERATOR else VIEWER

    def add(self, build: Callable[[viser.ClientHandle], T], *, operators_only: bool = False
            ) -> PerPage[T]:
        """Build `build(client)` for every page (already open and to come)."""
        per = PerPage(build, operators_only, {})
        with self._lock:
            self._builders.append(per)
        for client in list(self._app.server.get_clients().values()):
            self._build(per, client)
        return per

    def _build(self, per: PerPage[Any], client: viser.ClientHandle) -> None:
        if per.operators_only and self.role(client) != OPERATOR:
            return
        if client.client_id in per.made:
            return
        try:
            per.made[client.client_id] = per.build(client)
        except Exception:  # noqa: BLE001 - a page closing while its controls are built
            log.debug("building a page's own controls failed", exc_info=True)

    def _joined(self, client: viser.ClientHandle) -> None:
        with self._lock:
            builders = list(self._builders)
        for per in builders:
            self._build(per, client)

    def _left(self, client: viser.ClientHandle) -> None:
        with self._lock:
            for per in self._builders:
                per.made.pop(client.client_id, None)
