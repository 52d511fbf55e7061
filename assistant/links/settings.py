"""How to reach the robot: the JSON-able settings a session stores, and the link they build.

The set-up step of the workflow lets the operator choose the kind of link and its address;
the session saves `LinkSettings.to_json()` and rebuilds the link with `make_link`. Defaults
are the thesis' CR1 set-up (003 Appendix C): commands on 10001, the data link ``COM2:`` on
10002 (OPT12), robot 1, slot 1, the 7.1 ms controller cycle.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Literal

from assistant.collision.reports import ObstacleView
from assistant.links.link import RobotLink
from assistant.links.wirelog import NULL, WireLog
from assistant.robots.model import Robot

LinkKind = Literal["simulated", "melfa", "kuka_rest", "ur", "abb", "omnicore"]
KINDS: tuple[str, ...] = ("simulated", "melfa", "kuka_rest", "ur", "abb", "omnicore")


class LinkSettingsError(ValueError):
    """Settings that cannot work; the message names the field."""


@dataclass(frozen=True)
class LinkSettings:
    kind: LinkKind = "simulated"
    host: str = "127.0.0.1"
    #: MELFA: controller-communication port; KUKA: the bridge's HTTP port.
    port: int = 10001
    #: MELFA: TCP port of the data link the streaming program opens as COM2:.
    datalink_port: int = 10002
    robot_number: int = 1
    slot: int = 1
    connect_timeout_s: float = 2.0
    #: Longest wait for any reply (MELFA) / beyond a move's expected time (KUKA).
    timeout_s: float = 1.0
    stream_cycle_s: float = 0.0071
    stream_window: int = 4
    #: KUKA: how far on the arm the decimated PTP path may leave the planned one.
    decimation_tol_m: float = 0.002
    kuka_base_path: str = "/krl"
    #: Universal Robots: secondary interface (URScript), RTDE and dashboard server ports,
    #: and the highest RTDE state rate wanted (the controller's version caps it: 500 Hz on
    #: e-Series, 125 Hz on CB3); the primary interface carries messages and calibration.
    ur_script_port: int = 30002
    ur_primary_port: int = 30001
    ur_rtde_port: int = 30004
    ur_dashboard_port: int = 29999
    ur_rtde_hz: float = 500.0
    #: ABB (Robot Web Services on `port`: 80 on an IRC5, "abb"; 443 on an OmniCore,
    #: "omnicore", RWS 2.0 over HTTPS): the login - the controller's
    #: default user unless the cell has its own - and the RAPID motion task.
    rws_user: str = "Default User"
    rws_password: str = "robotics"
    rws_task: str = "T_ROB1"
    #: Simulated robot: robot seconds per wall second.
    time_scale: float = 1.0
    event_period_s: float = 0.05

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise LinkSettingsError(f"kind must be one of {KINDS}, got {self.kind!r}")
        for name in ("port", "datalink_port", "ur_script_port", "ur_rtde_port",
                     "ur_dashboard_port", "ur_primary_port"):
            v = getattr(self, name)
            if not 0 <= v <= 65535:
                raise LinkSettingsError(f"{name} {v} is not a TCP port")
        if not 1 <= self.robot_number <= 3:
            raise LinkSettingsError("robot_number must be 1, 2 or 3 (MELFA)")
        if not 1 <= self.slot <= 33:
            raise LinkSettingsError("slot must be 1-33 (MELFA)")
        for name in ("connect_timeout_s", "timeout_s", "stream_cycle_s", "decimation_tol_m",
                     "time_scale", "event_period_s"):
            if not getattr(self, name) > 0:
                raise LinkSettingsError(f"{name} must be > 0")
        if not 0.0 < self.ur_rtde_hz <= 500.0:
            raise LinkSettingsError("ur_rtde_hz must be in (0, 500]")
        if self.stream_window < 1:
            raise LinkSettingsError("stream_window must be >= 1")
        if not self.rws_user.strip():
            raise LinkSettingsError("rws_user is empty (ABB)")
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,31}", self.rws_task):
            raise LinkSettingsError(f"rws_task {self.rws_task!r} is not a RAPID task name")
        if not self.host.strip():
            raise LinkSettingsError("host is empty")

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @staticmethod
    def from_json(data: dict[str, Any]) -> LinkSettings:
        known = {f.name: f for f in fields(LinkSettings)}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise LinkSettingsError(f"unknown link setting(s): {', '.join(unknown)}")
        kw: dict[str, Any] = {}
        for k, v in data.items():
            typ = type(getattr(LinkSettings(), k))
            try:
                kw[k] = typ(v)
            except (TypeError, ValueError):
                raise LinkSettingsError(f"{k}: {v!r} is not a {typ.__name__}") from None
        return LinkSettings(**kw)


def wire_log(settings: LinkSettings, log_dir: Path | str | None) -> WireLog:
    """The link's wire log in `log_dir` (None: nothing recorded); the password is masked."""
    return WireLog(log_dir, settings.kind, secrets=[settings.rws_password])


def make_link(settings: LinkSettings, robot: Robot,
              hidden_obstacles: Iterable[ObstacleView] = (),
              log_dir: Path | str | None = None) -> RobotLink:
    """The link the settings describe. Hidden obstacles only exist for the simulated robot;
    with `log_dir` the link writes its wire traffic there (`wirelog`)."""
    wire = wire_log(settings, log_dir) if settings.kind != "simulated" else NULL
    if settings.kind == "simulated":
        from assistant.links.simulated import SimulatedRobot

        return SimulatedRobot(robot, hidden_obstacles=hidden_obstacles,
                              time_scale=settings.time_scale,
                              event_period_s=settings.event_period_s)
    if settings.kind == "melfa":
        from assistant.links.melfa import MelfaLink

        return MelfaLink(robot, host=settings.host, port=settings.port,
                         datalink_port=settings.datalink_port,
                         robot_number=settings.robot_number, slot=settings.slot,
                         connect_timeout_s=settings.connect_timeout_s,
                         timeout_s=settings.timeout_s, stream_cycle_s=settings.stream_cycle_s,
                         stream_window=settings.stream_window,
                         event_period_s=settings.event_period_s, wire=wire)
    if settings.kind in ("abb", "omnicore"):
        from assistant.links.abb_rws import AbbRwsLink

        return AbbRwsLink(robot, host=settings.host, port=settings.port,
                          username=settings.rws_user, password=settings.rws_password,
                          task=settings.rws_task, timeout_s=settings.timeout_s,
                          decimation_tol_m=settings.decimation_tol_m,
                          rws_version=2 if settings.kind == "omnicore" else 1, wire=wire)
    if settings.kind == "ur":
        from assistant.links.ur import URLink

        return URLink(robot, host=settings.host, script_port=settings.ur_script_port,
                      rtde_port=settings.ur_rtde_port,
                      dashboard_port=settings.ur_dashboard_port, rtde_hz=settings.ur_rtde_hz,
                      primary_port=settings.ur_primary_port, wire=wire,
                      connect_timeout_s=settings.connect_timeout_s,
                      timeout_s=settings.timeout_s, decimation_tol_m=settings.decimation_tol_m,
                      event_period_s=settings.event_period_s)
    from assistant.links.kuka_rest import KukaRestLink

    return KukaRestLink(robot, host=settings.host, port=settings.port,
                        base_path=settings.kuka_base_path, timeout_s=settings.timeout_s,
                        decimation_tol_m=settings.decimation_tol_m)
