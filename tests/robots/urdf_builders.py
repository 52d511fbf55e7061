"""Shared pieces of the URDF robot tests: the example-robot-data arms, pinocchio's full-model
FK as the reference, random configurations and a small generated 3-joint arm."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pinocchio as pin

from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.urdf_robot import URDFRobot

POS_TOL = 2e-6  # m: IK tolerance 1e-6 plus rounding
ROT_TOL = 2e-5  # rad


UR5_URDF, SHARE = installed_robot_urdf(
    "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
ROBOTS = SHARE / "example-robot-data" / "robots"
PANDA_URDF = ROBOTS / "panda_description" / "urdf" / "panda.urdf"



def _pin_fk(urdf: Path | str, robot: URDFRobot, q: np.ndarray, frame: str,
            locked: dict[str, float] | None = None, from_xml: bool = False) -> np.ndarray:
    """Reference: pinocchio's full model, chain joints at q, everything else at 0."""
    model = _pin_model(str(urdf), from_xml)
    data = model.createData()
    qf = pin.neutral(model)
    for name, v in list(zip(robot.joint_names, q, strict=True)) + list((locked or {}).items()):
        j = model.joints[model.getJointId(name)]
        if j.nq == 2:
            qf[j.idx_q:j.idx_q + 2] = np.cos(v), np.sin(v)
        else:
            qf[j.idx_q] = v
    pin.framesForwardKinematics(model, data, qf)
    T_root_base = data.oMf[model.getFrameId(robot.base_link)].homogeneous
    return np.linalg.inv(T_root_base) @ data.oMf[model.getFrameId(frame)].homogeneous


@functools.lru_cache(maxsize=8)
def _pin_model(urdf: str, from_xml: bool) -> pin.Model:
    return pin.buildModelFromXML(urdf) if from_xml else pin.buildModelFromUrdf(urdf)


def _random_q(robot, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(robot.limits.lower, robot.limits.upper,
                                               (n, robot.dof))



def _arm_urdf(*, collision: str = '<cylinder radius="0.03" length="0.2"/>',
              visual: str | None = None, extra: str = "", root_offset: str = "",
              j1_type: str = "revolute", j1_axis: str = "0 0 1", j2_axis: str = "0 1 0",
              j3_type: str = "revolute",
              j3_axis: str = "0 1 0", planar: bool = False,
              j1_limit: str = '<limit lower="-2.5" upper="2.5" effort="1" velocity="2"/>'
              ) -> str:
    """A small 3-joint arm: world -> base -> l1 -> l2 -> l3 -> tip (fixed)."""
    vis = f"<visual><geometry>{visual}</geometry></visual>" if visual else ""
    lim = '<limit lower="-2" upper="2" effort="1" velocity="2"/>'
    plim = '<limit lower="-0.1" upper="0.2" effort="1" velocity="0.5"/>'
    j1_axis = "0 1 0" if planar else j1_axis
    return f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="world"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/>{root_offset}
  </joint>
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <joint name="j1" type="{j1_type}"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="{j1_axis}"/>{j1_limit if j1_type != "continuous" else ""}
  </joint>
  <link name="l1">{vis}<collision><origin xyz="0 0 0.1" rpy="0.1 0 0"/>
    <geometry>{collision}</geometry></collision></link>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.2" rpy="0 0.3 0"/><axis xyz="{"0 1 0" if planar else j2_axis}"/>{lim}
  </joint>
  <link name="l2"><collision><origin xyz="0 0 0.15"/>
    <geometry><capsule radius="0.03" length="0.3"/></geometry></collision></link>
  <joint name="j3" type="{j3_type}"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.05 0 0.3" rpy="{"0 0 0" if planar else "1.57079632679 0 0"}"/>
    <axis xyz="{j3_axis}"/>
    {plim if j3_type == "prismatic" else lim}
  </joint>
  <link name="l3"><collision><geometry><sphere radius="0.04"/></geometry></collision></link>
  <joint name="tip_fixed" type="fixed"><parent link="l3"/><child link="tip"/>
    <origin xyz="0 0 0.08" rpy="0 0 0.5"/></joint>
  <link name="tip"/>
  {extra}
</robot>
"""
