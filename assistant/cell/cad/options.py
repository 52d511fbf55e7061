"""How a CAD file is to be read; stored with the file so a saved cell re-imports it the same way."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

#: Above this many triangles a mesh gets a simpler collision proxy (display keeps full detail).
DEFAULT_PROXY_MAX_FACES = 20_000
#: A proxy deviating less than this from the mesh is good enough: the continuous collision
#: check steps 5 mm by default, and an octree leaf is 62.5 mm.
DEFAULT_PROXY_TOLERANCE_M = 0.005
#: Chordal tolerance of STEP tessellation: far below what a pointer or the collision check
#: resolves, coarse enough that fillets do not explode the triangle count.
DEFAULT_STEP_TOLERANCE_M = 1e-4


@dataclass(frozen=True)
class ImportOptions:
    """Caller's choices for one import. Lengths in metres (convert mm at the UI edge)."""

    #: Unit of the file's numbers ('mm', 'm', 'inch', ...); None = the file's own, else size.
    units: str | None = None
    #: Thickness given to a 2-D DXF outline (metres); None refuses outline-only drawings.
    dxf_extrude_height: float | None = None
    proxy_max_faces: int = DEFAULT_PROXY_MAX_FACES
    proxy_tolerance_m: float = DEFAULT_PROXY_TOLERANCE_M
    step_tolerance_m: float = DEFAULT_STEP_TOLERANCE_M
    #: Read only this layer of a DXF (one part of a cell-layout drawing); None = all layers.
    dxf_layer: str | None = None

    def __post_init__(self) -> None:
        if self.dxf_extrude_height is not None and not (
            isinstance(self.dxf_extrude_height, (int, float))
            and math.isfinite(self.dxf_extrude_height) and self.dxf_extrude_height > 0
        ):
            raise ValueError(f"dxf_extrude_height must be a positive length in metres, "
                             f"got {self.dxf_extrude_height!r}")
        if not isinstance(self.proxy_max_faces, int) or self.proxy_max_faces < 4:
            raise ValueError(f"proxy_max_faces must be an integer >= 4, "
                             f"got {self.proxy_max_faces!r}")
        for name in ("proxy_tolerance_m", "step_tolerance_m"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a positive length in metres, got {v!r}")
        if self.dxf_layer is not None and not isinstance(self.dxf_layer, str):
            raise ValueError(f"dxf_layer must be a layer name, got {self.dxf_layer!r}")
        if self.units is not None and not isinstance(self.units, str):
            raise ValueError(f"units must be a unit name such as 'mm', got {self.units!r}")

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        if d["dxf_layer"] is None:  # cells saved before layouts existed stay byte-identical
            del d["dxf_layer"]
        return d

    @staticmethod
    def from_json(d: Any) -> ImportOptions:
        """Rebuild from stored JSON; unknown keys or wrong types raise ValueError."""
        if not isinstance(d, dict):
            raise ValueError("import options must be an object")
        known = set(ImportOptions.__dataclass_fields__)
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown import option(s): {', '.join(sorted(unknown))}")
        return ImportOptions(**d)
