"""Motion authority as the pages see it: each operator page's "Motion authority" folder, and
the pages' arrivals and departures told to the session's `MotionHold` (the rule itself lives
there, where every motion passes).

The first operator page to arrive holds authority; closing or reloading the holder's page lets
it go (the robot stops). A page served on this machine only (no gate) is an operator page;
behind the gate (`web.gate`) the gate says which pages are operators.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

if TYPE_CHECKING:
    from assistant.session.motion_hold import HoldState, MotionHold

log = logging.getLogger(__name__)


class PageAuthority:
    """Tells `hold` which operator pages come and go; one folder per operator page."""

    def __init__(self, hold: MotionHold, *,
                 is_operator: Callable[[viser.ClientHandle], bool] = lambda c: True,
                 where: Callable[[viser.ClientHandle], str] = lambda c: ""):
        self.hold = hold
        self._is_operator = is_operator
        self._where = where
        self._names: dict[int, str] = {}
        self._panels: dict[int, AuthorityPanel] = {}
        self._count = 0
        self._lock = threading.Lock()
        hold.subscribe(self._show)

    def attach(self, server: viser.ViserServer) -> None:
        server.on_client_connect(self.joined)
        server.on_client_disconnect(self.left)

    def name(self, client_id: int | None) -> str:
        return "nobody" if client_id is None else self._names.get(client_id, "an operator")

    def joined(self, client: viser.ClientHandle) -> None:
        if not self._is_operator(client):
            return
        with self._lock:
            self._count += 1
            where = self._where(client)
            self._names[client.client_id] = f"operator {self._count}" + \
                (f" ({where})" if where else "")
            self._panels[client.client_id] = AuthorityPanel(self, client)
        if not self.hold.joined(client.client_id):
            self._show(self.hold.state)

    def left(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._panels.pop(client.client_id, None)
        self.hold.left(client.client_id)

    def _show(self, state: HoldState) -> None:
        with self._lock:
            panels = list(self._panels.values())
        for p in panels:
            p.show(state)


class AuthorityPanel:
    """One operator page's "Motion authority" folder (client-scoped: only that page sees it)."""

    def __init__(self, pages: PageAuthority, client: viser.ClientHandle):
        self.pages = pages
        self.me = client.client_id
        gui = client.gui
        hold = pages.hold
        with gui.add_folder("Motion authority", order=0.5):
            self.status = gui.add_markdown("")
            self.take = gui.add_button("Take motion authority", visible=False)
            self.ask = gui.add_button("Ask for motion authority", visible=False)
            self.hand = gui.add_button("Hand over motion authority", visible=False)
            self.release = gui.add_button("Release motion authority", visible=False)
        for button, verb in ((self.take, hold.take), (self.ask, hold.request),
                             (self.hand, hold.hand_over), (self.release, hold.release)):
            button.on_click(self._calling(verb))
        self.show(hold.state)

    def _calling(self, verb: Callable[[int], object]) -> Callable[[Any], None]:
        """A button's callback: the hold's verb for this page (what it returns - did the
        holder change? - the page learns from the hold's own event)."""
        def call(_event: Any) -> None:
            verb(self.me)

        return call

    def show(self, st: HoldState) -> None:
        mine, name = st.holder == self.me, self.pages.name
        if mine:
            text = "**You hold motion authority**: the robot moves only while this page is " \
                "open and connected."
            if not st.present:
                text += "\n\nThis page's connection is not answering: the robot waits."
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
