"""Sample cells, saving, autosave and loading.

A part mixed into `Session`."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from assistant.cell.model import Cell
from assistant.cell.storage import load_cell, save_cell
from assistant.links.settings import LinkSettings
from assistant.mission.model import (
    Location,
    Mission,
)
from assistant.mission.motion import trajectory_from_json, trajectory_to_json
from assistant.session.store import (
    CELL_DIR,
    SESSION_JSON,
    SESSION_SCHEMA,
    SessionFileError,
    check_session_keys,
    read_session_json,
    write_json_atomic,
)
from assistant.session.types import (
    Counters,
    HiddenObstacle,
    sample_robot_spec,
)
from assistant.session.world_settings import WorldSettings
from workflow.machine import Machine

if TYPE_CHECKING:
    from assistant.session.session import Session

Array = np.ndarray


class Persistence:
    """Sample cells, saving, autosave and loading."""

    # ================================================================== samples
    @classmethod
    def from_sample(cls, name_or_path: str | Path = "thesis_rv2aj",
                    folder: str | Path | None = None, *, with_objects: bool = True,
                    with_mission: bool = True, autosave: bool = True) -> Session:
        """A session on a sample cell: its robot, link, cameras and hidden obstacles; with its
        placed objects and taught mission unless told otherwise (the operator then imports
        and teaches them)."""
        import json

        from assistant.cell.samples import SampleError, read_meta, sample_folder

        src = sample_folder(name_or_path)
        meta = read_meta(src)
        s = cls(folder, autosave=False)
        cell = load_cell(src / CELL_DIR)
        cell.robot_spec = sample_robot_spec(cell.robot_spec, src)
        s.cell = cell if with_objects else Cell(cell.robot_spec, cell.T_world_base, {},
                                                dict(cell.frames))
        try:
            hidden_path = src / "hidden.json"
            if hidden_path.exists():
                doc = json.loads(hidden_path.read_text(encoding="utf-8"))
                s.hidden = [HiddenObstacle.from_json(d) for d in doc.get("obstacles", [])]
            if "link" in meta:
                s.link_settings = LinkSettings.from_json(meta["link"])
            s.pointer_config = dict(meta.get("pointer", {}))
            s.export_dialect = str(meta.get("dialect", s.export_dialect))
            mission_path = src / "mission.json"
            if with_mission and mission_path.exists():
                doc = json.loads(mission_path.read_text("utf-8"))
                s.mission = Mission.from_json(doc)
                for loc in (s.mission.start, s.mission.goal):
                    if loc is not None:
                        s.locations[loc.name] = loc
                for d in doc.get("locations", ()):  # taught locations besides start and goal
                    loc = Location.from_json(d)
                    s.locations[loc.name] = loc
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise SampleError(f"sample {src.name}: {exc}") from None
        s.sample = src.name
        s.autosave_enabled = autosave and folder is not None
        s._autosave()
        return s

    # ================================================================== persistence
    def _autosave(self) -> None:
        if self.autosave_enabled and self.folder is not None:
            self.save(self.folder)

    def save(self, folder: str | Path) -> Path:
        """Write the whole session (cell with CAD files, mission, world observations, plan)."""
        folder = Path(folder)
        with self._lock:
            save_cell(self.cell, folder / CELL_DIR)
            doc = {
                "schema_version": SESSION_SCHEMA,
                "saved_at": time.time(),
                "machine": self.machine.to_json(),
                "locations": [loc.to_json() for loc in self.locations.values()],
                "mission": self.mission.to_json(),
                "link": self.link_settings.to_json(),
                "hidden_obstacles": [h.to_json() for h in self.hidden],
                "pointer": self.pointer_config,
                "counters": self.counters.to_json(),
                "recorded_collisions": [q.tolist() for q in self.recorded_collisions],
                "robot_joints": self.current_joints().tolist(),
                "trajectory": trajectory_to_json(self.trajectory) if self.trajectory else None,
                "plan_report": self.plan_report,
                "export_dialect": self.export_dialect,
                "world_settings": self.world_settings.to_json(),
                "sample": self.sample,
            }
            write_json_atomic(folder / SESSION_JSON, doc)
        return folder

    def save_as(self, folder: str | Path) -> Path:
        """Save to a new folder and autosave there from now on."""
        folder = Path(folder)
        with self._lock:
            self.folder = folder
            self.autosave_enabled = True
            return self.save(folder)

    @classmethod
    def load(cls, folder: str | Path, *, autosave: bool = True) -> Session:
        """Restore a saved session: scene, mission, world observations and plan."""
        folder = Path(folder)
        doc = read_session_json(folder)
        notes = check_session_keys(doc, folder / SESSION_JSON)
        try:
            cell = load_cell(folder / CELL_DIR)
            s = cls(folder, autosave=False)
            s.cell = cell
            s.machine = Machine.from_json(doc.get("machine", {}))
            for d in doc.get("locations", []):
                loc = Location.from_json(d)
                s.locations[loc.name] = loc
            s.mission = Mission.from_json(doc.get("mission", {}))
            s.link_settings = LinkSettings.from_json(doc.get("link", {}))
            s.hidden = [HiddenObstacle.from_json(h) for h in doc.get("hidden_obstacles", [])]
            s.pointer_config = dict(doc.get("pointer", {}))
            s.counters = Counters.from_json(doc.get("counters", {}))
            s.recorded_collisions = [np.asarray(q, float) for q in
                                     doc.get("recorded_collisions", [])]
            q = doc.get("robot_joints")
            if q is not None:
                qa = np.asarray(q, float)
                if qa.shape == (s.robot.dof,) and np.all(np.isfinite(qa)):
                    s._q_sim = qa
            t = doc.get("trajectory")
            s.trajectory = trajectory_from_json(t) if t else None
            s.plan_report = doc.get("plan_report")
            s.export_dialect = str(doc.get("export_dialect", "melfa"))
            s.sample = doc.get("sample")
            s.world_settings = WorldSettings.from_json(doc.get("world_settings", {}))
        except SessionFileError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise SessionFileError(f"{folder / SESSION_JSON}: {exc}") from None
        s.autosave_enabled = autosave
        s.load_notes = notes
        return s
