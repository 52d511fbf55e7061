"""The editable part of a session as one immutable snapshot: undo/redo swaps snapshots.

Objects are immutable `CellObject` values (meshes shared, never copied), locations are
immutable `Location`s and the mission is kept as its JSON, so a snapshot costs a few dicts
and restoring one can never leave half an edit behind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.cell.model import Cell, CellObject
from assistant.mission.model import Location, Mission

Array = np.ndarray


@dataclass(frozen=True)
class Document:
    objects: tuple[CellObject, ...]
    frames: tuple[tuple[str, tuple[tuple[float, ...], ...]], ...]
    T_world_base: tuple[tuple[float, ...], ...]
    locations: tuple[Location, ...]
    mission: dict

    @staticmethod
    def capture(cell: Cell, locations: dict[str, Location], mission: Mission) -> Document:
        return Document(
            tuple(cell.objects.values()),
            tuple((k, _t(v)) for k, v in cell.frames.items()),
            _t(cell.T_world_base),
            tuple(locations.values()),
            mission.to_json(),
        )

    def restore(self, cell: Cell, locations: dict[str, Location]) -> Mission:
        """Put this snapshot back into the live cell and location table; returns the mission."""
        cell.objects.clear()
        for obj in self.objects:
            cell.objects[obj.name] = obj
        cell.frames.clear()
        for name, T in self.frames:
            cell.frames[name] = np.array(T)
        cell.set_base_pose(np.array(self.T_world_base))
        locations.clear()
        for loc in self.locations:
            locations[loc.name] = loc
        return Mission.from_json(self.mission)

    def obstacles_key(self) -> tuple:
        """Changes whenever anything the world model depends on changes."""
        return (tuple((o.name, id(o.display_mesh), o.role.value, _t(o.T_world_object))
                      for o in self.objects), self.T_world_base)


def _t(T: Array) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(v) for v in row) for row in np.asarray(T))
