"""Step 1, set-up: the robot, its tool, the link to it, the hidden obstacles of a simulation.

A part of the `Session`, composed (`Session.setup`): it owns the robot link, the simulated
robot's joints while no link stands, and what the simulated robot's halts say; it reaches the
rest of the session only through the parts' contract (`PartContract`)."""

from __future__ import annotations

import contextlib

import numpy as np

from assistant.collision.reports import Obstacle
from assistant.links.link import LinkEvent, LinkEventKind, RobotLink
from assistant.links.settings import LinkSettings, make_link
from assistant.robots.catalog import RobotSpec, ToolSpec
from assistant.robots.model import Robot
from assistant.session.contract import PartContract
from assistant.session.events import RobotHalted, RobotMoved
from assistant.session.types import (
    HiddenObstacle,
    SessionError,
)
from assistant.transforms import inv_T

Array = np.ndarray


class SetupPart:
    """Step 1, set-up: the robot, its tool, the link to it, the hidden obstacles of a simulation."""

    def __init__(self, core: PartContract) -> None:
        self._core = core
        #: The robot link, made and connected on first use (`link`); None until then.
        self.robot_link: RobotLink | None = None
        #: The robot's joints while no link is connected (None: the home posture).
        self.q_sim: Array | None = None
        #: The page's simulated robot halts against a hidden obstacle and waits for the
        #: operator's Collision!; scripts keep the self-reporting robot.
        self.operator_confirms_contacts = False
        #: The simulated robot stands against something unknown, waiting for Collision!.
        self.halted = False
        #: Halts in the run under way (the run's sentence counts them).
        self.halts_this_run = 0
        #: How to reach the robot (saved with the session; passwords in secrets.json).
        self.link_settings = LinkSettings()
        #: What only the simulated robot knows (saved with the session).
        self.hidden: list[HiddenObstacle] = []

    def begin_run(self) -> None:
        """A run starts: no halt yet."""
        self.halted, self.halts_this_run = False, 0

    # ================================================================== 1. set-up
    def choose_robot(self, spec: RobotSpec) -> Robot:
        """Pick the robot (built-in RV-2AJ or a URDF) and its tool."""
        with self._core.action("choose the robot", ("setup",), scene="robot"):
            robot = spec.build()  # errors (missing URDF, bad mesh) before anything changes
            self._core.cell.robot_spec = spec
            self.q_sim = None
            self.drop_link()
            self._core.planning.backend = None
            if self._core.cell.objects:
                self._core.start_posture.recheck()
        return robot

    def set_tool(self, tool: ToolSpec) -> Robot:
        from dataclasses import replace

        return self.choose_robot(replace(self._core.cell.robot_spec, tool=tool))

    def set_link(self, settings: LinkSettings) -> None:
        """Choose how the assistant talks to the robot (simulated, MELFA, KUKA REST)."""
        with self._core.action("choose the robot link", ("setup",), undoable=False, scene="link"):
            self.drop_link()
            self.link_settings = settings

    def set_simulation_speed(self, time_scale: float, *, count: bool = True) -> None:
        """How fast the simulated robot runs (robot seconds per wall second, 1 = real time);
        in any step while the robot stands still. The page runs it at a person's pace,
        scripts as fast as the sample says."""
        from dataclasses import replace

        if not 0.01 <= float(time_scale) <= 100.0:
            raise SessionError(f"simulation speed {time_scale:g}x: give 0.01 to 100 times "
                               "real time")
        with self._core.action("change the simulation speed", None, undoable=False, scene="link",
                               count=count):
            if self.link_settings.time_scale != float(time_scale):
                self.link_settings = replace(self.link_settings,
                                                   time_scale=float(time_scale))
                if self.link_settings.kind == "simulated":
                    self.drop_link()  # made again with the new clock where it stands

    def set_hidden_obstacles(self, hidden: list[HiddenObstacle]) -> None:
        """Obstacles only the simulated robot knows (they stand in for reality)."""
        with self._core.action("set the simulated world", None, undoable=False, scene="hidden"):
            self.hidden = list(hidden)
            self.drop_link()

    def link(self) -> RobotLink:
        """The connected link, connecting on first use."""
        with self._core.lock:
            if self.robot_link is None:
                hidden = [Obstacle(h.name, inv_T(self._core.T_world_base()) @ h.T_world_object,
                                   (h.primitive().collision_shape(),)) for h in self.hidden]
                link = make_link(self.link_settings, self._core.robot, hidden,
                                 log_dir=self.link_log_dir())
                if self.q_sim is not None and hasattr(link, "set_joints"):
                    link.set_joints(self.q_sim)
                if hasattr(link, "wait_for_operator"):
                    link.wait_for_operator = self.operator_confirms_contacts
                link.subscribe(self._on_link_event)
                self.robot_link = link
            if not self.robot_link.connected:
                self.robot_link.connect()
            return self.robot_link

    def link_log_dir(self):  # noqa: ANN201
        """Where the links write their wire log: ``links/`` in the session folder."""
        return None if self._core.folder is None else self._core.folder / "links"

    def self_collision_rule(self, *, compute: bool = True) -> list[str] | None:
        """The robot's one self-collision rule in the operator's words, a line per kind of
        decision (`collision.self_rule`; teach, plan, jog and the world model use it).
        `compute=False`: None unless already known (memory or disk) - a mesh arm takes a
        second or two to sample the first time."""
        from assistant.collision.self_rule import link_words, self_collision_rule

        robot = self._core.robot
        rule = self_collision_rule(robot, compute=compute)
        return None if rule is None else rule.lines(link_words(robot))

    def check_link(self):  # noqa: ANN201
        """The link's pre-flight checklist (`assistant.links.checklist`) for the chosen
        settings and robot; moves nothing, changes nothing in the session."""
        from assistant.links.checklist import check_link

        return check_link(self.link_settings, self._core.robot, log_dir=self.link_log_dir())

    def drop_link(self) -> None:
        """Close the link (it is made again on next use), keeping where the robot stands."""
        if self.robot_link is not None:
            with contextlib.suppress(Exception):
                self.q_sim = np.asarray(self.robot_link.current_joints(), dtype=float)
            with contextlib.suppress(Exception):
                self.robot_link.close()
            self.robot_link = None

    def set_operator_confirms_contacts(self, on: bool) -> None:
        """The simulated robot halts against a hidden obstacle and waits for Collision!
        (the page: a person presses it) instead of reporting the contact itself."""
        self.operator_confirms_contacts = bool(on)
        link = self.robot_link
        if link is not None and hasattr(link, "wait_for_operator"):
            link.wait_for_operator = bool(on)

    def _on_link_event(self, ev: LinkEvent) -> None:
        if ev.q is not None:
            self.q_sim = np.asarray(ev.q, dtype=float)
            self._core.bus.emit(RobotMoved(self.q_sim.copy()))
        if ev.halt is not None:
            self.halted = True
            self.halts_this_run += 1
            self._core.bus.emit(RobotHalted(ev.halt.touching))
        if ev.kind == LinkEventKind.COLLISION_INDICATED:
            self.halted = False
        if ev.kind == LinkEventKind.COLLISION_INDICATED and ev.q is not None:
            # The run's executor (or explorer) feeds its world model itself.
            source = "operator" if ev.details.get("source") == "operator" else "robot"
            self._core.planning.record_collision(ev.q, source, learnt_by_run=True)
        if ev.kind == LinkEventKind.LINK_LOST:
            self._core.machine.enter_error(f"robot link lost: {ev.message}")
            self._core.error(f"robot link lost: {ev.message}",
                             "Check the cable/network, then press Reconnect; the plan is kept.")
            self._core.emit_state()

    def reconnect_link(self) -> None:
        with self._core.lock:
            link = self.robot_link
        if link is None:
            self.link()
        else:
            link.connect()
        with self._core.lock:
            self._core.machine.clear_error()
        self._core.emit_state()

    def acknowledge_error(self) -> None:
        with self._core.lock:
            self._core.machine.clear_error()
        self._core.emit_state()
