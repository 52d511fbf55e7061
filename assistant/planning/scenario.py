"""A sample cell as the planner and a simulated robot see it: cell, mission, hidden obstacles.

A sample folder (e.g. ``sample_cells/thesis_rv2aj``) holds ``cell/`` (saved with
`save_cell`), ``mission.json`` (`ResolvedMission.to_json`: start and goal whole) and
optionally ``hidden.json``: obstacles only the simulated robot knows, so planning meets them
through collision indications. The hidden file is plain JSON (boxes, cylinders, spheres;
metres, world frame), never code.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from assistant.cell.model import Cell, PrimitiveSpec, check_transform
from assistant.cell.storage import load_cell
from assistant.collision.reports import Obstacle
from assistant.mission.model import ResolvedMission
from assistant.transforms import inv_T

#: The product's default cell (the thesis experiment).
DEFAULT_SAMPLE = Path(__file__).resolve().parents[2] / "sample_cells" / "thesis_rv2aj"


@dataclass
class Scenario:
    cell: Cell
    mission: ResolvedMission
    #: Obstacles the planner does not know, in the robot base frame (for `SimulatedRobot`).
    hidden: list[Obstacle] = field(default_factory=list)
    folder: Path | None = None

    def known_obstacles(self) -> list:
        """The cell's objects in the base frame (what the planner knows)."""
        return self.cell.collision_objects_in_base()


def load_hidden(path: str | Path, T_world_base: np.ndarray) -> list[Obstacle]:
    """Hidden obstacles from ``hidden.json``, placed in the robot base frame."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read hidden obstacles ({exc})") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("obstacles"), list):
        raise ValueError(f"{path}: expected an object with a list 'obstacles'")
    T_base_world = inv_T(np.asarray(T_world_base, dtype=float))
    out = []
    for i, d in enumerate(doc["obstacles"]):
        if not isinstance(d, dict) or "name" not in d:
            raise ValueError(f"{path}: obstacle {i + 1} needs a name")
        try:
            spec = PrimitiveSpec(d.get("kind", "box"), tuple(d.get("size", ())))
            T = check_transform(d.get("T_world_object", np.eye(4).tolist()),
                                f"hidden obstacle {d['name']!r}")
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from exc
        out.append(Obstacle(str(d["name"]), T_base_world @ T, (spec.collision_shape(),)))
    return out


def load_scenario(folder: str | Path = DEFAULT_SAMPLE) -> Scenario:
    """Cell, mission and hidden obstacles of a sample folder."""
    folder = Path(folder)
    cell = load_cell(folder / "cell")
    try:
        doc = json.loads((folder / "mission.json").read_text("utf-8"))
        mission = ResolvedMission.from_json(doc)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{folder / 'mission.json'}: cannot read the mission ({exc})") from exc
    hidden_path = folder / "hidden.json"
    hidden = load_hidden(hidden_path, cell.T_world_base) if hidden_path.exists() else []
    return Scenario(cell, mission, hidden, folder)
