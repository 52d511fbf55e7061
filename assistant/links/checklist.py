"""The pre-flight checklist of a link: before anything moves, is the controller there, which
version, in which mode, is it ours to command, does its kinematics match the model, does a
harmless read work - one item per line, each failing one saying what to do.

`check_link(settings, robot)` runs the checklist of the settings' kind; the command
``cellteach check-link KIND HOST`` prints it (exit 0 only if every item passed) and the
set-up step's "Test connection" button shows it. Nothing here moves the arm: the UR and ABB
checks read and query (the dashboard's ``is in remote control``, RWS mastership request and
release), the KUKA check asks the bridge for its position and TCP, the MELFA one opens the
command port and reads the joints. Items that only the controller's own menus can show (the
MELFA parameters the streaming program needs) are printed as notes; they never fail.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from assistant.links.link import LinkError
from assistant.links.settings import LinkSettings, wire_log
from assistant.robots.model import Robot


@dataclass(frozen=True)
class CheckItem:
    name: str
    ok: bool | None  # None: a note (what to set on the controller), never a failure
    detail: str
    todo: str = ""

    def line(self) -> str:
        mark = {True: "ok  ", False: "FAIL", None: "note"}[self.ok]
        tail = f" -> {self.todo}" if self.todo and self.ok is not True else ""
        return f"[{mark}] {self.name}: {self.detail}{tail}"


@dataclass
class Checklist:
    kind: str
    host: str
    items: list[CheckItem]

    @property
    def passed(self) -> bool:
        return all(i.ok is not False for i in self.items)

    def text(self) -> str:
        head = f"{self.kind} at {self.host}: " + ("all checks passed" if self.passed else
                                                  f"{sum(i.ok is False for i in self.items)}"
                                                  " check(s) failed")
        return "\n".join([head] + [i.line() for i in self.items])


class _Stop(Exception):
    """A failed item the following ones depend on."""


class _Run:
    def __init__(self) -> None:
        self.items: list[CheckItem] = []

    def add(self, name: str, ok: bool | None, detail: str, todo: str = "") -> None:
        self.items.append(CheckItem(name, ok, detail, todo))

    def step(self, name: str, fn: Callable[[], str], todo: str, *, fatal: bool = True) -> bool:
        try:
            self.add(name, True, fn())
            return True
        except (LinkError, OSError, ValueError) as exc:
            self.add(name, False, str(exc), todo)
            if fatal:
                raise _Stop from None
            return False


def _reachable(host: str, port: int, timeout_s: float) -> str:
    with socket.create_connection((host, port), timeout_s):
        return f"TCP port {port} answers"


def default_robot(kind: str) -> Robot:
    """A model to check against when the caller has none: the vendor's typical arm."""
    from assistant.robots.catalog import RobotSpec, installed_robot_urdf

    if kind == "kuka_rest":
        return RobotSpec(kind="kuka_kr6_r900_sixx").build()
    if kind == "melfa" or kind == "simulated":
        return RobotSpec(kind="rv2aj").build()
    from assistant.robots.urdf_robot import URDFRobot

    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                               tool_link="tool0")


def check_link(settings: LinkSettings, robot: Robot | None = None,
               log_dir: Path | str | None = None) -> Checklist:
    """Run the checklist of `settings.kind` against the controller at `settings.host`."""
    robot = robot or default_robot(settings.kind)
    run = _Run()
    fn = {"ur": _ur, "abb": _abb, "omnicore": _abb, "kuka_rest": _kuka, "melfa": _melfa,
          "simulated": _simulated}[settings.kind]
    with contextlib.suppress(_Stop):
        fn(settings, robot, run, log_dir)
    return Checklist(settings.kind, settings.host, run.items)


def _simulated(s: LinkSettings, robot: Robot, run: _Run, log_dir) -> None:  # noqa: ANN001
    run.add("simulated robot", True, f"{robot.name}: nothing to connect to")


