"""Assemble the page: toolbar, one panel per workflow step, the 3-D scene, all over ONE session.

All GUI and scene handles are server-wide, so every open browser shows the same state and an
action in one page appears in the others. The session's events are applied by one UI thread
(`EventPump`); page callbacks call session methods through `Actions` (guarded, errors shown).
Off loopback the page sits behind the gate (`web.gate`): viser on 127.0.0.1, the front on the
exposed address, and `App.access` says which page may act and which may move the robot.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

import viser

from assistant.session import Session
from assistant.session.events import (
    CollisionRecorded,
    ErrorRaised,
    Event,
    ExecutionFinished,
    Notice,
    PlanReady,
    ProgramReady,
    SaveStateChanged,
    StateChanged,
)
from web.actions import Actions
from web.authority import PageAuthority
from web.gate import Access, GateConfig
from web.heartbeat import Heartbeat
from web.notify import Notifier
from web.pages import Pages
from web.panels.base import StepPanel
from web.panels.cad import CadPanel
from web.panels.cameras import CamerasPanel
from web.panels.explore import ExplorePanel
from web.panels.export import ExportPanel
from web.panels.jog import JogPanel
from web.panels.paths import PathsPanel
from web.panels.place import PlacePanel
from web.panels.plan import PlanPanel
from web.panels.session_file import SessionPanel
from web.panels.setup import SetupPanel
from web.panels.teach import TeachPanel
from web.panels.view import ViewPanel
from web.pump import EventPump
from web.scene.layers import SceneLayers
from web.toolbar import Toolbar
from web.uploads import DEFAULT_MAX_UPLOAD_MB, install_early_limit
from web.wording import goal_reached

log = logging.getLogger(__name__)

#: The simulated robot in the page runs at most this fast (x real time): a person watches it
#: and presses Collision! in time. Scripts keep the sample's faster pace.
OPERATOR_PACE = 1.0


@dataclass
class App:
    """The running page over one session (replaceable by loading another session)."""

    server: viser.ViserServer
    max_upload_bytes: int
    _session: Session
    #: The gate in front of the page (None on loopback: open, as before).
    access: Access | None = None
    notifier: Notifier = field(init=False)
    pages: Pages = field(init=False)
    actions: Actions = field(init=False)
    pump: EventPump = field(init=False)
    scene_layers: SceneLayers = field(init=False)
    toolbar: Toolbar = field(init=False)
    #: Which operator page holds motion authority (`web.authority`).
    authority: PageAuthority = field(init=False)
    heartbeat: Heartbeat = field(init=False)
    panels: dict[str, StepPanel] = field(init=False)
    #: The workflow step the page shows (a step change makes earlier errors stale).
    _shown_state: str = field(init=False, default="")
    _swap_lock: threading.Lock = field(default_factory=threading.Lock, init=False)
    #: An execution just finished well: its final PlanReady is no news to announce.
    _executed: bool = field(init=False, default=False)
    #: The session's mode as last dispatched: a plan made while the robot moves is the run's
    #: own (its exploring plan, a re-plan), not news to announce.
    _mode: str = field(init=False, default="")

    def __post_init__(self) -> None:
        operator_pace(self._session)
        self.server.gui.configure_theme(control_width="large", show_share_button=False,
                                        brand_color=(40, 110, 200))
        # viser's widest preset is ~350 px: the tables and the program preview need room.
        self.server.gui.main_panel.set_width(PANEL_WIDTH_PX)
        self.pages = Pages(self)
        self.notifier = Notifier(self.server, audience=self.pages.role, redact=self.redact)
        self._shown_state = self._session.machine.state
        self.actions = Actions(self)
        self.pump = EventPump(self._dispatch, on_queue=self._on_emit,
                              settled=lambda: self._session.settled())
        self.scene_layers = SceneLayers(self)
        self.toolbar = Toolbar(self)
        panels: tuple[StepPanel, ...] = (
            SetupPanel(self), CadPanel(self), PlacePanel(self), CamerasPanel(self),
            TeachPanel(self), PathsPanel(self), ExplorePanel(self), PlanPanel(self),
            ExportPanel(self), JogPanel(self), ViewPanel(self), SessionPanel(self))
        self.panels = {p.title: p for p in panels}
        install_early_limit(self)
        # The enabling switch: only the present holder's page moves the robot (the session's
        # rule); the pages tell it who comes and goes, the heartbeat who falls silent.
        if self.access is not None:
            self.authority = self.access.attach(self)
        else:
            self.authority = PageAuthority(self._session.hold)
            self.authority.attach(self.server)
        self._session.hold.enforce()
        self.heartbeat = Heartbeat(self.server, self._session.hold)
        self.heartbeat.start()
        self.pump.attach(self._session.bus)
        self.refresh()

    # ------------------------------------------------------------------ the session
    @property
    def session(self) -> Session:
        return self._session

    def replace_session(self, new: Session) -> None:
        """Show another session (a loaded one) in every page."""
        with self._swap_lock:
            old = self._session
            self.pump.detach()
            old.close()  # its robot, link and cameras stop with it
            new.adopt_hold(old.hold)  # the pages' motion authority carries over
            self._session = new
            operator_pace(new)
            self.pump.attach(new.bus)
        self.refresh()

    def redact(self, text: str) -> str:
        """Text every page sees, without the session folder's path (a viewer's page gets what
        watching needs, not where the files are)."""
        folder = self._session.folder
        if folder is not None:
            for form in sorted({str(folder), str(folder.expanduser().resolve())}, key=len,
                               reverse=True):
                text = text.replace(form, "the session folder")
        return text

    # ------------------------------------------------------------------ redraw
    def refresh(self) -> None:
        """Redraw everything from the session (queued on the UI thread)."""
        self.pump.post(self._refresh_now)

    def _refresh_now(self) -> None:
        self.scene_layers.refresh()
        state = self._session.machine.state
        for p in self.panels.values():
            p.show_for(state)
            p.refresh()
        self.toolbar.refresh()

    def _on_emit(self, ev: Event) -> None:
        """On the emitting thread, before the action returns: remember errors for dedup."""
        if isinstance(ev, ErrorRaised):
            self.notifier.remember(ev.message)

    def _dispatch(self, ev: Event) -> None:
        """Apply one event on the UI thread: scene first, then panels, then the toolbar."""
        if isinstance(ev, SaveStateChanged):
            self.toolbar.saved(ev.saved, ev.reason)
        self.scene_layers.on_event(ev)
        if isinstance(ev, StateChanged):
            if ev.mode == "moving" and self._mode != "moving":
                self.notifier.clear_done()  # a run starts: "planned" and the like are history
            self._mode = ev.mode
        if isinstance(ev, StateChanged):
            entered = ev.state != self._shown_state
            if entered:  # the step moved on: earlier errors are stale
                self._shown_state = ev.state
                self.notifier.clear_errors()
            for p in self.panels.values():
                p.show_for(ev.state)
            if entered:
                for p in self.panels.values():
                    if ev.state in p.steps:
                        p.on_enter()
        for p in self.panels.values():
            p.on_event(ev)
        self.toolbar.on_event(ev)
        if isinstance(ev, ErrorRaised):
            self.notifier.error(ev.message, ev.hint)
        elif isinstance(ev, Notice):
            key = "pointer" if ev.message.startswith("pointer") else None
            self.notifier.notice(ev.message, key=key)
        elif isinstance(ev, CollisionRecorded):
            self.notifier.notice(f"Collision #{ev.count} recorded ({ev.source}): that posture "
                                 "is now known as blocked.", key="collision")
        elif isinstance(ev, ExecutionFinished):
            self._executed = ev.ok
            if ev.ok:
                self.notifier.success(goal_reached(self._session.mission.goal,
                                                   ev.summary))
        elif isinstance(ev, PlanReady):
            if self._executed:  # the verified final plan of a run: announced as the goal
                self._executed = False
            elif self._mode != "moving":
                self.notifier.success("The mission is planned: the path is drawn in the scene.")
        elif isinstance(ev, ProgramReady):
            self.notifier.success(f"{ev.dialect} program written: {', '.join(ev.files)}")

    # ------------------------------------------------------------------ lifetime
    @property
    def url(self) -> str:
        if self.access is not None:
            return self.access.url
        host = self.server.get_host()
        shown = "127.0.0.1" if host in ("0.0.0.0", "") else host
        return f"http://{shown}:{self.server.get_port()}"

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Until every queued session event has reached the page's handles."""
        return self.pump.wait_idle(timeout)

    def stop(self) -> None:
        """Stop the page; the robot, link and cameras of the session stop too."""
        self.heartbeat.stop()
        if self.access is not None:
            self.access.stop()
        self.pump.stop()
        self._session.close()
        self.server.stop()


