"""The built-in sample cells (`sample_cells/<name>/`): list them and start a session from one.

A sample folder holds `cell/` (a saved cell with its CAD files), optional `mission.json`,
`hidden.json` (obstacles only the simulated robot knows), `sample.json` (description, link
settings, export dialect) and `session.yaml` (a scripted session with `expected.json`).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: The product's default cell: the thesis experiment.
DEFAULT_SAMPLE = "thesis_rv2aj"


class SampleError(ValueError):
    """An unknown or broken sample cell."""


def samples_root() -> Path:
    """`$CELLTEACH_SAMPLES`, else the `sample_cells` folder next to the installed packages."""
    env = os.environ.get("CELLTEACH_SAMPLES")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "sample_cells"


@dataclass(frozen=True)
class SampleInfo:
    name: str
    folder: Path
    description: str
    meta: dict[str, Any]


def sample_folder(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    if p.is_dir() and (p / "cell").is_dir():
        return p
    q = samples_root() / str(name_or_path)
    if q.is_dir() and (q / "cell").is_dir():
        return q
    known = ", ".join(s.name for s in list_samples()) or "none found"
    raise SampleError(f"no sample cell {str(name_or_path)!r} (known: {known}; or give a folder "
                      "with a cell/ inside)")


def read_meta(folder: Path) -> dict[str, Any]:
    path = folder / "sample.json"
    if not path.exists():
        return {}
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SampleError(f"{path}: {exc}") from None
    if not isinstance(meta, dict):
        raise SampleError(f"{path}: expected a JSON object")
    return meta


def list_samples() -> list[SampleInfo]:
    root = samples_root()
    out = []
    if root.is_dir():
        for d in sorted(root.iterdir()):
            if (d / "cell").is_dir():
                meta = read_meta(d)
                out.append(SampleInfo(d.name, d, str(meta.get("description", "")), meta))
    return out
