"""Robots by description: what a cell or a session file stores to rebuild its robot.

A `RobotSpec` is plain JSON-able data (never a pickled object), so a saved cell can be loaded
on another machine and a tampered file cannot run code.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from assistant.robots.errors import RobotModelError
from assistant.robots.model import Robot, Tool

BUILTIN_ROBOTS = ("rv2aj",)
ARMS_DIR = Path(__file__).with_name("arms")


@dataclass(frozen=True)
class CatalogArm:
    """An arm shipped with cellteach as a URDF in `arms/`, written from the maker's public
    data sheet (the file cites it). A `RobotSpec` names it by its key in `CATALOG`; to add an
    arm, put its URDF in `arms/` and copy an entry."""

    label: str  # what the set-up page offers
    urdf: str  # file name in arms/
    base_link: str  # the controller's robot base frame
    tool_link: str  # the flange, z out of it (tools run along z)
    vendor: str  # the link kind that drives it ("": none yet - export only)
    source: str  # the public document its numbers come from


CATALOG: dict[str, CatalogArm] = {
    "kuka_kr6_r900_sixx": CatalogArm(
        label="KUKA KR 6 R900 sixx (KR AGILUS)", urdf="kuka_kr6_r900_sixx.urdf",
        base_link="base_link", tool_link="tool0", vendor="kuka_rest",
        source="KUKA specification 'KR AGILUS sixx', technical data of the KR 6 R900 sixx"),
    "abb_irb1200_5_09": CatalogArm(
        label="ABB IRB 1200-5/0.9", urdf="abb_irb1200_5_09.urdf",
        base_link="base_link", tool_link="tool0", vendor="abb",
        source="ABB product specification 'IRB 1200' (3HAC046982-001), technical data of the "
               "IRB 1200-5/0.9"),
    "fanuc_lrmate200id": CatalogArm(
        label="FANUC LR Mate 200iD", urdf="fanuc_lrmate200id.urdf",
        base_link="base_link", tool_link="tool0", vendor="",
        source="FANUC data sheet 'LR Mate 200iD' (motion ranges, speeds, operating space); "
               "the serial J3 range as ROS-Industrial's fanuc_lrmate200id_support states it"),
}


def catalog_path(kind: str) -> Path:
    return ARMS_DIR / CATALOG[kind].urdf


@dataclass(frozen=True)
class ToolSpec:
    """A tool as stored in files: a TCP offset and an optional straight body of given radius."""

    name: str = "flange"
    T_flange_tool: tuple[tuple[float, ...], ...] = tuple(tuple(r) for r in np.eye(4))
    body_radius: float = 0.0
    has_gripper: bool = False

    @staticmethod
    def straight(length: float, radius: float = 0.02, name: str = "gripper",
                 has_gripper: bool = True) -> ToolSpec:
        T = np.eye(4)
        T[2, 3] = length
        return ToolSpec(name, tuple(tuple(r) for r in T), radius, has_gripper)

    def build(self) -> Tool:
        T = np.array(self.T_flange_tool, dtype=float)
        if T.shape != (4, 4) or not np.allclose(T[3], [0, 0, 0, 1]):
            raise RobotModelError(f"tool {self.name!r}: T_flange_tool is not a 4x4 transform")
        along_z = np.allclose(T[:3, :3], np.eye(3)) and np.allclose(T[:2, 3], 0)
        if self.body_radius > 0.0 and along_z:
            return Tool.straight(float(T[2, 3]), self.body_radius, name=self.name,
                                 has_gripper=self.has_gripper)
        return Tool(self.name, T, (), self.has_gripper)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "T_flange_tool": [list(r) for r in self.T_flange_tool],
                "body_radius": self.body_radius, "has_gripper": self.has_gripper}

    @staticmethod
    def from_json(d: dict[str, Any]) -> ToolSpec:
        return ToolSpec(str(d.get("name", "flange")),
                        tuple(tuple(float(v) for v in r) for r in d["T_flange_tool"]),
                        float(d.get("body_radius", 0.0)), bool(d.get("has_gripper", False)))


@dataclass(frozen=True)
class RobotSpec:
    """Which robot: a built-in by name, or a URDF file with its package folders and frames."""

    kind: str = "rv2aj"  # "rv2aj", "urdf" or a `CATALOG` key
    urdf_path: str | None = None
    package_dirs: tuple[str, ...] = ()
    base_link: str | None = None
    tool_link: str | None = None
    tool: ToolSpec = field(default_factory=ToolSpec)
    #: Optional per-joint (lower, upper) limits in degrees replacing the model's own.
    limits_deg: tuple[tuple[float, float], ...] | None = None
    #: The URDF link programs write poses in (`URDFRobot.program_frame`); None: the
    #: controller's base of a ROS-Industrial description, else the mounting frame.
    program_frame: str | None = None

    def build(self) -> Robot:
        if self.kind == "rv2aj":
            from assistant.robots.rv2aj import DATASHEET_LIMITS_DEG, RV2AJ, RV2AJConfig

            return RV2AJ(RV2AJConfig(limits_deg=self.limits_deg or DATASHEET_LIMITS_DEG,
                                     tool=self.tool.build()))
        if self.kind in CATALOG:
            from assistant.robots.urdf_robot import URDFRobot

            arm = CATALOG[self.kind]
            robot = URDFRobot.from_file(catalog_path(self.kind), base_link=arm.base_link,
                                        tool_link=arm.tool_link, tool=self.tool.build(),
                                        program_frame=self.program_frame)
            if self.limits_deg is not None:
                robot = robot.with_limits(np.radians(np.array(self.limits_deg, dtype=float)))
            return robot
        if self.kind == "urdf":
            if not self.urdf_path:
                raise RobotModelError("a URDF robot needs urdf_path")
            from assistant.robots.urdf_robot import URDFRobot

            robot = URDFRobot.from_file(Path(self.urdf_path), package_dirs=self.package_dirs,
                                        base_link=self.base_link, tool_link=self.tool_link,
                                        tool=self.tool.build(), program_frame=self.program_frame)
            if self.limits_deg is not None:
                robot = robot.with_limits(np.radians(np.array(self.limits_deg, dtype=float)))
            return robot
        raise RobotModelError(f"unknown robot kind {self.kind!r} (known: rv2aj, urdf, "
                              f"{', '.join(CATALOG)})")

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "urdf_path": self.urdf_path,
                "package_dirs": list(self.package_dirs), "base_link": self.base_link,
                "tool_link": self.tool_link, "tool": self.tool.to_json(),
                "limits_deg": [list(p) for p in self.limits_deg] if self.limits_deg else None,
                **({"program_frame": self.program_frame} if self.program_frame else {})}

    @staticmethod
    def from_json(d: dict[str, Any]) -> RobotSpec:
        if not isinstance(d, dict) or "kind" not in d:
            raise RobotModelError("robot description must be an object with a 'kind'")
        lim = d.get("limits_deg")
        return RobotSpec(
            kind=str(d["kind"]),
            urdf_path=d.get("urdf_path"),
            package_dirs=tuple(str(p) for p in d.get("package_dirs") or ()),
            base_link=d.get("base_link"),
            tool_link=d.get("tool_link"),
            tool=ToolSpec.from_json(d["tool"]) if d.get("tool") else ToolSpec(),
            limits_deg=tuple((float(a), float(b)) for a, b in lim) if lim else None,
            program_frame=str(d["program_frame"]) if d.get("program_frame") else None,
        )


def robot_data_dirs() -> list[Path]:
    """Installed robot description folders (example-robot-data's ``share``), found at run
    time in the interpreter's site-packages (the `test` extra installs it)."""
    import site
    import sys

    out: list[Path] = []
    for sp in [*site.getsitepackages(), site.getusersitepackages(), *sys.path]:
        share = Path(sp) / "cmeel.prefix" / "share"
        if share.is_dir() and share not in out:
            out.append(share)
    return out


def installed_robot_urdf(relative: str) -> tuple[Path, Path]:
    """(URDF file, the ``share`` folder its package:// paths resolve in) of an installed
    robot description, e.g. ``example-robot-data/robots/ur_description/urdf/ur5_robot.urdf``.
    Raises FileNotFoundError saying how to install it."""
    for share in robot_data_dirs():
        if (share / relative).is_file():
            return share / relative, share
    raise FileNotFoundError(f"{relative} is not installed: pip install -e '.[test]' "
                            "(example-robot-data)")
