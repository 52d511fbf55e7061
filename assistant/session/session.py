"""`Session`: the one facade every operator action goes through (web UI, scripts, tests, CLI).

A thin front, composed the way viser's server is (`server.scene`, `server.gui`): the core
(`core.py`: the shared state, the lock, the action wrapper, the long-task runners, the event
bus and the workflow) and the parts by concern, each an object that owns its own state and
reaches the rest only through the core's public methods and the other parts' public ones
(`contract.PartContract` declares that list; mypy reads every part against it):

    setup (robot, tool, link)      objects (CAD, placement, frames)   layout (a layout DXF)
    teaching (locations, paths,    motion (jog, Stop, Collision!)     planning (world model,
      the marker pointer)                                               plan, execute, explore)
    start_posture                  studies (placement studies)        exporter (step 7)
    scene (what the page draws)    persistence (samples, save, load)  saving (autosave)

Every verb the page and the scripts call stays on the session as a one-line hand-over to the
part that does the work (`hand_over`), so `session.plan()` is `session.planning.plan()`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from assistant.session.cell_part import CellPart
from assistant.session.core import SessionCore
from assistant.session.export_part import ExportPart
from assistant.session.handover import Forward, hand_over
from assistant.session.layout_part import LayoutPart
from assistant.session.motion_part import MotionPart
from assistant.session.persistence_part import (
    PersistencePart,
    load_session,
    session_from_sample,
)
from assistant.session.planning_part import PlanningPart
from assistant.session.saving import SavingPart
from assistant.session.scene_part import ScenePart
from assistant.session.setup_part import SetupPart
from assistant.session.start_part import StartPosturePart
from assistant.session.study_part import StudyPart
from assistant.session.teach_part import TeachPart

if TYPE_CHECKING:
    from typing_extensions import Self

    from assistant.study import StudyResult

Array = np.ndarray


class Session(SessionCore):
    """Everything the operator does, headless or behind the web page: the core's state and
    workflow, and the verbs of its composed parts (see the module)."""

    def __init__(self, folder: str | Path | None = None, *, autosave: bool = True):
        super().__init__(folder, autosave=autosave)
        #: Step 1: the robot, its tool, the link (owns the link and the simulated joints).
        self.setup = SetupPart(self)
        #: Steps 2-3: CAD import, primitives, roles, placement, measured frames.
        self.objects = CellPart(self)
        #: Step 2: a cell-layout drawing's parts and locations in one action.
        self.layout = LayoutPart(self)
        #: Step 4: locations, start and goal, paths (owns the live pointer).
        self.teaching = TeachPart(self)
        #: Moving the robot by hand: jog, Stop, Collision!, cancel, close.
        self.motion = MotionPart(self)
        #: Steps 5-6: world model, explore, plan, execute (owns the world and the last run).
        self.planning = PlanningPart(self)
        #: Step 7: the exported program and the verbs that make and send it.
        self.exporter = ExportPart(self)
        #: Placement studies: the last study's result and the verbs that run one.
        self.studies = StudyPart(self)
        #: What the page draws (as viser's `server.scene`).
        self.scene = ScenePart(self)
        #: The start posture against the cell: what touches and the way out.
        self.start_posture = StartPosturePart(self)
        #: Samples, save and load (owns what was last written to secrets.json).
        self.persistence = PersistencePart(self)
        #: Autosave and the page's settled view (owns why the last autosave failed).
        self.saving = SavingPart(self)
        self.hold.on_lost(self.motion.holder_gone)

    # ================================================================== samples, load
    @classmethod
    def from_sample(cls, name_or_path: str | Path = "thesis_rv2aj",
                    folder: str | Path | None = None, *, with_objects: bool = True,
                    with_mission: bool = True, autosave: bool = True) -> Self:
        """A session on a sample cell (`persistence_part.session_from_sample`)."""
        return session_from_sample(cls, name_or_path, folder, with_objects=with_objects,
                                   with_mission=with_mission, autosave=autosave)

    @classmethod
    def load(cls, folder: str | Path, *, autosave: bool = True) -> Self:
        """Restore a saved session (`persistence_part.load_session`)."""
        return load_session(cls, folder, autosave=autosave)

    # ================================================================== state in the parts
    pending_point = Forward[Any]("teaching", "pending_point")
    last_run = Forward["dict | None"]("planning", "last_run")
    save_error = Forward[str]("saving", "save_error")
    recorded_collisions = Forward["list[Array]"]("planning", "recorded_collisions")

    @property
    def placement_study(self) -> StudyResult | None:
        """The last placement study's result (owned by `studies`); None before the first."""
        return self.studies.placement_study

    # ================================================================== 1. set-up
    choose_robot = hand_over("setup", SetupPart.choose_robot)
    set_tool = hand_over("setup", SetupPart.set_tool)
    set_link = hand_over("setup", SetupPart.set_link)
    set_simulation_speed = hand_over("setup", SetupPart.set_simulation_speed)
    set_hidden_obstacles = hand_over("setup", SetupPart.set_hidden_obstacles)
    link = hand_over("setup", SetupPart.link)
    link_log_dir = hand_over("setup", SetupPart.link_log_dir)
    self_collision_rule = hand_over("setup", SetupPart.self_collision_rule)
    check_link = hand_over("setup", SetupPart.check_link)
    set_operator_confirms_contacts = hand_over("setup", SetupPart.set_operator_confirms_contacts)
    reconnect_link = hand_over("setup", SetupPart.reconnect_link)
    acknowledge_error = hand_over("setup", SetupPart.acknowledge_error)
    # ================================================================== 2-3. CAD, placement
    import_cad = hand_over("objects", CellPart.import_cad)
    start_import_cad = hand_over("objects", CellPart.start_import_cad)
    import_cad_path = hand_over("objects", CellPart.import_cad_path)
    add_primitive = hand_over("objects", CellPart.add_primitive)
    remove_object = hand_over("objects", CellPart.remove_object)
    set_object_role = hand_over("objects", CellPart.set_object_role)
    place_object = hand_over("objects", CellPart.place_object)
    fit_object_pose = hand_over("objects", CellPart.fit_object_pose)
    measure_with_robot = hand_over("objects", CellPart.measure_with_robot)
    calibrate_frame = hand_over("objects", CellPart.calibrate_frame)
    place_object_in_frame = hand_over("objects", CellPart.place_object_in_frame)
    read_layout = hand_over("layout", LayoutPart.read_layout)
    import_layout = hand_over("layout", LayoutPart.import_layout)
    start_import_layout = hand_over("layout", LayoutPart.start_import_layout)
    start_import_file = hand_over("layout", LayoutPart.start_import_file)
    import_layout_path = hand_over("layout", LayoutPart.import_layout_path)
    # ================================================================== 4. teach
    teach = hand_over("teaching", TeachPart.teach)
    teach_from_robot = hand_over("teaching", TeachPart.teach_from_robot)
    teach_from_cad_click = hand_over("teaching", TeachPart.teach_from_cad_click)
    teach_from_pointer = hand_over("teaching", TeachPart.teach_from_pointer)
    teach_by_pointer_dwell = hand_over("teaching", TeachPart.teach_by_pointer_dwell)
    simulate_pointer_dwell = hand_over("teaching", TeachPart.simulate_pointer_dwell)
    start_pointer = hand_over("teaching", TeachPart.start_pointer)
    stop_pointer = hand_over("teaching", TeachPart.stop_pointer)
    pointer_move_to = hand_over("teaching", TeachPart.pointer_move_to)
    pointer_state = hand_over("teaching", TeachPart.pointer_state)
    teach_pending_point = hand_over("teaching", TeachPart.teach_pending_point)
    calibrate_pointer_color = hand_over("teaching", TeachPart.calibrate_pointer_color)
    camera_models = hand_over("teaching", TeachPart.camera_models)
    remove_location = hand_over("teaching", TeachPart.remove_location)
    set_start = hand_over("teaching", TeachPart.set_start)
    set_goal = hand_over("teaching", TeachPart.set_goal)
    add_path = hand_over("teaching", TeachPart.add_path)
    remove_path = hand_over("teaching", TeachPart.remove_path)
    move_path = hand_over("teaching", TeachPart.move_path)
    add_drawing = hand_over("teaching", TeachPart.add_drawing)
    set_path_actions = hand_over("teaching", TeachPart.set_path_actions)
    # ================================================================== moving the robot
    jog_joints = hand_over("motion", MotionPart.jog_joints)
    jog_tcp = hand_over("motion", MotionPart.jog_tcp)
    adopt_hold = hand_over("motion", MotionPart.adopt_hold)
    stop = hand_over("motion", MotionPart.stop)
    indicate_collision = hand_over("motion", MotionPart.indicate_collision)
    close = hand_over("motion", MotionPart.close)
    cancel = hand_over("motion", MotionPart.cancel)
    # ================================================================== 5-6. world, plan, run
    start_build_world = hand_over("planning", PlanningPart.start_build_world)
    set_world_settings = hand_over("planning", PlanningPart.set_world_settings)
    build_world = hand_over("planning", PlanningPart.build_world)
    start_plan = hand_over("planning", PlanningPart.start_plan)
    plan = hand_over("planning", PlanningPart.plan)
    start_execute = hand_over("planning", PlanningPart.start_execute)
    execute = hand_over("planning", PlanningPart.execute)
    resume_execution = hand_over("planning", PlanningPart.resume_execution)
    run_state = hand_over("planning", PlanningPart.run_state)
    start_drive_final = hand_over("planning", PlanningPart.start_drive_final)
    drive_final = hand_over("planning", PlanningPart.drive_final)
    final_driven = hand_over("planning", PlanningPart.final_driven)
    forget_indication = hand_over("planning", PlanningPart.forget_indication)
    learnt_indications = hand_over("planning", PlanningPart.learnt_indications)
    start_explore = hand_over("planning", PlanningPart.start_explore)
    explore = hand_over("planning", PlanningPart.explore)
    order_mission = hand_over("planning", PlanningPart.order_mission)
    occupancy_cells = hand_over("planning", PlanningPart.occupancy_cells)
    learnt_cells = hand_over("planning", PlanningPart.learnt_cells)
    learnt_view = hand_over("planning", PlanningPart.learnt_view)
    road_cells = hand_over("planning", PlanningPart.road_cells)
    #: (the sample scripts' tests compare their planner settings with the session's)
    _planner_config = hand_over("planning", PlanningPart.planner_config)
    # ================================================================== 7. export
    export = hand_over("exporter", ExportPart.export)
    upload_program = hand_over("exporter", ExportPart.upload_program)
    # ================================================================== the start posture
    start_posture_problem = hand_over("start_posture", StartPosturePart.problem_now)
    move_to_free_posture = hand_over("start_posture", StartPosturePart.move_to_free_posture)

    def start_posture_links(self) -> tuple[str, ...]:
        """The links the last start check found touching (the page draws them red)."""
        return self.start_posture.links

    def start_posture_text(self) -> str:
        """What the last start check found touching, in the operator's words ("" if free)."""
        return self.start_posture.problem or ""

    # ================================================================== what the page draws
    scene_objects = hand_over("scene", ScenePart.scene_objects)
    robot_visuals = hand_over("scene", ScenePart.robot_visuals)
    link_poses_world = hand_over("scene", ScenePart.link_poses_world)
    path_polylines = hand_over("scene", ScenePart.path_polylines)
    plan_polylines = hand_over("scene", ScenePart.plan_polylines)
    # ================================================================== placement studies
    study_problem = hand_over("studies", StudyPart.study_problem)
    start_study_placement = hand_over("studies", StudyPart.start_study_placement)
    study_placement = hand_over("studies", StudyPart.study_placement)
    apply_placement = hand_over("studies", StudyPart.apply_placement)
    # ================================================================== save
    save = hand_over("persistence", PersistencePart.save)
    save_as = hand_over("persistence", PersistencePart.save_as)
    settled = hand_over("saving", SavingPart.settled)