# ---------------------------------------------------------------------- Universal Robots
def _ur(s: LinkSettings, robot: Robot, run: _Run, log_dir) -> None:  # noqa: ANN001
    from assistant.links import ur_kinematics as uk
    from assistant.links import ur_rtde_wire as w
    from assistant.links.ur import LOCAL_MODE, URLink

    t = s.connect_timeout_s
    run.step("reachable", lambda: "dashboard, RTDE: " + ", ".join(
        _reachable(s.host, p, t) for p in (s.ur_dashboard_port, s.ur_rtde_port)),
        f"check the cable and that {s.host} is the controller's address (Settings > System "
        "> Network on the pendant)")
    link = URLink(robot, host=s.host, script_port=s.ur_script_port, rtde_port=s.ur_rtde_port,
                  dashboard_port=s.ur_dashboard_port, rtde_hz=s.ur_rtde_hz,
                  primary_port=s.ur_primary_port, connect_timeout_s=t,
                  timeout_s=max(s.timeout_s, 1.0), wire=wire_log(s, log_dir))
    try:
        def version() -> str:
            st = link.rtde.connect()
            v = ".".join(map(str, link.rtde.controller_version))
            family = "e-Series" if link.e_series else "CB3"
            link._last_q = st.q
            return f"PolyScope {v} ({family}), RTDE at {link.rtde.frequency_hz:g} Hz"

        run.step("version", version, "the RTDE interface must be on (it is by default)")

        def remote() -> str:
            try:
                link.check_remote_control()
            except LinkError:
                raise LinkError("the robot is in Local control") from None
            return {None: "no Local/Remote mode (CB3)", True: "Remote control"}[
                link.remote_control]

        run.step("remote control", remote, LOCAL_MODE.split(": ", 1)[1], fatal=False)

        def mode() -> str:
            st = link.rtde.latest()
            rm = w.mode_name(w.RobotMode, st["robot_mode"])
            sm = w.mode_name(w.SafetyMode, st["safety_mode"])
            if st["safety_mode"] not in (w.SafetyMode.NORMAL, w.SafetyMode.REDUCED):
                raise LinkError(f"robot {rm}, safety {sm}")
            return f"robot {rm}, safety {sm}"

        run.step("mode", mode, "clear the stop on the teach pendant (release the e-stop, "
                 "unlock the protective stop)", fatal=False)
        got: dict = {}

        def primary() -> str:
            link.primary.connect()
            got["k"] = link.primary.wait_kinematics(max(s.timeout_s, 1.0))
            if link.primary.failure is not None:
                raise link.primary.failure
            return f"port {s.ur_primary_port} open, robot state arriving"

        run.step("primary interface", primary, "an e-Series closes it in Local control: "
                 "switch to Remote Control", fatal=False)

        def calibration() -> str:
            if "k" not in got or link.primary.failure is not None:
                raise LinkError("not read: the primary interface is closed")
            k = got["k"]
            if k is None:
                raise LinkError("the controller sent no kinematics info (software before 3.6)")
            model, _, angle = uk.identify(robot)
            if model is None:
                raise LinkError(f"{robot.name} is not a UR arm the link knows")
            if angle > 1e-3:
                raise LinkError(f"our model's flange is turned {np.degrees(angle):.0f} deg "
                                "against the UR's tool flange")
            rep = uk.compare(k, robot, link._last_q)
            if rep.max_deviation_m > 0.02:
                raise LinkError(f"the controller's calibrated arm is {rep.max_deviation_m*1e3:.0f}"
                                f" mm from a nominal {model}: another UR type?")
            return (f"calibrated {model}: the TCP is up to {rep.max_deviation_m * 1e3:.1f} mm "
                    f"from the nominal model ({rep.here_m * 1e3:.1f} mm here); the link "
                    "uses the calibrated kinematics")

        run.step("calibration", calibration, "choose the robot model of this arm (tool link "
                 "tool0) in step 1", fatal=False)
        run.step("read", lambda: "joints " + ", ".join(
            f"{v:.1f}" for v in np.degrees(link.rtde.latest().q)) + " deg",
            "the RTDE stream stopped: reconnect")
    finally:
        link.close()


