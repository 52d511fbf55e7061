"""Step 2 - import CAD: upload any supported file, confirm its units, set its role; simple
boxes/cylinders for things without CAD; the list of parts in the cell."""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass

import numpy as np
import viser

from assistant.cell.model import ObjectRole
from assistant.progress import Cancelled
from assistant.session.events import Event, SceneChanged
from assistant.session.layout_part import FileImport
from web.gui_value import set_value
from web.panels.base import Panel, gate
from web.units import point_from_mm
from web.uploads import check_upload_size

UNITS = ("from the file", "mm", "m", "inch")
ROLES = tuple(r.value for r in ObjectRole)
FORMATS = "STL, OBJ, PLY, GLB/GLTF, 3MF, DXF, STEP"
#: Imported parts wait here until placed: behind the robot's base (its -x), in a row.
STAGING_BEHIND_M = -0.45
STAGING_STEP_M = 0.3
STAGING_SLOTS = 4
#: The one-click work table: a common 1200 x 1200 mm top, 20 mm thick, under the robot's base.
TABLE_SIZE_MM = (1200.0, 1200.0, 20.0)


@dataclass
class LastImport:
    """The bytes of the last upload, kept so the operator can re-import with other units."""

    filename: str
    data: bytes
    object_name: str
    units: str


