"""Step 7 - export: the program is written as the step opens, in full and coloured per dialect,
and one click downloads it (one file, or a zip when the dialect writes several).

The panel writes the program itself when the step shows a verified plan and no program (or the
plan changed since: the session then drops the program), and again whenever the operator picks
another language or frame. Writing runs on a worker thread of this panel, never on the UI
thread, one write at a time: a choice made while a write runs is written next (the newest
choice wins), so the program always ends in the language the dropdown shows.
"""

from __future__ import annotations

import threading
from functools import partial
from typing import Any

import viser

from assistant.export.registry import DIALECT_NAMES, get_dialect
from assistant.session.events import Event, ProgramReady, SceneChanged, StateChanged
from web.gui_value import set_value
from web.panels.base import Panel, busy_reason, gate, why_greyed
from web.program_view import program_html

DIALECT_LABELS = {"melfa": "Mitsubishi MELFA BASIC IV", "krl": "KUKA KRL",
                  "rapid": "ABB RAPID", "urscript": "Universal Robots URScript",
                  "fanuc": "FANUC TP (ASCII .LS)", "yaskawa": "Yaskawa INFORM (.JBI)"}
BASE = "robot base"
WRITE_HINT = "Write the program again in the chosen language and frame (it is written by " \
    "itself when this step opens and when either changes)"
NO_PROGRAM = "<i>The program appears here, written by itself, once the mission is planned " \
    "(step 6).</i>"


def cycle_markdown(result: Any) -> str:
    """The predicted total and a table of seconds per mission step (as the operator named it)."""
    ct = getattr(result, "cycle_time", None)
    if ct is None:
        return "*No cycle time predicted for this program.*"
    rows = [f"| {(step or '-').replace('|', '/')} | {sec:.2f} |" for step, sec in ct.by_step()]
    return "\n".join([f"Predicted cycle time **{ct.total_s:.1f} s**: a prediction from the "
                      "robot's joint speed/acceleration limits and the programmed speeds, not "
                      "measured on a controller.", "", "| step | s |", "|---|---:|", *rows])


def _content(handle: Any, text: str) -> None:
    if handle.content != text:
        handle.content = text


