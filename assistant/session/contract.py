"""What a part of the `Session` may use of the whole: the core's shared state, the lock, the
action wrapper, the long-task runners, the event bus, and the other parts (by their public
methods).

Every part (`*_part.py`, `saving`) is built with the session as its core, typed as
`PartContract`, so a type checker reads each part against this one list instead of guessing:
a part that reaches for anything else, or calls a verb with the wrong arguments, is an error
in `.ci/run`'s mypy step. The class holds declarations only (annotations, and signatures
under TYPE_CHECKING): at run time the core is `core.SessionCore` (its base) and the parts are
the `Session`'s own.
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
    from assistant.cell.model import Cell
    from assistant.collision.checker import CollisionChecker
    from assistant.links.settings import LinkSettings
    from assistant.mission.model import Location, Mission
    from assistant.mission.motion import Trajectory
    from assistant.progress import Progress
    from assistant.robots.model import Robot
    from assistant.session.cell_part import CellPart
    from assistant.session.events import EventBus
    from assistant.session.export_part import ExportPart
    from assistant.session.history import History
    from assistant.session.layout_part import LayoutPart
    from assistant.session.motion_hold import MotionHold
    from assistant.session.motion_part import MotionPart
    from assistant.session.persistence_part import PersistencePart
    from assistant.session.planning_part import PlanningPart
    from assistant.session.saving import SavingPart
    from assistant.session.scene_part import ScenePart
    from assistant.session.setup_part import SetupPart
    from assistant.session.start_part import StartPosturePart
    from assistant.session.study_part import StudyPart
    from assistant.session.teach_part import TeachPart
    from assistant.session.types import Counters, HiddenObstacle
    from assistant.session.worker import Worker
    from assistant.session.world_settings import WorldSettings
    from workflow.machine import Machine

Array = np.ndarray


class PartContract:
    """The core's state and verbs, and the parts (declarations; see the module docstring)."""

    # ------------------------------------------------------------- the core: state, lock, bus
    bus: EventBus
    worker: Worker
    machine: Machine
    lock: threading.RLock
    history: History
    counters: Counters
    hold: MotionHold
    # ------------------------------------------------------------- the operator's document
    cell: Cell
    locations: dict[str, Location]
    mission: Mission
    sample: str | None
    load_notes: list[str]
    # ----------------------- the document the parts keep, by the core's names (`Forward`)
    hidden: list[HiddenObstacle]  # setup
    link_settings: LinkSettings  # setup
    pointer_config: dict[str, Any]  # teaching
    export_dialect: str  # exporter
    world_settings: WorldSettings  # planning
    trajectory: Trajectory | None  # planning
    plan_report: dict[str, Any] | None  # planning
    # ------------------------------------------------------------- where it is saved
    folder: Path | None
    autosave_enabled: bool
    # ------------------------------------------------------------- the parts
    setup: SetupPart
    objects: CellPart
    layout: LayoutPart
    teaching: TeachPart
    motion: MotionPart
    planning: PlanningPart
    exporter: ExportPart
    studies: StudyPart
    scene: ScenePart
    start_posture: StartPosturePart
    persistence: PersistencePart
    saving: SavingPart

    if TYPE_CHECKING:
        # the core (core.py)
        def __init__(self, folder: str | Path | None = None, *,
                     autosave: bool = True) -> None: ...
        @contextlib.contextmanager
        def action(self, label: str, steps: tuple[str, ...] | None, *, undoable: bool = True,
                   scene: str = "", count: bool = True) -> Iterator[None]: ...
        def run_busy(self, task: str, fn: Callable[[Progress], Any],
                     steps: tuple[str, ...] | None = None, *, moving: bool = False) -> Future: ...
        def run_motion(self, task: str, fn: Callable[[Progress], Any]) -> Future: ...
        def emit_state(self) -> None: ...
        def error(self, message: str, hint: str = "") -> None: ...
        def obstacles_key(self) -> tuple: ...
        def known_checker(self) -> CollisionChecker: ...
        @property
        def robot(self) -> Robot: ...
        @property
        def program(self) -> Any: ...  # the exported program (`exporter` owns it)
        @program.setter
        def program(self, value: Any) -> None: ...
        @property
        def world_ready(self) -> bool: ...
        def current_joints(self) -> Array: ...
        def T_world_base(self) -> Array: ...
        def tcp_world(self, q: Array | None = None) -> Array: ...
