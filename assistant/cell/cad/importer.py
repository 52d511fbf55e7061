"""The import pipeline shared by every format: read, check, units, repair, collision proxy."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.formats import format_from_filename, reader_for
from assistant.cell.cad.options import (
    DEFAULT_PROXY_MAX_FACES,
    DEFAULT_PROXY_TOLERANCE_M,
    DEFAULT_STEP_TOLERANCE_M,
    ImportOptions,
)
from assistant.cell.cad.proxy import ProxyReport, collision_proxy
from assistant.cell.cad.source import CadSource
from assistant.cell.cad.units import decide_units, size_warning
from assistant.cell.cad.validate import check_raw, repair
from assistant.robots.model import CollisionShape

#: Larger uploads are refused before parsing (memory); no cell part needs more.
MAX_FILE_BYTES = 512 * 1024 * 1024


@dataclass(frozen=True, eq=False)
class CadImport:
    """An imported part: a repaired mesh in metres (file frame), its collision geometry, and
    a report of everything decided on the way (units, repairs, proxy, warnings)."""

    filename: str
    format: str
    #: Full-detail mesh in the file's own frame, scaled to metres.
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

    def summary(self) -> str:
        """A few lines for the operator: size, units and why, repairs, proxy, warnings."""
        ext = self.mesh.extents * 1000.0
        lines = [
            f"{self.filename}: {len(self.mesh.faces):,} triangles, "
            f"{ext[0]:.1f} x {ext[1]:.1f} x {ext[2]:.1f} mm",
            f"units: {self.units} ({self.units_reason})",
        ]
        lines += [f"repaired: {r}" for r in self.repairs]
        if self.proxy.kind != "mesh":
            lines.append(f"collision proxy: {self.proxy.kind.replace('_', ' ')}, "
                         f"{self.proxy.parts} part(s), {self.proxy.faces:,} triangles, "
                         f"deviation {self.proxy.deviation_m * 1000:.2f} mm")
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

    Returns:
        The imported part; see `CadImport`.

    Raises:
        CadImportError: the file cannot be used; the message says why and what to do.
    """
    try:
        options = ImportOptions(units=units, dxf_extrude_height=dxf_extrude_height,
                                proxy_max_faces=proxy_max_faces,
                                proxy_tolerance_m=proxy_tolerance_m,
                                step_tolerance_m=step_tolerance_m)
    except ValueError as exc:
        raise CadImportError(filename, f"bad import option: {exc}") from exc
    return import_with_options(data, filename, options)


def load_cad_path(path: str | Path, **kwargs) -> CadImport:
    """`load_cad` for a file on disk (same keyword arguments)."""
    p = Path(path)
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise CadImportError(str(p), f"cannot be opened ({exc.strerror})",
                             "check the path") from exc
    if size > MAX_FILE_BYTES:
        raise CadImportError(p.name, f"is {size / 2**20:.0f} MiB, more than the "
                             f"{MAX_FILE_BYTES // 2**20} MiB allowed", "simplify it in CAD")
    return load_cad(p.read_bytes(), p.name, **kwargs)


def import_with_options(data: bytes, filename: str, options: ImportOptions) -> CadImport:
    """The pipeline behind `load_cad` (used directly when re-importing a saved cell)."""
    try:
        return _import(data, filename, options)
    except CadImportError:
        raise
    except MemoryError as exc:
        raise CadImportError(filename, "is too large to import in the available memory",
                             "simplify the part in CAD or export it coarser") from exc
    except Exception as exc:  # a library failing on odd geometry: still the file's fault
        raise CadImportError(
            filename, f"could not be imported ({type(exc).__name__}: {exc})",
            "export the part again (e.g. as STEP or binary STL); if it persists, report it "
            "with the file") from exc


def _import(data: bytes, filename: str, options: ImportOptions) -> CadImport:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise CadImportError(filename, f"expected the file's bytes, got {type(data).__name__}")
    data = bytes(data)
    if len(data) == 0:
        raise CadImportError(filename, "is empty (0 bytes)", "upload the file again")
    if len(data) > MAX_FILE_BYTES:
        raise CadImportError(filename, f"is {len(data) / 2**20:.0f} MiB, more than the "
                             f"{MAX_FILE_BYTES // 2**20} MiB allowed", "simplify it in CAD")
    fmt = format_from_filename(filename)
    raw = reader_for(fmt)(data, filename, options)

    if raw.mesh is None and raw.outline is not None:
        size = raw.outline.bounds_size()
    else:
        check_raw(raw.mesh, filename)
        used = raw.mesh.vertices[np.unique(raw.mesh.faces)]
        size = float(np.ptp(used, axis=0).max())
    decision = decide_units(filename=filename, largest_dimension=size,
                            file_units=raw.file_units, caller_units=options.units,
                            converted_from=raw.converted_from)
    if raw.mesh is None:
        assert raw.outline is not None and options.dxf_extrude_height is not None
        raw.mesh = raw.outline.extrude(options.dxf_extrude_height / decision.scale_to_m)
        raw.notes.append(f"extruded the outline by {options.dxf_extrude_height * 1000:.1f} mm")
        check_raw(raw.mesh, filename)

    mesh = raw.mesh.copy()
    if decision.scale_to_m != 1.0:
        mesh.apply_scale(decision.scale_to_m)
    mesh, rep = repair(mesh, filename)
    warnings = list(raw.warnings) + rep.warnings
    w = size_warning(float(mesh.extents.max()), decision)
    if w:
        warnings.append(w)
    collision, proxy, proxy_warnings = collision_proxy(
        mesh, max_faces=options.proxy_max_faces, tolerance_m=options.proxy_tolerance_m)
    warnings += proxy_warnings

    source = CadSource(filename=filename, data=data, format=fmt.value, units=decision.units,
                       units_source=decision.source.value, scale_to_m=decision.scale_to_m,
                       options=options.to_json())
    return CadImport(
        filename=filename, format=fmt.value, mesh=mesh, collision=collision, proxy=proxy,
        units=decision.units, units_source=decision.source.value,
        file_units=decision.file_units, scale_to_m=decision.scale_to_m,
        units_reason=decision.reason, repairs=tuple(rep.repairs),
        notes=tuple(raw.notes + rep.notes),
        warnings=tuple(warnings), bodies=raw.bodies, source=source)