# ---------------------------------------------------------------------- ABB
def _abb(s: LinkSettings, robot: Robot, run: _Run, log_dir) -> None:  # noqa: ANN001
    from assistant.links.abb_rws import AbbRwsLink

    v2 = s.kind == "omnicore"
    link = AbbRwsLink(robot, host=s.host, port=s.port, username=s.rws_user,
                      password=s.rws_password, task=s.rws_task,
                      timeout_s=max(s.timeout_s, 2.0), rws_version=2 if v2 else 1,
                      wire=wire_log(s, log_dir))
    run.step("reachable", lambda: _reachable(s.host, link.port, s.connect_timeout_s),
             f"check the cable to the controller's WAN/public port and that {s.host}:"
             f"{link.port} is its address")

    def version() -> str:
        st = link.system()
        return f"{st.get('name', '?')}, RobotWare {st.get('rwversion', '?')} " \
               f"(RWS {'2.0, HTTPS' if v2 else '1.0'})"

    run.step("version", version, f"check the RWS user {s.rws_user!r} and its password; "
             + ("an OmniCore speaks RWS 2.0: choose 'ABB OmniCore'" if not v2 else
                "an IRC5 speaks RWS 1.0: choose 'ABB IRC5'"))

    def mode() -> str:
        m, c = link.operation_mode(), link.controller_state()
        if m.upper() != "AUTO":
            raise LinkError(f"operating mode {m}")
        return f"operating mode {m}, motors {c}"

    run.step("mode", mode, "turn the mode key to Auto and confirm on the FlexPendant",
             fatal=False)

    def mastership() -> str:
        link.request_mastership()
        link.release_mastership()
        return "taken and given back"

    run.step("mastership", mastership, "someone holds write access (the FlexPendant's "
             "program editor, RobotStudio): release it there", fatal=False)

    def task() -> str:
        mods = [m["name"] for m in link.get_states(f"rw/rapid/tasks/{s.rws_task}/modules"
                                                   if v2 else f"rw/rapid/modules?task="
                                                   f"{s.rws_task}")]
        return f"{s.rws_task} holds {', '.join(mods) or 'no module'}; ours load beside " \
               "them and start by 'set PP to routine' (its main stays)"

    run.step("task", task, f"the RAPID task {s.rws_task} must exist", fatal=False)

    def subscription() -> str:
        link._opener = link._new_opener()
        link.controller_state()  # a session first
        link._subscribe()
        ok = link.subscription is not None
        link._unsubscribe()
        if not ok:
            raise LinkError("the controller refused the websocket; the link will poll")
        return "execution-state events over a websocket"

    run.step("subscription", subscription, "allow the subscription service (a firewall "
             "between here and the controller must pass websockets)", fatal=False)
    run.step("read", lambda: "joints " + ", ".join(f"{v:.1f}" for v in np.degrees(
        link.read_joints())) + " deg", "the mechanical unit ROB_1 must exist")
    with contextlib.suppress(LinkError):
        link.request("GET", "logout", json=False)


