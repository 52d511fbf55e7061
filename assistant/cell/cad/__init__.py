"""CAD import: one entry point, `load_cad`, over one module per format quirk.

Owns reading STL/OBJ/PLY/GLB/glTF/3MF (trimesh), DXF (ezdxf) and STEP (cascadio), deciding the
length unit, validating and repairing meshes, and building collision proxies for big meshes.
Results are in metres in the file's own frame. Must not import the cell, the UI or planning.
"""

from assistant.cell.cad.errors import CadImportError
from assistant.cell.cad.formats import SUPPORTED_SUFFIXES, CadFormat
from assistant.cell.cad.importer import CadImport, import_with_options, load_cad, load_cad_path
from assistant.cell.cad.options import ImportOptions
from assistant.cell.cad.proxy import ProxyReport
from assistant.cell.cad.source import CadSource
from assistant.cell.cad.units import UnitsSource

__all__ = [
    "SUPPORTED_SUFFIXES",
    "CadFormat",
    "CadImport",
    "CadImportError",
    "CadSource",
    "ImportOptions",
    "ProxyReport",
    "UnitsSource",
    "import_with_options",
    "load_cad",
    "load_cad_path",
]
