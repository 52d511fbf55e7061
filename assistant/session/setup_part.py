"""Step 1, set-up: the robot, its tool, the link to it, the hidden obstacles of a simulation.

A part mixed into `Session`."""

from __future__ import annotations

import contextlib

import numpy as np

from assistant.collision.reports import Obstacle
from assistant.links.link import LinkEvent, LinkEventKind, RobotLink
from assistant.links.settings import LinkSettings, make_link
from assistant.robots.catalog import RobotSpec, ToolSpec
from assistant.robots.model import Robot
from assistant.session.contract import PartContract
from assistant.session.events import (
    CollisionRecorded,
    RobotHalted,
    RobotMoved,
)
from assistant.session.types import (
    HiddenObstacle,
    SessionError,
)
from assistant.transforms import inv_T

Array = np.ndarray


class SetupActions(PartContract):
    """Step 1, set-up: the robot, its tool, the link to it, the hidden obstacles of a simulation."""

    # ================================================================== 1. set-up
    def choose_robot(self, spec: RobotSpec) -> Robot:
        """Pick the robot (built-in RV-2AJ or a URDF) and its tool."""
        with self._action("choose the robot", ("setup",), scene="robot"):
            robot = spec.build()  # errors (missing URDF, bad mesh) before anything changes
            self.cell.robot_spec = spec
            self._q_sim = None
            self._drop_link()
            self._world = None
            if self.cell.objects:
                self._start_check()
        return robot

    def set_tool(self, tool: ToolSpec) -> Robot:
        from dataclasses import replace

        return self.choose_robot(replace(self.cell.robot_spec, tool=tool))

    def set_link(self, settings: LinkSettings) -> None:
        """Choose how the assistant talks to the robot (simulated, MELFA, KUKA REST)."""
        with self._action("choose the robot link", ("setup",), undoable=False, scene="link"):
            self._drop_link()
            self.link_settings = settings

    def set_simulation_speed(self, time_scale: float, *, count: bool = True) -> None:
        """How fast the simulated robot runs (robot seconds per wall second, 1 = real time);
        in any step while the robot stands still. The page runs it at a person's pace,
        scripts as fast as the sample says."""
        from dataclasses import replace

        if not 0.01 <= float(time_scale) <= 100.0:
            raise SessionError(f"simulation speed {time_scale:g}x: give 0.01 to 100 times "
                               "real time")
        with self._action("change the simulation speed", None, undoable=False, scene="link",
                          count=count):
            if self.link_settings.time_scale != float(time_scale):
                self.link_settings = replace(self.link_settings, time_scale=float(time_scale))
                if self.link_settings.kind == "simulated":
                    self._drop_link()  # made again with the new clock where it stands

    def set_hidden_obstacles(self, hidden: list[HiddenObstacle]) -> None:
        """Obstacles only the simulated robot knows (they stand in for reality)."""
        with self._action("set the simulated world", None, undoable=False, scene="hidden"):
            self.hidden = list(hidden)
            self._drop_link()

    def link(self) -> RobotLink:
        """The connected link, connecting on first use."""
        with self._lock:
            if self._link is None:
                hidden = [Obstacle(h.name, inv_T(self.T_world_base()) @ h.T_world_object,
                                   (h.primitive().collision_shape(),)) for h in self.hidden]
                link = make_link(self.link_settings, self.robot, hidden,
                                 log_dir=self.link_log_dir())
                if self._q_sim is not None and hasattr(link, "set_joints"):
                    link.set_joints(self._q_sim)
                if hasattr(link, "wait_for_operator"):
                    link.wait_for_operator = self.operator_confirms_contacts
                link.subscribe(self._on_link_event)
                self._link = link
            if not self._link.connected:
                self._link.connect()
            return self._link

    def link_log_dir(self):  # noqa: ANN201
        """Where the links write their wire log: ``links/`` in the session folder."""
        return None if self.folder is None else self.folder / "links"

    def self_collision_rule(self, *, compute: bool = True) -> list[str] | None:
        """The robot's one self-collision rule in the operator's words, a line per kind of
        decision (`collision.self_rule`; teach, plan, jog and the world model use it).
        `compute=False`: None unless already known (memory or disk) - a mesh arm takes a
        second or two to sample the first time."""
        from assistant.collision.self_rule import link_words, self_collision_rule

        robot = self.robot
        rule = self_collision_rule(robot, compute=compute)
        return None if rule is None else rule.lines(link_words(robot))

    def check_link(self):  # noqa: ANN201
        """The link's pre-flight checklist (`assistant.links.checklist`) for the chosen
        settings and robot; moves nothing, changes nothing in the session."""
        from assistant.links.checklist import check_link

        return check_link(self.link_settings, self.robot, log_dir=self.link_log_dir())

    def _drop_link(self) -> None:
        if self._link is not None:
            with contextlib.suppress(Exception):
                self._q_sim = np.asarray(self._link.current_joints(), dtype=float)
            with contextlib.suppress(Exception):
                self._link.close()
            self._link = None

    def set_operator_confirms_contacts(self, on: bool) -> None:
        """The simulated robot halts against a hidden obstacle and waits for Collision!
        (the page: a person presses it) instead of reporting the contact itself."""
        self.operator_confirms_contacts = bool(on)
        link = self._link
        if link is not None and hasattr(link, "wait_for_operator"):
            link.wait_for_operator = bool(on)

    def _on_link_event(self, ev: LinkEvent) -> None:
        if ev.q is not None:
            self._q_sim = np.asarray(ev.q, dtype=float)
            self.bus.emit(RobotMoved(self._q_sim.copy()))
        if ev.message.startswith("halted, touching"):
            self.halted = True
            self.halts_this_run += 1
            self.bus.emit(RobotHalted(ev.message.split(":", 1)[-1].strip()))
        if ev.kind == LinkEventKind.COLLISION_INDICATED:
            self.halted = False
        if ev.kind == LinkEventKind.COLLISION_INDICATED and ev.q is not None:
            # The executor/explorer feeds the world model; the session keeps the posture so a
            # reloaded session knows it too.
            with self._lock:
                self.recorded_collisions.append(np.asarray(ev.q, float).copy())
                self.counters.collision_indications += 1
                self._autosave()  # saved before the page says "Collision #n recorded"
            self.bus.emit(CollisionRecorded(np.asarray(ev.q, float).copy(),
                                            self.counters.collision_indications,
                                            "operator" if "operator" in ev.message else "robot"))
        if ev.kind == LinkEventKind.LINK_LOST:
            self.machine.enter_error(f"robot link lost: {ev.message}")
            self._error(f"robot link lost: {ev.message}",
                        "Check the cable/network, then press Reconnect; the plan is kept.")
            self._emit_state()

    def reconnect_link(self) -> None:
        with self._lock:
            link = self._link
        if link is None:
            self.link()
        else:
            link.connect()
        with self._lock:
            self.machine.clear_error()
        self._emit_state()

    def acknowledge_error(self) -> None:
        with self._lock:
            self.machine.clear_error()
        self._emit_state()
