"""What a part of the `Session` may use of the whole: the shared state, the lock, the action
wrapper, the event bus, and the few verbs of other parts it calls.

Every part (`*_part.py`, `saving`) derives from `PartContract`, so a type checker reads each
part against this one list instead of guessing: a part that reaches for anything else, or
calls a verb with the wrong arguments, is an error in `.ci/run`'s mypy step. The class holds
declarations only (annotations, and signatures under TYPE_CHECKING): at run time the state
is the `Session`'s own (set in `Session.__init__`) and the verbs are the parts' own.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from assistant.cell.model import Cell, CellObject
    from assistant.collision.checker import CollisionChecker
    from assistant.links.link import RobotLink
    from assistant.links.settings import LinkSettings
    from assistant.mission.model import Location, LocationSource, Mission
    from assistant.mission.motion import Trajectory
    from assistant.progress import Progress
    from assistant.robots.model import Robot
    from assistant.session.events import EventBus
    from assistant.session.motion_hold import MotionHold
    from assistant.session.pointer_live import LivePointer
    from assistant.session.types import Counters, HiddenObstacle
    from assistant.session.worker import Worker
    from assistant.session.world_settings import WorldSettings
    from workflow.machine import Machine

Array = np.ndarray


class PartContract:
    """The state and verbs the parts share (declarations; see the module docstring)."""

    # ------------------------------------------------------------- the core: state, lock, bus
    bus: EventBus
    worker: Worker
    machine: Machine
    _lock: threading.RLock
    counters: Counters
    hold: MotionHold
    # ------------------------------------------------------------- the operator's document
    cell: Cell
    locations: dict[str, Location]
    mission: Mission
    hidden: list[HiddenObstacle]
    link_settings: LinkSettings
    pointer_config: dict[str, Any]
    export_dialect: str
    world_settings: WorldSettings
    sample: str | None
    load_notes: list[str]
    # ------------------------------------------------------------- results and run state
    trajectory: Trajectory | None
    program: Any  # the exported program (`Session.exporter` owns it)
    plan_report: dict[str, Any] | None
    recorded_collisions: list[Array]
    halts_this_run: int
    _link: RobotLink | None
    _q_sim: Array | None
    _world: Any
    _world_key: tuple | None
    last_run: dict | None
    _pointer: LivePointer | None  # while the camera step is open
    # ------------------------------------------------------------- where it is saved
    folder: Path | None
    autosave_enabled: bool

    if TYPE_CHECKING:
        # the core (session.py)
        def __init__(self, folder: str | Path | None = None, *,
                     autosave: bool = True) -> None: ...
        @contextlib.contextmanager
        def _action(self, label: str, steps: tuple[str, ...] | None, *, undoable: bool = True,
                    scene: str = "", count: bool = True) -> Iterator[None]: ...
        def _emit_state(self) -> None: ...
        def _error(self, message: str, hint: str = "") -> None: ...
        def _obstacles_key(self) -> tuple: ...
        def _start_check(self) -> None: ...
        @property
        def robot(self) -> Robot: ...
        @property
        def world_ready(self) -> bool: ...
        def current_joints(self) -> Array: ...
        def T_world_base(self) -> Array: ...
        def tcp_world(self, q: Array | None = None) -> Array: ...
        # saving, persistence
        def _autosave(self) -> None: ...
        def save(self, folder: str | Path) -> Path: ...
        # set-up: the robot link
        def link(self) -> RobotLink: ...
        def _drop_link(self) -> None: ...
        # cell
        def _frame(self, name: str) -> Array: ...
        def _note_working_volume(self, obj: CellObject) -> None: ...
        # teach
        def _loc(self, name: str) -> Location: ...
        def _make_location(self, name: str, T_world_tool: Array, source: LocationSource,
                           q_hint: Array | None, uncertainty_m: float) -> Location: ...
        def _relink_mission(self, name: str) -> None: ...
        def stop_pointer(self) -> None: ...
        # motion, planning, start posture
        def _known_checker(self) -> CollisionChecker: ...
        def _run_motion(self, task: str, fn: Callable[[Progress], Any]) -> Future: ...
        def _planner_config(self) -> Any: ...
        def _run_busy(self, task: str, fn: Callable[[Progress], Any],
                      steps: tuple[str, ...] | None = None, *, moving: bool = False) -> Future: ...
        def _require_free_start(self) -> None: ...
