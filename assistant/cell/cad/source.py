"""The original CAD file kept with an object, so a saved cell can re-import it exactly."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True, eq=False)
class CadSource:
    """The bytes the operator uploaded and how they were read.

    The stored file is the source of truth: a saved cell keeps these bytes and re-imports them
    with `options` on load, rather than storing a derived mesh that could drift from them.
    """

    filename: str
    data: bytes = field(repr=False)
    format: str
    #: The unit the file's numbers were taken to be in, and who decided (file/size/caller).
    units: str
    units_source: str
    #: Factor applied to the reader's numbers to get metres.
    scale_to_m: float
    #: The keyword arguments given to `load_cad` (JSON-able), e.g. dxf_extrude_height.
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.data).hexdigest()
