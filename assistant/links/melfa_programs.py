"""Program handling for `MelfaLink`: the controller's program directory, upload through the
edit slot (``NEW`` / ``LOAD`` / ``EMDAT`` / ``SAVE``) under a name not yet taken, and running
a stored program until it ends.

Kept apart from the command-port session in `assistant.links.melfa`, which mixes
`MelfaPrograms` into `MelfaLink`; the streaming program is stored the same way.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from assistant.links import melfa_protocol as mp
from assistant.links.link import LinkError, LinkEvent, LinkEventKind
from assistant.links.melfa_protocol import Reply


class MelfaPrograms:
    """Mixin of `MelfaLink`: list, upload and run programs stored on the controller.

    The host supplies `command`, `read_state`, `_read_joints`, `_stop_stream`,
    `_controller_stopped`, `_emit` and the attributes below.
    """

    slot: int
    status_period_s: float
    _connected: bool
    _stop: threading.Event
    _pressed: str | None
    _last_q: np.ndarray

    def program_names(self) -> list[str]:
        """Programs stored on the controller (PDIR pages until an empty one)."""
        names: list[str] = []
        for page in range(256):
            body = self.command("PDIR" if page == 0 else f"PDIR{page:02X}").body
            if not body.strip():
                break
            names.append(body.split(";", 1)[0].split(".", 1)[0].upper())
        return names

    def _store_program(self, name: str, lines: list[str]) -> None:
        chunks = mp.emdat_chunks(lines)
        if not chunks:
            raise LinkError("program is empty")
        self.command("NEW")
        self.command(f"LOAD={name}")
        self.request_edit("ECLR")
        for chunk in chunks:
            self.request_edit(f"EMDAT{chunk}")
        self.command("SAVE")

    def request_edit(self, command: str) -> Reply:
        """A command for the edit slot (TASKMAX + 1), as program editing requires."""
        slot, self.slot = self.slot, mp.EDIT_SLOT
        try:
            return self.command(command)
        finally:
            self.slot = slot

    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Store a program under a name not yet on the controller; returns that name.

        The name is `name` made MELFA-safe (A-Z, 0-9, at most 6 characters) plus a two-digit
        number chosen against the controller's directory, so a second upload never replaces
        (or is confused with) the first - the flaw of the 002 bridge.
        """
        if not self._connected:
            raise LinkError("MELFA link is not connected; call connect() first")
        try:
            lines = mp.program_lines(files)
        except UnicodeDecodeError as exc:
            raise LinkError(f"program files must be ASCII: {exc}") from None
        taken = set(self.program_names())
        base = mp.sanitize_program_name(name, max_len=6)
        unique = next((f"{base}{n:02d}" for n in range(1, 100) if f"{base}{n:02d}" not in taken),
                      None)
        if unique is None:
            raise LinkError(f"controller already holds 99 programs named {base}NN")
        self._stop_stream()
        self._store_program(unique, lines)
        if unique not in self.program_names():
            raise LinkError(f"controller did not list {unique} after SAVE")
        return unique

    def run_program(self, name: str, *, wait: bool = True,
                    on_poll: Callable[[], None] | None = None,
                    timeout_s: float = 600.0) -> LinkEvent:
        """Run a stored program in slot 1 (cycle mode); optionally wait until it ends."""
        if not self._connected:
            raise LinkError("MELFA link is not connected; call connect() first")
        self._stop_stream()
        self._stop.clear()
        self._pressed = None
        self.command("SLOTINIT")
        self.command(f"RUN{mp.sanitize_program_name(name, max_len=12)};1")
        if not wait:
            return LinkEvent(LinkEventKind.MOVED, self._last_q.copy(), time.monotonic(),
                             f"{name} started")
        deadline = time.monotonic() + timeout_s
        while True:
            st = self.read_state()
            if on_poll:
                on_poll()
            if st.error_code:
                return self._controller_stopped(st.error_code, f"DSTATE error "
                                                f"{st.error_code:04d}", st.step)
            if self._stop.is_set():
                self.command("STOP")
                return self._controller_stopped(0, "STOP", st.step, stopped=True, message="")
            if not st.running:
                self._last_q = self._read_joints()
                ev = LinkEvent(LinkEventKind.REACHED, self._last_q.copy(), time.monotonic(),
                               f"{name} finished")
                self._emit(ev)
                return ev
            if time.monotonic() > deadline:
                raise LinkError(f"{name} still running after {timeout_s:.0f} s")
            time.sleep(max(self.status_period_s, 0.01))