class CadPanel(Panel):
    title = "Import CAD"
    steps = ("cad",)

    def build(self) -> None:
        g = self.gui
        g.add_markdown(f"Upload a part ({FORMATS}). It waits beside the robot, out of its "
                       "way, until you place it in the next step. A DXF with a LOCATIONS "
                       "layer is a cell layout: its parts stand where drawn and its labelled "
                       "points are taught.")
        self.units = g.add_dropdown("Units", UNITS, hint="Leave 'from the file' unless the "
                                    "size comes out wrong")
        self.role = g.add_dropdown("Role", ROLES, initial_value="obstacle")
        self.extrude = g.add_number("DXF height (mm)", 0.0, min=0.0, max=5000.0, step=1.0,
                                    hint="Only for a DXF holding a 2-D outline; 0 = none")
        self.upload = g.add_upload_button("Upload CAD file", icon=viser.Icon.UPLOAD)
        self.table_btn = g.add_button(
            "Add the work table", icon=viser.Icon.TABLE,
            hint=f"A {TABLE_SIZE_MM[0]:.0f} x {TABLE_SIZE_MM[1]:.0f} mm table top under the "
                 "robot's base (a fixture); other sizes under 'Add a simple shape'")
        self.report = g.add_markdown("")
        with g.add_folder("Units of the last part", visible=False) as self.confirm:
            self.reunits = g.add_dropdown("Re-import as", UNITS[1:])
            self.reimport = g.add_button("Re-import with these units")
        with g.add_folder("Parts in the cell"):
            self.table = g.add_markdown("")
            self.pick = g.add_dropdown("Part", ("-",))
            self.new_role = g.add_dropdown("New role", ROLES)
            self.set_role = g.add_button("Change role")
            self.remove = g.add_button("Remove part", color="red")
        with g.add_folder("Add a simple shape", expand_by_default=False):
            self.shape = g.add_dropdown("Shape", ("box", "cylinder", "sphere"))
            self.size = g.add_vector3("Size (mm)", (100.0, 100.0, 100.0), step=1.0,
                                      hint="box: x, y, z; cylinder: radius, height, -; "
                                           "sphere: radius, -, -")
            self.shape_at = g.add_vector3("Centre at (mm)", (0.0, 0.0, 0.0), step=1.0)
            self.shape_role = g.add_dropdown("Shape role", ROLES, initial_value="obstacle")
            self.shape_name = g.add_text("Name", "")
            self.add_shape = g.add_button("Add shape")
        self.last: LastImport | None = None
        self.bind(self.upload, self._uploaded)
        self.bind(self.reimport, lambda e: self._reimport())
        self.bind(self.set_role, lambda e: self.session.set_object_role(self.pick.value,
                                                                        self.new_role.value))
        self.bind(self.remove, lambda e: self.session.remove_object(self.pick.value))
        self.bind(self.add_shape, lambda e: self._add_shape())
        self.bind(self.table_btn, lambda e: self._add_table())

    # ------------------------------------------------------------------ actions
    def _uploaded(self, event: viser.GuiEvent) -> None:
        f = event.target.value
        check_upload_size(self.app, f.name, len(f.content))
        units = None if self.units.value == UNITS[0] else self.units.value
        self._import(f.name, f.content, units, name=None, decide=True)

    def _layout_started(self, filename: str, job: FileImport) -> None:
        """A cell layout: its parts stand where drawn, its locations are taught (one action)."""
        layout, fut = job.layout, job.future
        assert layout is not None
        self.report.content = f"*Importing the cell layout {filename}...*"

        def shown(f: Future) -> None:
            if f.exception() is not None:
                self.report.content = f"*{filename}: not imported.*"
                return
            names = ", ".join(o.name for o in f.result())
            locs = ", ".join(loc.name + (f" ({loc.role})" if loc.role else "")
                             for loc in layout.locations)
            self.report.content = (f"**Imported {names}** from the cell layout {filename}, "
                                   "standing where drawn" +
                                   (f"; taught {locs}" if locs else "") + ".")
        fut.add_done_callback(lambda f: self.app.pump.post(lambda: shown(f)))

    def _import(self, filename: str, data: bytes, units: str | None, *, name: str | None,
                decide: bool = False) -> None:
        """Start the import on the session's worker (progress bar and Cancel in the toolbar,
        the page stays responsive); the report is shown when it is done. `decide`: an
        upload, which the session imports as a cell layout or as one part."""
        height = self.extrude.value / 1000.0 if self.extrude.value > 0 else None
        if decide:
            job = self.session.start_import_file(data, filename, units=units,
                                                 dxf_extrude_height=height,
                                                 role=self.role.value,
                                                 T_world_object=self._waiting_spot())
            if job.layout is not None:
                self._layout_started(filename, job)
                return
            fut = job.future
        else:
            fut = self.session.start_import_cad(data, filename, name=name, units=units,
                                                dxf_extrude_height=height,
                                                role=self.role.value,
                                                T_world_object=self._waiting_spot())
        self.report.content = f"*Importing {filename}...*"
        fut.add_done_callback(lambda f: self.app.pump.post(
            lambda: self._imported(f, filename, data)))

    def _waiting_spot(self) -> np.ndarray:
        """Where a new part waits to be placed: behind the robot's base, side by side (the
        k-th part STAGING_STEP_M further along), not inside the arm where it would hide."""
        s = self.session
        k = len(s.cell.objects) % STAGING_SLOTS
        T = np.eye(4)
        T[:3, 3] = (STAGING_BEHIND_M, STAGING_STEP_M * (k - (STAGING_SLOTS - 1) / 2.0), 0.0)
        return s.T_world_base() @ T

    def _imported(self, fut: Future, filename: str, data: bytes) -> None:
        exc = fut.exception()
        if exc is not None:  # the session already showed the error (or the cancel notice)
            what = "cancelled" if isinstance(exc, Cancelled) else "not imported"
            self.report.content = f"*{filename}: {what}.*"
            return
        obj, cad = fut.result()
        self.last = LastImport(filename, data, obj.name, cad.units)
        guessed = cad.units_source == "size"
        text = "\n".join(f"- {line}" for line in cad.summary().splitlines())
        head = f"**Imported {obj.name}**" + (" - *units guessed from its size: check them*"
                                              if guessed else "")
        self.report.content = f"{head}\n\n{text}"
        self.confirm.visible = True
        if cad.units in UNITS:
            set_value(self.reunits, cad.units)

    def _reimport(self) -> None:
        last = self.last
        if last is None:
            raise ValueError("nothing imported yet")
        s = self.session
        if last.object_name in s.cell.objects:
            s.remove_object(last.object_name)
        self._import(last.filename, last.data, self.reunits.value, name=last.object_name)

    def _add_shape(self) -> None:
        kind = self.shape.value
        v = [x / 1000.0 for x in self.size.value]
        size = {"box": tuple(v), "cylinder": (v[0], v[1]), "sphere": (v[0],)}[kind]
        at = point_from_mm(self.shape_at.value)
        T = np.eye(4)
        T[:3, 3] = at
        self.session.add_primitive(kind, size, name=self.shape_name.value.strip() or None,
                                   role=self.shape_role.value, T_world_object=T)

    def _add_table(self) -> None:
        s = self.session
        T = np.eye(4)
        T[2, 3] = -TABLE_SIZE_MM[2] / 2000.0  # its top at the base
        name = "table" if "table" not in s.cell.objects else s.cell.unique_name("table")
        s.add_primitive("box", tuple(v / 1000.0 for v in TABLE_SIZE_MM), name=name,
                        role="fixture", T_world_object=s.T_world_base() @ T)

    # ------------------------------------------------------------------ redraw
    def refresh(self) -> None:
        objs = self.session.scene_objects()
        if not objs:
            self.table.content = "*No parts yet.*"
        else:
            rows = ["| part | role | size (mm) |", "|---|---|---|"]
            for o in objs:
                ext = o.part_mesh.extents * 1000.0
                rows.append(f"| {o.name} | {o.role.value} | "
                            f"{ext[0]:.0f} x {ext[1]:.0f} x {ext[2]:.0f} |")
            self.table.content = "\n".join(rows)
        names = tuple(o.name for o in objs) or ("-",)
        if tuple(self.pick.options) != names:
            self.pick.options = names
        for btn in (self.remove, self.set_role):
            gate(btn, "" if objs else "Import or add a part first")
        if self.last is not None and self.last.object_name not in self.session.cell.objects:
            self.confirm.visible = False

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("objects", "all"):
            self.refresh()