#: Wide enough for the parts/locations tables and most program lines unwrapped.
PANEL_WIDTH_PX = 520


def operator_pace(session: Session) -> None:
    """A sped-up simulated robot (a sample's 20x, for scripts) runs in real time in the page,
    and halts against what the model does not know until the operator presses Collision!."""
    ls = session.link_settings
    if ls.kind == "simulated" and ls.time_scale > OPERATOR_PACE and \
            session.machine.mode.value == "idle":
        session.set_simulation_speed(OPERATOR_PACE, count=False)
    # A person presses Collision! in the page: the simulated robot halts and waits for it.
    session.set_operator_confirms_contacts(True)


def build_app(session: Session, server: viser.ViserServer, *,
              max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB, access: Access | None = None
              ) -> App:
    """The page for `session` on an existing viser server (behind `access` if given)."""
    if max_upload_mb <= 0:
        raise ValueError("max_upload_mb must be > 0")
    return App(server, int(max_upload_mb * 2**20), session, access)


def serve(session: Session, *, host: str = "127.0.0.1", port: int = 8080,
          max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB, gate: GateConfig | None = None) -> App:
    """Start the page on host:port (127.0.0.1 by default: only this computer can connect).

    With `gate` the page is served by the authenticating front on `gate.host:gate.port` and
    viser listens on a free loopback port behind it (host/port are then not used).
    Returns at once; the server runs on background threads until `App.stop()`. If the port
    is taken the next ones are tried - `App.url` is where it really listens.
    """
    if gate is not None:
        if max_upload_mb <= 0:
            raise ValueError("max_upload_mb must be > 0")
        gate.max_upload_bytes = int(max_upload_mb * 2**20)
        host, port = "127.0.0.1", 0
    server = viser.ViserServer(host=host, port=port, label="cellteach", verbose=False)
    access: Access | None = None
    try:
        if gate is not None:
            access = Access.create(gate, server.get_port())
        app = build_app(session, server, max_upload_mb=max_upload_mb, access=access)
    except BaseException:
        server.stop()
        raise
    try:
        if access is not None:
            access.open()  # only now: every client it lets in meets an attached page
        return app
    except BaseException:
        app.stop()
        raise
