"""Step 7 - export: write the planned mission in a robot's language, preview every file and
download it (one file, or a zip when the dialect writes several)."""

from __future__ import annotations

from typing import Any

import viser

from assistant.export.registry import DIALECT_NAMES, get_dialect
from assistant.session.events import Event, ProgramReady, SceneChanged, StateChanged
from web.panels.base import Panel

DIALECT_LABELS = {"melfa": "Mitsubishi MELFA BASIC IV", "krl": "KUKA KRL",
                  "rapid": "ABB RAPID", "urscript": "Universal Robots URScript"}
PREVIEW_LINES = 400
BASE = "robot base"


def preview_markdown(result: Any) -> str:
    parts = []
    for f in result.files:
        text = f.data.decode("ascii", errors="replace")
        lines = text.splitlines()
        more = f"\n... {len(lines) - PREVIEW_LINES} more lines" if len(lines) > PREVIEW_LINES \
            else ""
        body = "\n".join(lines[:PREVIEW_LINES]).replace("```", "'''")
        parts.append(f"**{f.name}** ({len(f.data):,} bytes)\n\n```\n{body}{more}\n```")
    return "\n\n".join(parts)


def cycle_markdown(result: Any) -> str:
    """The predicted total and a table of seconds per mission step (as the operator named it)."""
    ct = getattr(result, "cycle_time", None)
    if ct is None:
        return "*No cycle time predicted for this program.*"
    rows = [f"| {(step or '-').replace('|', '/')} | {sec:.2f} |" for step, sec in ct.by_step()]
    return "\n".join([f"Predicted cycle time **{ct.total_s:.1f} s**: a prediction from the "
                      "robot's joint speed/acceleration limits and the programmed speeds, not "
                      "measured on a controller.", "", "| step | s |", "|---|---:|", *rows])


class ExportPanel(Panel):
    title = "Export program"
    steps = ("export",)

    def build(self) -> None:
        g = self.gui
        self.dialect = g.add_dropdown("Robot language",
                                      tuple(DIALECT_LABELS.get(d, d) for d in DIALECT_NAMES))
        self.frame = g.add_dropdown("Positions in", (BASE,),
                                    hint="The robot base, or a calibrated frame (KRL $BASE, "
                                         "RAPID wobj, URScript pose_trans, ...)")
        self.write = g.add_button("Write program", icon=viser.Icon.FILE_CODE)
        self.summary = g.add_markdown("")
        with g.add_folder("Cycle time (predicted)"):
            self.cycle = g.add_markdown("")
        self.download = g.add_button("Download", icon=viser.Icon.DOWNLOAD, disabled=True,
                                     color="green")
        with g.add_folder("Program preview"):
            self.preview = g.add_markdown("*Write the program to see it here.*")
        self.bind(self.write, lambda e: self._write())
        self.bind(self.download, self._download)

    def _dialect(self) -> str:
        return next((k for k, v in DIALECT_LABELS.items() if v == self.dialect.value),
                    self.dialect.value)

    def _write(self) -> None:
        frame = None if self.frame.value == BASE else self.frame.value
        self.session.export(self._dialect(), frame=frame)

    def _download(self, event: viser.GuiEvent) -> None:
        result = self.session.program
        if result is None:
            raise ValueError("write the program first")
        d = result.download
        event.client.send_file_download(d.name, d.data, save_immediately=True)

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
        self.write.disabled = (s.trajectory is None or s.machine.mode.value != "idle"
                               or not langs)
        if not langs:
            self.summary.content = (f"*No robot language here writes a {s.robot.dof}-axis "
                                    "arm; the plan is verified and saved with the session.*")
            self.preview.content = ""
            self.cycle.content = ""
            return
        self.download.disabled = result is None
        if result is None:
            self.summary.content = "*No program yet.*" if s.trajectory is not None else \
                "*Plan the mission first (step 6).*"
            self.preview.content = "*Write the program to see it here.*"
            self.cycle.content = ""
            return
        counts = ", ".join(f"{n} {k}" for k, n in sorted(result.primitive_counts.items()))
        name = result.download.name
        ct = getattr(result, "cycle_time", None)
        cycle = "" if ct is None else f" Predicted cycle time **{ct.total_s:.1f} s**."
        self.summary.content = (f"**{DIALECT_LABELS.get(result.dialect, result.dialect)}**, "
                                f"{result.primitives} motions as written, the move to the "
                                f"start included ({counts}).{cycle} "
                                f"Download gives **{name}**.")
        self.cycle.content = cycle_markdown(result)
        self.preview.content = preview_markdown(result)
        label = DIALECT_LABELS.get(result.dialect)
        if label is not None and self.dialect.value != label:
            self.dialect.value = label

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, (ProgramReady, StateChanged)) or \
                isinstance(ev, SceneChanged) and ev.what in ("program", "all", "mission"):
            self.refresh()
