"""Step 2: a cell-layout drawing (`assistant.cell.cad.layout`) - its parts placed as drawn and
its labelled locations taught, start and goal set, in one undoable action. The same layout
imported again replaces its parts and locations (the drawing was updated in CAD).

A part of the `Session`, composed (`Session.layout`): it has no state of its own: it adds a
drawing's parts and locations through `objects` and `teaching`; it reaches the rest of the
session only through the parts' contract (`PartContract`)."""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from assistant.cell.cad import CadImport, CadImportError, load_cad
from assistant.cell.cad.importer import read_cad_file
from assistant.cell.cad.layout import CellLayout, read_layout
from assistant.cell.model import CellObject, ObjectRole
from assistant.mission.model import LocationSource
from assistant.progress import Progress
from assistant.robots.model import UnreachableError
from assistant.session.contract import PartContract
from assistant.session.events import Notice, SceneChanged
from assistant.session.types import EDIT_CELL, SessionError, _safe_name
from assistant.transforms import pose_from_mm_deg

Array = np.ndarray


@dataclass(frozen=True)
class FileImport:
    """An upload under way (`LayoutPart.start_import_file`): what the file is, and its job."""

    #: The cell layout the drawing holds; None when the file is one part.
    layout: CellLayout | None
    #: The import's future: the layout's objects (a list), or (object, `CadImport`) of a part.
    future: Future


class LayoutPart:
    """Import a cell-layout DXF: the thesis' "absolute data of the DXF file" and "locations
    attached to the CAD objects", which spare the operator placing and teaching them."""

    def __init__(self, core: PartContract) -> None:
        self._core = core

    def read_layout(self, data: bytes, filename: str) -> CellLayout | None:
        """The layout in a DXF, or None when it is an ordinary one-part drawing."""
        return read_layout(data, filename)

    def import_layout(self, data: bytes, filename: str, *, units: str | None = None,
                      role: ObjectRole | str = ObjectRole.OBSTACLE) -> list[CellObject]:
        return self.start_import_layout(data, filename, units=units, role=role).result()

    def start_import_file(self, data: bytes, filename: str, *, units: str | None = None,
                          role: ObjectRole | str = ObjectRole.OBSTACLE,
                          dxf_extrude_height: float | None = None,
                          T_world_object: Array | None = None) -> FileImport:
        """An uploaded file, decided here: a cell layout (a DXF with a LOCATIONS layer) is
        imported as one (`start_import_layout`: its parts where drawn, its locations
        taught), anything else as one part (`start_import_cad`, at `T_world_object`). The
        drawing is read for its layout once; the answer says which it was at once."""
        layout = read_layout(data, filename)
        if layout is None:
            return FileImport(None, self._core.objects.start_import_cad(
                data, filename, units=units, dxf_extrude_height=dxf_extrude_height, role=role,
                T_world_object=T_world_object))
        return FileImport(layout, self._start_layout(layout, data, filename, units, role))

    def start_import_layout(self, data: bytes, filename: str, *, units: str | None = None,
                            role: ObjectRole | str = ObjectRole.OBSTACLE) -> Future:
        """Read every part off the session lock (with progress and Cancel), then add them and
        the locations as one action: all of it or, on any error, nothing."""
        layout = read_layout(data, filename)
        if layout is None:
            raise SessionError(f"{filename} is not a cell layout (no LOCATIONS layer)")
        return self._start_layout(layout, data, filename, units, role)

    def _start_layout(self, layout: CellLayout, data: bytes, filename: str, units: str | None,
                      role: ObjectRole | str) -> Future:
        def read(progress: Progress) -> dict[str, CadImport]:
            cads: dict[str, CadImport] = {}
            n = len(layout.parts)
            for i, (name, layer) in enumerate(layout.parts.items()):
                cads[name] = load_cad(data, filename, units=units, dxf_layer=layer,
                                      progress=progress.sub(i / n, (i + 1) / n,
                                                            f"part {name}"),
                                      dxf_document=layout.document)  # parsed once
            return cads

        return self._core.objects.start_cell_job(
            f"import {filename}", read, lambda cads: self._add_layout(layout, cads, filename,
                                                                      role))

    def _add_layout(self, layout: CellLayout, cads: dict[str, CadImport], filename: str,
                    role: ObjectRole | str) -> list[CellObject]:
        objs: list[CellObject] = []
        with self._core.action(f"import {filename}", EDIT_CELL, scene="objects"):
            for name, cad in cads.items():
                obj_name = _safe_name(name)
                old = self._core.cell.objects.get(obj_name)
                if old is not None and old.source is not None and \
                        old.source.filename == filename:
                    # The same layout again (e.g. updated in CAD): its parts are replaced.
                    self._core.cell.remove_object(obj_name)
                else:
                    obj_name = self._core.cell.unique_name(obj_name)
                # Drawn in cell coordinates: the part stands where the drawing has it.
                obj = CellObject.from_cad(obj_name, cad, np.eye(4), role=role)
                self._core.cell.add_object(obj)
                objs.append(obj)
                for w in (*cad.warnings, *cad.bounded):
                    self._core.bus.emit(Notice(f"{filename} ({name}): {w}"))
                self._core.objects.note_working_volume(obj)
            scale = next(iter(cads.values())).scale_to_m * 1000.0  # drawing units -> mm
            for loc in layout.locations:
                pose = np.array([*(scale * v for v in loc.xyz), *loc.abc_deg], float)
                try:
                    self._core.locations[loc.name] = self._core.teaching.make_location(
                        loc.name, pose_from_mm_deg(pose), LocationSource.CAD_FILE, None, 0.0)
                except UnreachableError as exc:
                    raise SessionError(f"location {loc.name}: {exc}") from exc
                if loc.role == "start":
                    self._core.mission = replace(self._core.mission, start=loc.name,
                                                 order=None)
                elif loc.role == "goal":
                    self._core.mission = replace(self._core.mission, goal=loc.name,
                                                 order=None)
        for note in layout.notes:
            self._core.bus.emit(Notice(f"{filename}: {note}"))
        self._core.bus.emit(SceneChanged("all"))
        return objs

    def import_layout_path(self, path: str | Path, **kw) -> list[CellObject]:
        p = Path(path)
        try:
            data = read_cad_file(p)
        except CadImportError as exc:
            raise SessionError(f"cannot import {p}: {exc.problem}"
                               + (f" — {exc.advice}" if exc.advice else "")) from None
        return self.import_layout(data, p.name, **kw)
