"""The import pipeline shared by every format: size up, read, check, units, repair, display
level of detail, collision proxy.

The full-resolution part is kept (`CadImport.mesh`: picking, sizes, the reports); the page
draws a decimated copy of at most `DISPLAY_MAX_FACES` triangles (`display_mesh`), and the
collision checks use the proxy with its margin (`collision`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import trimesh

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.formats import CadFormat, format_from_filename
from assistant.cell.cad.options import (
    DEFAULT_PROXY_MAX_FACES,
    DEFAULT_PROXY_TOLERANCE_M,
    DEFAULT_STEP_TOLERANCE_M,
    ImportOptions,
)
from assistant.cell.cad.precheck import check_before_parsing
from assistant.cell.cad.proxy import ProxyReport, collision_proxy
from assistant.cell.cad.raw import RawGeometry
from assistant.cell.cad.source import CadSource
from assistant.cell.cad.units import decide_units, size_warning
from assistant.cell.cad.validate import MAX_FACES, check_raw, repair
from assistant.file_guard import FileRefused, read_file
from assistant.progress import Cancelled, Progress
from assistant.robots.model import CollisionShape


def reader_for(fmt: CadFormat) -> Callable[[bytes, str, ImportOptions], RawGeometry]:
    """The reader function for a format (imported lazily: STEP pulls in OpenCASCADE)."""
    if fmt == CadFormat.DXF:
        from assistant.cell.cad.dxf import read_dxf

        return read_dxf
    if fmt == CadFormat.STEP:
        from assistant.cell.cad.step import read_step

        return read_step
    from assistant.cell.cad.meshfile import read_mesh_file

    return lambda data, filename, options: read_mesh_file(data, filename, fmt.value, options)


#: Larger files are refused before reading (memory): a binary STL of `MAX_FACES` triangles
#: is 191 MiB.
MAX_FILE_BYTES = 512 * 1024 * 1024
#: Above this many triangles the page draws a decimated copy of the part (its level of
#: detail): a browser without a GPU draws 100 000 smoothly; picking and the reports use the
#: full part, collision its own proxy.
DISPLAY_MAX_FACES = 100_000
#: A part larger than this (metres, after units) or farther than this from its file's origin
#: is refused: no robot cell part is, and such numbers break the collision checks' precision
#: (an OBJ with a 1e27 m triangle collided with nothing).
MAX_PART_SIZE_M = 1000.0
#: ... and geometry farther than this from the file's origin (plant coordinates are fine).
MAX_PART_REACH_M = 1000.0


@dataclass(frozen=True, eq=False)
class CadImport:
    """An imported part: a repaired mesh in metres (file frame), its collision geometry, and
    a report of everything decided on the way (units, repairs, proxy, warnings)."""

    filename: str
    format: str
    #: The repaired part at full resolution, in the file's own frame, scaled to metres.
    mesh: trimesh.Trimesh
    #: Collision shapes in the same frame: the mesh itself, or a proxy for big meshes.
    collision: tuple[CollisionShape, ...]
    proxy: ProxyReport
    units: str
    units_source: str
    file_units: str | None
    scale_to_m: float
    units_reason: str
    repairs: tuple[str, ...]
    notes: tuple[str, ...]
    warnings: tuple[str, ...]
    bodies: int
    source: CadSource
    #: What was bounded to keep a big import short: display decimation, proxy work copy...
    bounded: tuple[str, ...] = ()
    #: What the page draws: `mesh` itself, or a decimated copy of a big part.
    display_mesh: trimesh.Trimesh | None = None

    def __post_init__(self) -> None:
        if self.display_mesh is None:
            object.__setattr__(self, "display_mesh", self.mesh)

    def summary(self) -> str:
        """A few lines for the operator: size, units and why, repairs, proxy, warnings."""
        ext = self.mesh.extents * 1000.0
        lines = [
            f"{self.filename}: {len(self.mesh.faces):,} triangles, "
            f"{ext[0]:.1f} x {ext[1]:.1f} x {ext[2]:.1f} mm",
            f"units: {self.units} ({self.units_reason})",
        ]
        lines += [f"repaired: {r}" for r in self.repairs]
        lines += [f"bounded: {b}" for b in self.bounded]
        if self.proxy.kind != "mesh":
            p = self.proxy
            lines.append(f"collision proxy: {p.kind.replace('_', ' ')}, {p.parts} part(s), "
                         f"{p.faces:,} triangles, deviation {p.deviation_m * 1000:.2f} mm")
            if p.margin_m > 0.0:
                lines.append(
                    f"the part lies at most {p.margin_m * 1000:.2f} mm outside its proxy "
                    "(one-sided Hausdorff, bounded over every triangle): the collision "
                    f"checks keep a {p.margin_m * 1000:.2f} mm margin around the proxy")
            else:
                lines.append("the part lies inside its proxy (the hull holds every vertex)")
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def load_cad(
    data: bytes,
    filename: str,
    *,
    units: str | None = None,
    dxf_extrude_height: float | None = None,
    proxy_max_faces: int = DEFAULT_PROXY_MAX_FACES,
    proxy_tolerance_m: float = DEFAULT_PROXY_TOLERANCE_M,
    step_tolerance_m: float = DEFAULT_STEP_TOLERANCE_M,
    dxf_layer: str | None = None,
    progress: Progress | None = None,
    dxf_document: Any = None,
) -> CadImport:
    """Import a CAD file given as bytes (an upload); the format comes from the file name.

    Args:
        data: the file's bytes.
        filename: the original name; its suffix selects the format.
        units: the unit of the file's numbers ('mm', 'm', 'inch', ...), overriding the file's
            own unit and the size guess.
        dxf_extrude_height: thickness (metres) for a DXF that holds only a 2-D outline.
        proxy_max_faces: above this many triangles collision uses a simpler proxy.
        proxy_tolerance_m: how far a proxy may deviate from the mesh.
        step_tolerance_m: chordal tolerance of STEP tessellation.
        dxf_layer: read only this layer of a DXF (a part of a cell-layout drawing).
        progress: reports the stages and raises `Cancelled` between them after `cancel()`.
        dxf_document: `data` already parsed (`dxf.read_document`): the parts of a cell
            layout are read from one parsed drawing, not the file parsed again per part.

    Returns:
        The imported part; see `CadImport`.

    Raises:
        CadImportError: the file cannot be used; the message says why and what to do.
    """
    try:
        options = ImportOptions(units=units, dxf_extrude_height=dxf_extrude_height,
                                proxy_max_faces=proxy_max_faces,
                                proxy_tolerance_m=proxy_tolerance_m,
                                step_tolerance_m=step_tolerance_m, dxf_layer=dxf_layer)
    except ValueError as exc:
        raise CadImportError(filename, f"bad import option: {exc}") from exc
    return import_with_options(data, filename, options, progress, dxf_document=dxf_document)


def load_cad_path(path: str | Path, **kwargs) -> CadImport:
    """`load_cad` for a file on disk (same keyword arguments)."""
    p = Path(path)
    return load_cad(read_cad_file(p), p.name, **kwargs)


def read_cad_file(path: str | Path) -> bytes:
    """The bytes of a CAD file on disk: a regular file of at most `MAX_FILE_BYTES`
    (`file_guard`: no devices, FIFOs or folders), else `CadImportError` saying why."""
    try:
        return read_file(path, limit=MAX_FILE_BYTES, what="CAD file")
    except FileRefused as exc:
        raise CadImportError(Path(path).name, exc.problem, exc.advice) from None


def import_with_options(data: bytes, filename: str, options: ImportOptions,
                        progress: Progress | None = None, *,
                        dxf_document: Any = None) -> CadImport:
    """The pipeline behind `load_cad` (used directly when re-importing a saved cell)."""
    try:
        return _import(data, filename, options, progress or Progress(), dxf_document)
    except (CadImportError, Cancelled):
        raise
    except MemoryError as exc:
        raise CadImportError(filename, "is too large to import in the available memory",
                             "simplify the part in CAD or export it coarser") from exc
    except Exception as exc:  # a library failing on odd geometry: still the file's fault
        raise CadImportError(
            filename, f"could not be imported ({type(exc).__name__}: {exc})",
            "export the part again (e.g. as STEP or binary STL); if it persists, report it "
            "with the file") from exc


def _import(data: bytes, filename: str, options: ImportOptions,
            progress: Progress, dxf_document: Any = None) -> CadImport:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise CadImportError(filename, f"expected the file's bytes, got {type(data).__name__}")
    data = bytes(data)
    if len(data) == 0:
        raise CadImportError(filename, "is empty (0 bytes)", "upload the file again")
    if len(data) > MAX_FILE_BYTES:
        raise CadImportError(filename, f"is {len(data) / 2**20:.0f} MiB, more than the "
                             f"{MAX_FILE_BYTES // 2**20} MiB allowed", "simplify it in CAD")
    fmt = format_from_filename(filename)
    progress.update(0.01, "sizing up the file")
    check_before_parsing(data, filename, fmt, MAX_FACES)
    progress.update(0.02, "reading the file")
    if dxf_document is not None and fmt == CadFormat.DXF:
        from assistant.cell.cad.dxf import read_dxf

        raw = read_dxf(data, filename, options, document=dxf_document)
    else:
        raw = reader_for(fmt)(data, filename, options)

    progress.update(0.12, "checking the geometry")
    if raw.mesh is None and raw.outline is not None:
        size = raw.outline.bounds_size()
        reach = size
    else:
        size, reach = check_raw(raw.mesh, filename)
    decision = decide_units(filename=filename, largest_dimension=size,
                            file_units=raw.file_units, caller_units=options.units,
                            converted_from=raw.converted_from)
    _check_working_volume(filename, size * decision.scale_to_m, reach * decision.scale_to_m,
                          decision.units, decision.source.value)
    if raw.mesh is None:
        assert raw.outline is not None and options.dxf_extrude_height is not None
        raw.mesh = raw.outline.extrude(options.dxf_extrude_height / decision.scale_to_m)
        raw.notes.append(f"extruded the outline by {options.dxf_extrude_height * 1000:.1f} mm")
        check_raw(raw.mesh, filename)

    progress.update(0.15, "repairing the mesh")
    mesh = raw.mesh
    raw.mesh = None  # one copy of a big mesh at a time
    mesh, rep = repair(mesh, filename, copy=False, scale=decision.scale_to_m,
                       progress=progress.sub(0.15, 0.33, "repairing the mesh"))
    warnings = list(raw.warnings) + rep.warnings
    w = size_warning(float(mesh.extents.max()), decision)
    if w:
        warnings.append(w)
    bounded: list[str] = []
    display = mesh
    if len(mesh.faces) > DISPLAY_MAX_FACES:
        progress.update(0.35, "a level of detail for the page")
        display = mesh.simplify_quadric_decimation(face_count=DISPLAY_MAX_FACES)
        bounded.append(f"drawn with {len(display.faces):,} of its {len(mesh.faces):,} "
                       "triangles (picking, sizes and collision use the full part)")
    progress.update(0.45, "collision proxy")
    collision, proxy, proxy_warnings = collision_proxy(
        mesh, max_faces=options.proxy_max_faces, tolerance_m=options.proxy_tolerance_m,
        progress=progress.sub(0.45, 0.98), lod=display if display is not mesh else None)
    warnings += proxy_warnings
    bounded += proxy.bounded
    progress.update(1.0, "imported")

    source = CadSource(filename=filename, data=data, format=fmt.value, units=decision.units,
                       units_source=decision.source.value, scale_to_m=decision.scale_to_m,
                       options=options.to_json())
    return CadImport(
        filename=filename, format=fmt.value, mesh=mesh, collision=collision, proxy=proxy,
        units=decision.units, units_source=decision.source.value,
        file_units=decision.file_units, scale_to_m=decision.scale_to_m,
        units_reason=decision.reason, repairs=tuple(rep.repairs),
        notes=tuple(raw.notes + rep.notes),
        warnings=tuple(warnings), bodies=raw.bodies, source=source, bounded=tuple(bounded),
        display_mesh=display)


def _check_working_volume(filename: str, size_m: float, reach_m: float, units: str,
                          source: str) -> None:
    """Refuse geometry no cell holds: larger than `MAX_PART_SIZE_M`, or farther than
    `MAX_PART_REACH_M` from the file's origin (the part lands at the world origin)."""
    said = f"read as {units} ({'guessed from its size' if source == 'size' else source})"
    if size_m > MAX_PART_SIZE_M:
        raise CadImportError(
            filename, f"is {size_m:.3g} m across ({said}), more than the "
                      f"{MAX_PART_SIZE_M:g} m a robot cell part can be",
            "if its numbers are in another unit, import it again giving the units; otherwise "
            "the file holds stray or broken geometry: remove it in CAD (or cut the part "
            "down to the robot's surroundings) and export again")
    if reach_m > MAX_PART_REACH_M:
        raise CadImportError(
            filename, f"has geometry {reach_m:.3g} m from its own origin ({said}), more "
                      f"than the {MAX_PART_REACH_M:g} m a robot cell can hold",
            "if its numbers are in another unit, import it again giving the units; otherwise "
            "move the part near the origin in CAD (it is placed in the next step) or remove "
            "the stray geometry, and export again")