class ExportPanel(Panel):
    title = "Export program"
    steps = ("export",)

    def build(self) -> None:
        g = self.gui
        self.dialect = g.add_dropdown("Robot language",
                                      tuple(DIALECT_LABELS.get(d, d) for d in DIALECT_NAMES),
                                      hint="The program is written again in the language "
                                           "you choose")
        self.frame = g.add_dropdown("Positions in", (BASE,),
                                    hint="The robot base, or a calibrated frame (KRL $BASE, "
                                         "RAPID wobj, URScript pose_trans, FANUC UFRAME, "
                                         "...)")
        self.summary = g.add_markdown("")
        self.download = g.add_button("Download", icon=viser.Icon.DOWNLOAD, disabled=True,
                                     color="green")
        self.write = g.add_button("Write again", icon=viser.Icon.FILE_CODE, hint=WRITE_HINT)
        self.why = g.add_markdown("")
        with g.add_folder("Program preview"):
            self.preview = g.add_html(NO_PROGRAM)
        with g.add_folder("Cycle time (predicted)"):
            self.cycle = g.add_markdown("")
        self._lock = threading.Lock()
        #: The newest write asked for, (dialect, frame, page) - taken by the worker.
        self._pending: tuple[str, str | None, Any] | None = None
        self._worker: threading.Thread | None = None
        #: The plan an automatic write was started for (a failed one is not retried in a
        #: loop; the error is shown once and "Write again" or a new choice tries again).
        self._auto_for: object | None = None
        #: The program (or, without one, the session) the language dropdown was last set from.
        self._synced_to: object | None = None
        #: The program the preview shows.
        self._previewed: object | None = None
        self.bind(self.write, lambda e: self._request(e.client))
        self.bind(self.dialect, self._chosen)
        self.bind(self.frame, self._chosen)
        self.bind(self.download, self._download)

    # ------------------------------------------------------------------ writing
    def _dialect(self) -> str:
        return next((k for k, v in DIALECT_LABELS.items() if v == self.dialect.value),
                    self.dialect.value)

    @property
    def writing(self) -> bool:
        """A write is running or queued (the page says so; the dropdowns are not synced)."""
        with self._lock:
            return self._worker is not None

    def _request(self, client: viser.ClientHandle | None = None) -> None:
        """Write the program in the dropdowns' language and frame, off the UI thread."""
        if self.session.trajectory is None:
            raise ValueError("plan the mission first (step 6): there is nothing to write yet")
        frame = None if self.frame.value == BASE else self.frame.value
        with self._lock:
            self._pending = (self._dialect(), frame, client)
            if self._worker is None:
                self._worker = threading.Thread(target=self._work, name="cellteach-export",
                                                daemon=True)
                self._worker.start()
        self.app.refresh()  # "Writing ..." and the buttons wait

    def on_enter(self) -> None:
        """Entering step 7 writes the program when the plan has none: it is what the step is
        for, and the operator's first click here is Download. (Through `refresh`: the
        dropdowns show this session's choices before the write reads them.)"""
        self.refresh()

    def _write_if_needed(self) -> bool:
        """Start the automatic write when this step shows a plan without a program (once per
        plan: a failed write is not retried in a loop). True if it started."""
        s = self.session
        if (s.machine.state not in self.steps or s.trajectory is None or s.program is not None
                or s.machine.mode.value != "idle" or self.writing
                or self._auto_for is s.trajectory
                or not any(s.robot.dof in get_dialect(d).axis_counts for d in DIALECT_NAMES)):
            return False
        self._auto_for = s.trajectory
        self._request()
        return True

    def _chosen(self, event: viser.GuiEvent) -> None:
        """Another language or frame: written at once (before a plan there is nothing to write)."""
        if self.session.trajectory is not None:
            self._request(event.client)
        else:
            self.app.refresh()

    def _work(self) -> None:
        while True:
            with self._lock:
                job, self._pending = self._pending, None
                if job is None:
                    self._worker = None
                    break
            dialect, frame, client = job
            # errors become one notification, as for every page action
            self.app.actions.run(partial(self.session.export, dialect, frame=frame,
                                         count=client is not None), client)
        self.app.refresh()

    def _download(self, event: viser.GuiEvent) -> None:
        result = self.session.program
        if result is None:
            raise ValueError("write the program first")
        d = result.download
        if event.client is None:
            raise ValueError("no page to send the program to")
        event.client.send_file_download(d.name, d.data, save_immediately=True)

    # ------------------------------------------------------------------ drawing
    def refresh(self) -> None:
        s = self.session
        frames = (BASE, *s.cell.frames)
        if tuple(self.frame.options) != frames:
            self.frame.options = frames
        # only the languages whose controllers run this robot's axis count (URScript: 6)
        langs = tuple(DIALECT_LABELS.get(d, d) for d in DIALECT_NAMES
                      if s.robot.dof in get_dialect(d).axis_counts)
        if langs and tuple(self.dialect.options) != langs:
            self.dialect.options = langs
        result = s.program
        mode = s.machine.mode.value
        writing = self.writing
        # The dropdown follows a new program (or the session's choice when there is none) -
        # only when that changes, so a refresh never undoes a choice on its way to a write.
        marker = result if result is not None else s
        if not writing and marker is not self._synced_to:
            self._synced_to = marker
            shown = DIALECT_LABELS.get(result.dialect if result is not None
                                       else s.export_dialect)
            if shown in langs and self.dialect.value != shown:
                set_value(self.dialect, shown)
        if self._write_if_needed():  # e.g. a loaded session opened at step 7
            writing = True
        plan_first = "" if s.trajectory is not None else "plan the mission first (step 6)"
        why_write = busy_reason(mode) or plan_first or \
            ("" if langs else "no robot language here writes this arm")
        why_download = ("wait: the program is being written" if writing else
                        (why_write or "write the program first (Write again)")
                        if result is None else "")
        gate(self.write, why_write, WRITE_HINT)
        gate(self.download, why_download, "Download the program (a zip when it has several "
                                          "files)")
        _content(self.why, why_greyed({"Download": why_download, "Write again": why_write}))
        if not langs:
            _content(self.summary, f"*No robot language here writes a {s.robot.dof}-axis "
                                   "arm; the plan is verified and saved with the session.*")
            self._show_none("")
            _content(self.cycle, "")
            return
        if writing:
            _content(self.summary, f"*Writing the {self.dialect.value} program ...*")
        if result is None:
            if not writing:
                failed = s.trajectory is not None and self._auto_for is s.trajectory
                _content(self.summary, "*Plan the mission first (step 6).*"
                         if s.trajectory is None else "*No program: writing it failed (the "
                         "message says why). Choose another language or frame, or Write "
                         "again.*" if failed else "*No program yet.*")
            self._show_none(NO_PROGRAM)
            _content(self.cycle, "")
            return
        if not writing:
            _content(self.summary, summary_markdown(result))
        _content(self.cycle, cycle_markdown(result))
        if self._previewed is not result:  # the coloured text is made once per program
            self._previewed = result
            _content(self.preview, program_html(result))

    def _show_none(self, text: str) -> None:
        self._previewed = None
        _content(self.preview, text)

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, (ProgramReady, StateChanged)) or \
                isinstance(ev, SceneChanged) and ev.what in ("program", "all", "mission"):
            self.refresh()


def summary_markdown(result: Any) -> str:
    """What was written, how many motions, the predicted time and the download's name."""
    counts = ", ".join(f"{n} {k}" for k, n in sorted(result.primitive_counts.items()))
    ct = getattr(result, "cycle_time", None)
    cycle = "" if ct is None else f" Predicted cycle time **{ct.total_s:.1f} s**."
    # what the controller's rules changed (a split, joint values, blends), said as written
    notes = "".join(f"\n\n*Note:* {n}." for n in getattr(result, "notes", ()))
    return (f"**{DIALECT_LABELS.get(result.dialect, result.dialect)}**, {result.primitives} "
            f"motions as written, the move to the start included ({counts}).{cycle} "
            f"Download gives **{result.download.name}**.{notes}")
