"""`report.json` of a scripted session: what was produced and whether it is safe.

`collision_free` is checked against *every* obstacle - the known CAD and the hidden ones the
simulated robot owned - with the exact continuous FCL check of the final dense joint path,
so a report cannot claim a program that would hit the thesis' O3.

`predicted_cycle_time_s` and `cycle_time` (per move, wait and gripper action) come from the
exported program (`assistant.export.cycle_time`): a prediction under the robot's joint
limits, not a time measured on a controller.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.session.session import Session
from assistant.transforms import inv_T


def all_obstacles(session: Session) -> list[Any]:
    """Known cell objects and hidden obstacles, in the robot base frame."""
    T_bw = inv_T(session.T_world_base())
    hidden = [Obstacle(h.name, T_bw @ h.T_world_object, (h.primitive().collision_shape(),))
              for h in session.hidden]
    return [*session.cell.collision_objects_in_base(), *hidden]


def object_summary(obj: Any) -> dict[str, Any]:
    """A cell object as the report lists it: the part at full resolution, what the page
    draws, and the collision margin its proxy carries (0 when it collides as itself)."""
    return {"name": obj.name, "role": obj.role.value,
            "triangles": int(len(obj.full_mesh.faces)),
            "drawn_triangles": int(len(obj.display_mesh.faces)),
            "collision_shapes": len(obj.collision),
            "collision_margin_mm": round(obj.collision_margin_m * 1000.0, 3)}


def session_report(session: Session, *, wall_time_s: float, error: str | None = None,
                   program_files: list[str] | None = None) -> dict[str, Any]:
    traj = session.trajectory
    rep: dict[str, Any] = {
        "ok": error is None and traj is not None,
        "error": error,
        "sample": session.sample,
        "program_files": program_files or [],
        "dialect": session.export_dialect if session.program is not None else None,
        "primitives": {},
        "predicted_cycle_time_s": None,
        "cycle_time": None,
        "tcp_path_length_m": None,
        "joint_path_length_rad": None,
        "min_clearance_m": None,
        "collision_free": None,
        "within_limits": None,
        "collision_indications": session.counters.collision_indications,
        "replans": session.counters.replans,
        "planning_time_s": round(session.counters.planning_time_s, 3),
        "wall_time_s": round(wall_time_s, 3),
        "operator_actions": session.counters.operator_actions,
        "workflow_step": session.machine.state,
    }
    rep["objects"] = [object_summary(o) for o in session.cell.objects.values()]
    if session.program is not None:
        # as written: the move to the start included, what the operator counts in the file
        rep["program_motions"] = session.program.primitives
        rep["renames"] = list(session.program.renames)
    cycle = getattr(session.program, "cycle_time", None)
    if cycle is not None:
        rep["predicted_cycle_time_s"] = round(cycle.total_s, 3)
        rep["cycle_time"] = {**cycle.to_json(), "prediction_ms": round(cycle.compute_s * 1e3, 1)}
    if traj is None:
        return rep
    robot = session.robot
    Q = traj.dense_joint_path()
    checker = CollisionChecker(robot, all_obstacles(session))
    bad = checker.check_path(list(Q))
    P = robot.batch_fk(Q).positions
    rep.update({
        "primitives": traj.primitive_counts(),
        "tcp_path_length_m": round(float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum()), 4),
        "joint_path_length_rad": round(float(np.abs(np.diff(Q, axis=0)).sum()), 4),
        "min_clearance_m": round(checker.min_clearance_along(list(Q)), 4),
        "collision_free": bad is None,
        "within_limits": bool(np.all(robot.limits.contains_batch(Q))),
    })
    if bad is not None:
        i, mc = bad
        rep["collision"] = (f"motion {i}: {mc.report.describe()}" if mc.report
                            else f"motion {i}")
    if session.plan_report:
        rep["plan"] = {k: session.plan_report.get(k) for k in ("order", "description")}
    return rep
