"""Sample cells, saving and loading (autosave and the page's settled view: `saving.py`).

A save writes the cell, then the link passwords (`link_secrets.py`, 0600), then
`session.json` (never a password); each file atomically and fsynced with its folder. A load
bounds the JSON (`store.py`), range-checks every field (`load_checks.py`), opens a session
saved mid-task idle, and reports what it changed in `load_notes`.

A part of the `Session`, composed (`Session.persistence`): it owns what was last written to
`secrets.json`; it reaches the rest of the session only through the parts' contract
(`PartContract`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TypeVar

import numpy as np

from assistant.cell.model import Cell
from assistant.cell.storage import load_cell, save_cell
from assistant.links.settings import LinkSettings
from assistant.mission.model import (
    Location,
    Mission,
    inline_locations,
)
from assistant.mission.motion import trajectory_from_json, trajectory_to_json
from assistant.session import link_secrets
from assistant.session.contract import PartContract
from assistant.session.load_checks import check_session, reset_transient
from assistant.session.store import (
    CELL_DIR,
    SESSION_JSON,
    SESSION_SCHEMA,
    SessionFileError,
    check_session_keys,
    fsync_folder,
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

Array = np.ndarray
S = TypeVar("S", bound=PartContract)


class PersistencePart:
    """Sample cells, saving and loading."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: (folder, secrets) last written to `secrets.json`: autosave rewrites it only on
        #: change.
        self.secrets_written: tuple[Path, dict[str, str]] | None = None

    # ================================================================== persistence
    def save(self, folder: str | Path) -> Path:
        """Write the whole session (cell with CAD files, mission, world observations, plan);
        on disk (fsynced) when this returns."""
        folder = Path(folder)
        with self._core.lock:
            save_cell(self._core.cell, folder / CELL_DIR)
            fsync_folder(folder / CELL_DIR)
            link, secret = link_secrets.split(self._core.link_settings.to_json(),
                                              LinkSettings().to_json())
            if self.secrets_written != (folder, secret):
                link_secrets.write(folder, secret)
                self.secrets_written = (folder, secret)
            doc = {
                "schema_version": SESSION_SCHEMA,
                "saved_at": time.time(),
                "machine": self._core.machine.to_json(),
                "locations": [loc.to_json() for loc in self._core.locations.values()],
                "mission": self._core.mission.to_json(),
                "link": link,
                "hidden_obstacles": [h.to_json() for h in self._core.hidden],
                "pointer": self._core.pointer_config,
                "counters": self._core.counters.to_json(),
                "recorded_collisions": [q.tolist()
                                        for q in self._core.planning.recorded_collisions],
                "robot_joints": self._core.current_joints().tolist(),
                "trajectory": trajectory_to_json(self._core.trajectory)
                if self._core.trajectory else None,
                "plan_report": self._core.plan_report,
                "export_dialect": self._core.export_dialect,
                "world_settings": self._core.world_settings.to_json(),
                "sample": self._core.sample,
            }
            write_json_atomic(folder / SESSION_JSON, doc)
        return folder

    def save_as(self, folder: str | Path) -> Path:
        """Save to a new folder and autosave there from now on."""
        folder = Path(folder)
        with self._core.lock:
            self._core.folder = folder
            self._core.autosave_enabled = True
            return self.save(folder)


# ================================================================== samples
def session_from_sample(cls: type[S], name_or_path: str | Path = "thesis_rv2aj",
                        folder: str | Path | None = None, *, with_objects: bool = True,
                        with_mission: bool = True, autosave: bool = True) -> S:
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
            for loc in inline_locations(doc):  # the file holds its start and goal whole
                s.locations[loc.name] = loc
            for d in doc.get("locations", ()):  # taught locations besides start and goal
                loc = Location.from_json(d)
                s.locations[loc.name] = loc
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SampleError(f"sample {src.name}: {exc}") from None
    s.sample = src.name
    s.autosave_enabled = autosave and folder is not None
    s.saving.autosave()
    return s


# ================================================================== loading
def load_session(cls: type[S], folder: str | Path, *, autosave: bool = True) -> S:
    """Restore a saved session: scene, mission, world observations and plan."""
    folder = Path(folder)
    path = folder / SESSION_JSON
    doc = read_session_json(folder)
    notes = check_session_keys(doc, path)
    secret, secret_notes = link_secrets.read(folder)
    notes += secret_notes
    try:
        cell = load_cell(folder / CELL_DIR)
        s = cls(folder, autosave=False)
        s.cell = cell
        s.machine = Machine.from_json(doc.get("machine", {}))
        notes += reset_transient(s, path)
        for d in doc.get("locations", []):
            loc = Location.from_json(d)
            s.locations[loc.name] = loc
        mission = doc.get("mission", {})
        s.mission = Mission.from_json(mission)
        notes += _adopt_inline_locations(s, mission, path)
        link = dict(doc.get("link", {}))
        in_clear = sorted(k for k in link if link_secrets.is_secret(k))
        if in_clear:
            notes.append(f"{path}: the link's {', '.join(in_clear)} was stored in clear; "
                         f"it moves to {link_secrets.SECRETS_JSON} (readable by you only)")
        # A password in session.json is newer than secrets.json (only an older cellteach
        # or a hand edit puts one there, after secrets.json was written).
        s.link_settings = LinkSettings.from_json({**secret, **link})
        s.hidden = [HiddenObstacle.from_json(h) for h in doc.get("hidden_obstacles", [])]
        s.pointer_config = dict(doc.get("pointer", {}))
        s.counters = Counters.from_json(doc.get("counters", {}))
        s.planning.recorded_collisions = [np.asarray(q, float) for q in
                                          doc.get("recorded_collisions", [])]
        q = doc.get("robot_joints")
        if q is not None:
            s.setup.q_sim = np.asarray(q, float)
        t = doc.get("trajectory")
        s.trajectory = trajectory_from_json(t) if t else None
        s.plan_report = doc.get("plan_report")
        s.export_dialect = str(doc.get("export_dialect", "melfa"))
        s.sample = doc.get("sample")
        s.world_settings = WorldSettings.from_json(doc.get("world_settings", {}))
        notes += check_session(s, path)
    except SessionFileError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        raise SessionFileError(f"{path}: {exc}") from None
    s.autosave_enabled = autosave
    s.load_notes = notes
    if in_clear and autosave:
        with s.lock:
            s.saving.autosave()  # the password leaves session.json now, not at the next edit
    return s


def _adopt_inline_locations(s: PartContract, mission: dict, path: Path) -> list[str]:
    """A session saved before the mission named its locations holds its start and goal
    whole inside the mission too: one missing from the locations joins them; where both
    hold one, the locations' (the page showed it) is kept, with a note if they differ."""
    notes = []
    for loc in inline_locations(mission):
        known = s.locations.get(loc.name)
        if known is None:
            s.locations[loc.name] = loc
        elif known != loc:
            notes.append(f"{path}: the mission's copy of {loc.name} differed from the taught "
                         f"location {loc.name}; the taught location is kept")
    return notes
