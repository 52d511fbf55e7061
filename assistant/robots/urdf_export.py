"""A URDF robot's description as others read it: the URDF text with absolute mesh paths, the
operator's joint limits and a fixed `tool` frame at the TCP (for a viewer, pinocchio, or a
saved session that must reload the same arm)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from assistant.robots.model import JointLimits
from assistant.robots.urdf_parse import CONTINUOUS_RANGE, URDFDocument

Array = np.ndarray


def robot_urdf(doc: URDFDocument, joint_names: Sequence[str], limits: JointLimits,
               T_flange_tool: Array, tool_link: str) -> str:
    """The URDF with absolute mesh paths, the current limits and a fixed `tool` frame.

    The tool frame is a link named "tool" (or "cellteach_tool" if "tool" is taken) fixed
    to `tool_link` at `T_flange_tool`, so a viewer or pinocchio sees the TCP.
    """
    root = etree.fromstring(etree.tostring(doc.tree))
    for mesh in root.iter("mesh"):
        fn = mesh.get("filename")
        if fn:
            mesh.set("filename", str(_resolved(doc, fn)))
    by_name = {j.get("name"): j for j in root.findall("joint")}
    for k, name in enumerate(joint_names):
        el = by_name[name]
        lo, hi = float(limits.lower[k]), float(limits.upper[k])
        if el.get("type") == "continuous":
            if lo == -CONTINUOUS_RANGE and hi == CONTINUOUS_RANGE:
                continue
            el.set("type", "revolute")
        lim = el.find("limit")
        if lim is None:
            lim = etree.SubElement(el, "limit", effort="0",
                                   velocity=repr(float(limits.velocity[k])))
        lim.set("lower", repr(lo))
        lim.set("upper", repr(hi))
    tool_name = "tool" if "tool" not in doc.links else "cellteach_tool"
    joint_name = f"{tool_name}_fixed"
    while joint_name in doc.joints:
        joint_name = "_" + joint_name
    etree.SubElement(root, "link", name=tool_name)
    j = etree.SubElement(root, "joint", name=joint_name, type="fixed")
    T = T_flange_tool
    rpy = pin.rpy.matrixToRpy(T[:3, :3])
    etree.SubElement(j, "origin", xyz=" ".join(repr(float(v)) for v in T[:3, 3]),
                     rpy=" ".join(repr(float(v)) for v in rpy))
    etree.SubElement(j, "parent", link=tool_link)
    etree.SubElement(j, "child", link=tool_name)
    return '<?xml version="1.0"?>\n' + etree.tostring(root, encoding="unicode")


def _resolved(doc: URDFDocument, filename: str) -> Path:
    for link in doc.links.values():
        for g in link.visuals + link.collisions:
            if g.filename == filename and g.path is not None:
                return g.path
    raise KeyError(filename)
