"""Step 7: the program in a dialect, and its upload to the robot.

A part of the `Session`, composed rather than mixed in (`Session.exporter`): it owns the
exported program; the session's `export` and `upload_program` verbs hand over to it, and it
reaches the rest of the session only through the parts' contract (`PartContract`)."""

from __future__ import annotations

from typing import Any

from assistant.session.contract import PartContract
from assistant.session.events import Notice, ProgramReady
from assistant.session.types import SessionError


class ExportPart:
    """Step 7: the program in a dialect, and its upload to the robot."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: The last exported program (`export.ExportResult`); None until the first export,
        #: and again when a new plan or an edit makes it stale.
        self.program: Any = None
        #: The dialect last written (saved with the session; the default of `export`).
        self.export_dialect = "melfa"

    def export(self, dialect: str | None = None, *, name: str | None = None,
               frame: str | None = None, count: bool = True) -> Any:
        """Write the planned mission as a robot program; returns the files (and a zip).
        With `frame` (a named, e.g. calibrated, frame) the targets are written in that frame
        (KRL $BASE, RAPID wobj, URScript pose_trans, ...) instead of the robot base.
        `count=False`: written by the page on its own (not an operator action)."""
        from assistant.export import export_files, get_dialect, program_from_trajectory
        from assistant.export.program import Frame

        s = self._core
        with s.action("export the program", ("export", "plan"), undoable=False,
                      scene="program", count=count):
            if s.trajectory is None:
                raise SessionError("Plan the mission first: there is no verified trajectory yet")
            d = get_dialect(dialect or self.export_dialect)
            work = None
            if frame is not None:
                s.objects.frame(frame)
                work = Frame(frame, s.cell.T_base_frame(frame))
            program = program_from_trajectory(s.trajectory, s.robot,
                                              name=name or "MISSION", work=work)
            result = export_files(program, d, s.robot)
            self.export_dialect = d.name
            self.program = result
        for line in result.renames:  # said once, where the operator looks for the name
            s.bus.emit(Notice(f"Renamed for the controller: {line}"))
        s.bus.emit(ProgramReady(d.name, tuple(f.name for f in result.files)))
        return result

    def upload_program(self) -> str:
        """Send the exported program to the robot controller; returns its name there."""
        s = self._core
        with s.action("upload the program", ("export",), undoable=False):
            if self.program is None:
                raise SessionError("Export the program first")
            files = {f.name: f.data for f in self.program.files}
            name = s.setup.link().upload_program(self.program.files[0].name.split(".")[0], files)
        s.bus.emit(Notice(f"program uploaded to the robot as {name}"))
        return name
