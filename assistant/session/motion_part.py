"""Moving the robot by hand: jogging, Stop, Collision!, cancel and close.

A part of the `Session`, composed (`Session.motion`): it has no state of its own: it drives the
robot through `setup`'s link; it reaches the rest of the session only through the parts'
contract (`PartContract`)."""

from __future__ import annotations

from concurrent.futures import Future
from typing import Any

import numpy as np

from assistant.robots.model import UnreachableError
from assistant.session.contract import PartContract
from assistant.session.events import (
    Notice,
)
from assistant.session.types import (
    SessionError,
)
from assistant.transforms import inv_T
from workflow.machine import Mode

Array = np.ndarray


class MotionPart:
    """Moving the robot by hand: jogging, Stop, Collision!, cancel and close."""

    def __init__(self, core: PartContract) -> None:
        self._core = core

    # ================================================================== robot motion (jog)
    def jog_joints(self, q: Array, *, wait: bool = True) -> Future:
        """Move the robot to joint values (checked against limits and known obstacles)."""
        q = np.asarray(q, dtype=float)
        r = self._core.robot
        if q.shape != (r.dof,):
            raise SessionError(f"{r.name} has {r.dof} joints, got {q.shape[0]} values")
        viol = r.limits.violations(q, r.joint_names)
        if viol:
            raise SessionError("joint limit: " + "; ".join(viol))
        checker = self._core.known_checker()
        q0 = self._core.current_joints()
        mc = checker.check_motion(q0, q)
        if not mc.valid:
            raise SessionError(f"that move would collide: {mc.report.describe()}"
                               if mc.report else "that move would collide")
        fut = self._core.run_motion(
            "jog", lambda p: self._core.setup.link().move_path(np.array([q0, q])))
        if wait:
            fut.result()
        return fut

    def jog_tcp(self, T_world_tool: Array, *, wait: bool = True) -> Future:
        """Move the TCP to a pose by IK (5-axis: the orientation is projected, and said so)."""
        T_base = inv_T(self._core.T_world_base()) @ np.asarray(T_world_tool, float)
        res = self._core.robot.ik(T_base, seed=self._core.current_joints())
        if not res.ok and res.nearest_T_base_tool is not None:
            self._core.bus.emit(Notice(res.message))
            res = self._core.robot.ik(res.nearest_T_base_tool, seed=self._core.current_joints())
        if not res.ok:
            raise UnreachableError(res.message, res)
        return self.jog_joints(res.best(self._core.current_joints()), wait=wait)

    def adopt_hold(self, hold: Any) -> None:
        """Take over the page's motion authority (a session loaded into a running page)."""
        self._core.hold = hold
        hold.on_lost(self.holder_gone)

    def holder_gone(self, why: str) -> None:
        """The enabling switch was let go (`MotionHold`): the robot stops now and waits;
        a run is left resumable for the next holder."""
        if self._core.machine.mode != Mode.MOVING:
            return
        self.stop()
        self._core.bus.emit(Notice(f"The robot stopped: {why}. It waits for the page that holds "
                                   "motion authority to resume."))

    def stop(self) -> None:
        """Stop the robot now (from any thread)."""
        link = self._core.setup.robot_link
        if link is not None:
            link.stop()
        self._core.worker.cancel()

    def indicate_collision(self) -> None:
        """The operator's Collision! button: stop and record the posture as an obstacle."""
        link = self._core.setup.robot_link
        if link is not None and self._core.machine.mode == Mode.MOVING:
            link.indicate_collision()
            return
        # Not moving: record the current posture directly (e.g. after a manual jog).
        q = self._core.current_joints()
        self._core.planning.record_collision(q, "operator", learnt_by_run=False)

    def close(self) -> None:
        """Stop the robot and background work, close the link and the cameras."""
        self.stop()
        self._core.worker.join(5.0)
        self._core.teaching.stop_pointer()
        with self._core.lock:
            self._core.setup.drop_link()

    def cancel(self) -> None:
        self._core.worker.cancel()
        link = self._core.setup.robot_link
        if link is not None and self._core.machine.mode == Mode.MOVING:
            link.stop()