# ---------------------------------------------------------------------- KUKA bridge
def _kuka(s: LinkSettings, robot: Robot, run: _Run, log_dir) -> None:  # noqa: ANN001
    from assistant.links import kuka_protocol as kp
    from assistant.links.kuka_rest import KukaRestLink

    run.step("reachable", lambda: _reachable(s.host, s.port, s.connect_timeout_s),
             "start bridge_server.py on the controller's Windows side (INSTALL.md) and open "
             f"port {s.port} in its firewall")
    link = KukaRestLink(robot, host=s.host, port=s.port, base_path=s.kuka_base_path,
                        timeout_s=max(s.timeout_s, 5.0), wire=wire_log(s, log_dir))
    got: dict = {}

    def program() -> str:
        reply = link.command("getpos")
        got["pos"] = reply
        kind = "cellteach's bridge (reports axes)" if reply.axes else \
            "a bridge without axes (002's?): configurations guessed by IK"
        return f"the robot program answers; {kind}"

    run.step("robot program", program, "select cellbridge on the smartPAD, AUT/EXT, drives "
             "on, start; acknowledge any message")

    def tcp() -> str:
        reply = link.command("gettcp")
        return "TCP " + ", ".join(f"{v:.1f}" for v in reply.position) + " (mm, deg)"

    run.step("tcp", tcp, "the bridge must answer gettcp", fatal=False)

    def model() -> str:
        reply = got["pos"]
        if not reply.axes:
            return "no axes reported: not compared"
        q = np.radians(reply.axes[:robot.dof])
        T = kp.position_to_T(reply.position)
        flange = robot.with_tool(np.eye(4))
        off = min(float(np.linalg.norm(m.fk(q)[:3, 3] - T[:3, 3])) for m in (robot, flange))
        if off > 0.002:
            raise LinkError(f"the reported pose is {off * 1000:.1f} mm from where our "
                            f"{robot.name} model puts it at the reported axes")
        return f"pose and axes agree with {robot.name} within {off * 1000:.2f} mm"

    run.step("model", model, "choose the robot model of this arm in step 1 and check "
             "XFLANGE_TOOL0 in cellbridge.dat", fatal=False)
    run.step("read", lambda: "position " + ", ".join(
        f"{v:.1f}" for v in got["pos"].position), "the bridge must answer getpos")


# ---------------------------------------------------------------------- MELFA
#: What the controller needs for our link (thesis 003 Appendix C, Tables 14-15; the
#: parameter names are Mitsubishi's): set on the teach pendant or with RT ToolBox, then
#: power the controller off and on.
MELFA_PARAMETERS = (
    ("NETIP", "the controller's IP address: the address cellteach connects to"),
    ("NETMSK", "the subnet mask of the cell network"),
    ("NETPORT", "OPT11 = {port} (commands), OPT12 = {datalink} (the streaming data link)"),
    ("CPRCE11", "0: OPT11 in controller communication mode (the commands)"),
    ("CPRCE12", "2: OPT12 as a data link (the streaming program's COM2:)"),
    ("COMDEV", "COM2: = OPT12 (e.g. RS232C,OPT12,,,,,,)"),
    ("NETMODE", "OPT12 = 1: the controller is the server, cellteach connects"),
    ("TASKMAX", "8 (the default): the edit slot is 9"),
)


def _melfa(s: LinkSettings, robot: Robot, run: _Run, log_dir) -> None:  # noqa: ANN001
    from assistant.links.melfa import MelfaLink

    for name, what in MELFA_PARAMETERS:
        run.add(f"parameter {name}", None, what.format(port=s.port, datalink=s.datalink_port),
                "")
    run.step("reachable", lambda: _reachable(s.host, s.port, s.connect_timeout_s),
             f"NETIP must be {s.host} and NETPORT OPT11 {s.port}; power-cycle after setting")
    link = MelfaLink(robot, host=s.host, port=s.port, datalink_port=s.datalink_port,
                     robot_number=s.robot_number, slot=s.slot,
                     connect_timeout_s=s.connect_timeout_s, timeout_s=max(s.timeout_s, 1.0),
                     wire=wire_log(s, log_dir))
    try:
        def version() -> str:
            link.connect()
            return f"controller answers: {link.controller_info or 'QoK'}"

        run.step("version", version, "CPRCE11 must be 0 (controller communication mode)")

        def mode() -> str:
            st = link.read_state()
            if st.error_code:
                raise LinkError(f"controller in error {st.error_code:04d}")
            return f"servo {'on' if st.servo_on else 'off'}, no error"

        run.step("mode", mode, "reset the error on the teach pendant", fatal=False)
        run.step("data link", lambda: _reachable(s.host, s.datalink_port, s.connect_timeout_s)
                 + " (the streaming program's COM2:)",
                 f"CPRCE12 = 2, COMDEV COM2: = OPT12, NETPORT OPT12 = {s.datalink_port}, "
                 "NETMODE OPT12 = 1", fatal=False)
        run.step("read", lambda: "joints " + ", ".join(
            f"{v:.1f}" for v in np.degrees(link.current_joints())) + " deg",
            "JPOSF must answer")
    finally:
        link.close()
