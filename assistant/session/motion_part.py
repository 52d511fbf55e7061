"""Moving the robot by hand: jogging, Stop, Collision!, cancel and close.

A part mixed into `Session`."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.progress import Cancelled, Progress
from assistant.robots.model import UnreachableError
from assistant.session.contract import PartContract
from assistant.session.events import (
    CollisionRecorded,
    Notice,
)
from assistant.session.types import (
    SessionError,
    hint_for,
)
from assistant.transforms import inv_T
from workflow.machine import Mode

Array = np.ndarray


class MotionActions(PartContract):
    """Moving the robot by hand: jogging, Stop, Collision!, cancel and close."""

    # ================================================================== robot motion (jog)
    def jog_joints(self, q: Array, *, wait: bool = True) -> Future:
        """Move the robot to joint values (checked against limits and known obstacles)."""
        q = np.asarray(q, dtype=float)
        r = self.robot
        if q.shape != (r.dof,):
            raise SessionError(f"{r.name} has {r.dof} joints, got {q.shape[0]} values")
        viol = r.limits.violations(q, r.joint_names)
        if viol:
            raise SessionError("joint limit: " + "; ".join(viol))
        checker = self._known_checker()
        q0 = self.current_joints()
        mc = checker.check_motion(q0, q)
        if not mc.valid:
            raise SessionError(f"that move would collide: {mc.report.describe()}"
                               if mc.report else "that move would collide")
        fut = self._run_motion("jog", lambda p: self.link().move_path(np.array([q0, q])))
        if wait:
            fut.result()
        return fut

    def jog_tcp(self, T_world_tool: Array, *, wait: bool = True) -> Future:
        """Move the TCP to a pose by IK (5-axis: the orientation is projected, and said so)."""
        T_base = inv_T(self.T_world_base()) @ np.asarray(T_world_tool, float)
        res = self.robot.ik(T_base, seed=self.current_joints())
        if not res.ok and res.nearest_T_base_tool is not None:
            self.bus.emit(Notice(res.message))
            res = self.robot.ik(res.nearest_T_base_tool, seed=self.current_joints())
        if not res.ok:
            raise UnreachableError(res.message, res)
        return self.jog_joints(res.best(self.current_joints()), wait=wait)

    def _run_motion(self, task: str, fn: Callable[[Progress], Any]) -> Future:
        self.hold.check_start()
        with self._lock:
            self.machine.begin_moving()
        self._emit_state()

        def done(fut: Future) -> None:
            with self._lock:
                self.machine.end_mode()
                exc = fut.exception()
                if exc is not None and not isinstance(exc, Cancelled):
                    self._error(f"{task}: {exc}", hint_for(exc))
                self._autosave()
            self._emit_state()

        return self.worker.submit(task, fn, done)

    def _known_checker(self) -> CollisionChecker:
        return CollisionChecker(self.robot, self.cell.collision_objects_in_base())

    def adopt_hold(self, hold: Any) -> None:
        """Take over the page's motion authority (a session loaded into a running page)."""
        self.hold = hold
        hold.on_lost(self._holder_gone)

    def _holder_gone(self, why: str) -> None:
        """The enabling switch was let go (`MotionHold`): the robot stops now and waits;
        a run is left resumable for the next holder."""
        if self.machine.mode != Mode.MOVING:
            return
        self.stop()
        self.bus.emit(Notice(f"The robot stopped: {why}. It waits for the page that holds "
                             "motion authority to resume."))

    def stop(self) -> None:
        """Stop the robot now (from any thread)."""
        link = self._link
        if link is not None:
            link.stop()
        self.worker.cancel()

    def indicate_collision(self) -> None:
        """The operator's Collision! button: stop and record the posture as an obstacle."""
        link = self._link
        if link is not None and self.machine.mode == Mode.MOVING:
            link.indicate_collision()
            return
        # Not moving: record the current posture directly (e.g. after a manual jog).
        q = self.current_joints()
        self._record_collision(q, "operator")

    def _record_collision(self, q: Array, source: str) -> None:
        with self._lock:
            self.recorded_collisions.append(np.asarray(q, float).copy())
            self.counters.collision_indications += 1
            if self._world is not None:
                self._world.add_collision(q)
            self._autosave()
        self.bus.emit(CollisionRecorded(np.asarray(q, float).copy(),
                                        self.counters.collision_indications, source))

    def close(self) -> None:
        """Stop the robot and background work, close the link and the cameras."""
        self.stop()
        self.worker.join(5.0)
        self.stop_pointer()
        with self._lock:
            self._drop_link()

    def cancel(self) -> None:
        self.worker.cancel()
        link = self._link
        if link is not None and self.machine.mode == Mode.MOVING:
            link.stop()
