"""Step 1 - robot, tool and link: what the assistant drives and how it talks to it.

The link's password is typed into a field of the operator's own page (`web.pages`: no other
page, a viewer's least, ever receives what is typed), masked as it is typed, and never sent
back to any page: the summary shows that one is stored, not what it is."""

from __future__ import annotations

import threading
from typing import Any

import viser

from assistant.links.settings import KINDS, LinkSettings
from assistant.robots.catalog import CATALOG, RobotSpec, ToolSpec
from assistant.session.events import Event, SceneChanged, StateChanged
from assistant.session.link_secrets import masked
from web.gui_value import set_value
from web.panels.base import Panel

ROBOTS = {"Mitsubishi RV-2AJ (built in)": "rv2aj",
          **{arm.label: key for key, arm in CATALOG.items()}, "URDF file": "urdf"}
LINK_LABELS = {"simulated": "Simulated robot", "melfa": "Mitsubishi CR1 (MELFA, TCP)",
               "kuka_rest": "KUKA via REST bridge",
               "ur": "Universal Robots (RTDE + URScript)",
               "abb": "ABB IRC5 (Robot Web Services 1.0)",
               "omnicore": "ABB OmniCore (Robot Web Services 2.0, HTTPS)"}
#: The port a link kind usually listens on, offered when the operator picks the kind.
DEFAULT_PORTS = {"melfa": 10001, "kuka_rest": 8000, "abb": 80, "omnicore": 443}
RWS_KINDS = frozenset({"abb", "omnicore"})
#: Links whose ports are fixed by the controller (UR: 30002, 30004, 29999): address only.
FIXED_PORTS = frozenset({"ur"})


class SetupPanel(Panel):
    title = "Robot & link"
    steps = ("setup",)

    def build(self) -> None:
        g = self.gui
        self.summary = g.add_markdown("")
        with g.add_folder("Robot and tool"):
            self.robot = g.add_dropdown("Robot", tuple(ROBOTS))
            self.urdf = g.add_text("URDF path", "", visible=False,
                                   hint="A URDF on this computer (package:// paths resolve "
                                        "next to it)")
            self.tool_len = g.add_number("Tool length (mm)", 100.0, min=0.0, max=1000.0,
                                         step=0.5, hint="Flange to tool centre point, along z")
            self.tool_rad = g.add_number("Tool radius (mm)", 20.0, min=0.0, max=200.0, step=0.5)
            self.gripper = g.add_checkbox("Gripper", True)
            self.apply_robot = g.add_button("Use this robot")
        with g.add_folder("Self-collision rule", expand_by_default=False):
            self.rule_text = g.add_markdown("")
        self.link_folder = g.add_folder("Link to the robot")
        with self.link_folder:
            self.link_kind = g.add_dropdown("Link", tuple(LINK_LABELS[k] for k in KINDS))
            self.host = g.add_text("Address", "127.0.0.1", visible=False)
            self.port = g.add_number("Port", 10001, min=1, max=65535, step=1, visible=False)
            self.rws_user = g.add_text("RWS user", "Default User", visible=False,
                                       hint="The IRC5's default login unless the cell "
                                            "has its own")
            self.time_scale = g.add_number(
                "Simulation speed (x real time)", 1.0, min=0.1, max=50.0, step=0.1,
                hint="1 = as fast as the real robot; 20 runs a minute's motion in 3 s")
            self.apply_link = g.add_button("Use this link")
            self.test_link = g.add_button("Test connection",
                                          hint="Checks the controller before anything moves: "
                                               "reachable, version, mode, write access, "
                                               "kinematics, a harmless read")
            self.check_result = g.add_markdown("")
            self.connect = g.add_button("Connect now")
        self.robot.on_update(lambda e: self._robot_kind_changed())
        self.link_kind.on_update(lambda e: self._link_kind_picked())
        self.bind(self.apply_robot, lambda e: self._choose_robot())
        #: Each operator page's own password field (`_password_field`).
        self.rws_password = self.app.pages.add(self._password_field, operators_only=True)
        self.bind(self.apply_link, lambda e: self._set_link(e.client))
        self.bind(self.connect, lambda e: self._connect(e.client))
        self.bind(self.test_link, lambda e: self._test_link())

    def _password_field(self, client: viser.ClientHandle) -> viser.GuiTextHandle:
        with self.link_folder:
            field = client.gui.add_text(
                "RWS password", "", order=self.rws_user.order + 0.5,
                visible=self._link_kind() in RWS_KINDS, hint="Leave it empty to keep the "
                "stored password; type a new one to change it (Use this link stores it)")
        # Typed characters show as dots on this page (viser's text field has no password
        # mode; the style reaches this page only).
        client.gui.add_html(mask_style(field))
        return field

    def _robot_kind_changed(self) -> None:
        self.urdf.visible = ROBOTS[self.robot.value] == "urdf"

    def _link_kind(self) -> str:
        return next(k for k, v in LINK_LABELS.items() if v == self.link_kind.value)

    def _link_kind_picked(self) -> None:
        port = DEFAULT_PORTS.get(self._link_kind())
        if port is not None:
            set_value(self.port, port)
        self._link_kind_changed()

    def _link_kind_changed(self) -> None:
        kind = self._link_kind()
        self.rws_user.visible = kind in RWS_KINDS
        for field in self.rws_password.all():
            if field.visible != (kind in RWS_KINDS):
                field.visible = kind in RWS_KINDS
        sim = kind == "simulated"
        self.host.visible = not sim
        self.port.visible = not sim and kind not in FIXED_PORTS
        self.time_scale.visible = sim

    def _choose_robot(self) -> None:
        kind = ROBOTS[self.robot.value]
        tool = ToolSpec.straight(self.tool_len.value / 1000.0, self.tool_rad.value / 1000.0,
                                 has_gripper=bool(self.gripper.value)) \
            if self.tool_len.value > 0 else ToolSpec()
        spec = RobotSpec(kind=kind, urdf_path=self.urdf.value.strip() or None, tool=tool)
        self.session.choose_robot(spec)

    def _set_link(self, client: Any = None) -> None:
        kind = self._link_kind()
        kw: dict = {"kind": kind}
        if kind == "simulated":
            kw["time_scale"] = float(self.time_scale.value)
        else:
            kw["host"] = self.host.value.strip()
            if kind not in FIXED_PORTS:
                kw["port"] = int(self.port.value)
        field = self.rws_password.of(client)
        typed = field.value if field is not None else ""
        if kind in RWS_KINDS:
            kw["rws_user"] = self.rws_user.value.strip()
            kw["rws_password"] = typed or self.session.link_settings.rws_password
        self.session.set_link(LinkSettings(**kw))
        if field is not None and typed:
            set_value(field, "")  # stored: it is not kept on the page

    def _test_link(self) -> None:
        """Run the session's checklist off the UI thread; the result is shown on it, one
        line per item."""
        self.test_link.disabled = True
        self.check_result.content = "*Testing the connection...*"

        def show(text: str) -> None:
            self.check_result.content = text
            self.test_link.disabled = False

        def work() -> None:
            try:
                result = self.session.check_link()
                head = ("**Connection test: all checks passed**" if result.passed else
                        "**Connection test: some checks failed**")
                text = "\n".join([head] + [f"- `{i.line()}`" for i in result.items])
            except Exception as exc:  # noqa: BLE001 - shown to the operator, page stays up
                text = f"**Connection test could not run:** {exc}"
            self.app.pump.post(lambda: show(text))

        threading.Thread(target=work, name="cellteach-link-check", daemon=True).start()

    def _show_rule(self) -> None:
        """The robot's self-collision rule (the one teach, plan and jog use); sampled off the
        UI thread the first time a robot is seen."""
        lines = self.session.self_collision_rule(compute=False)
        if lines is not None:
            self.rule_text.content = "\n".join(f"- {line}" for line in lines)
            return
        self.rule_text.content = "*Sampling the arm's postures for its self-collision rule...*"

        def work() -> None:
            try:
                got = self.session.self_collision_rule()
                text = "\n".join(f"- {line}" for line in got or [])
            except Exception as exc:  # noqa: BLE001 - shown to the operator, page stays up
                text = f"**The self-collision rule could not be worked out:** {exc}"
            self.app.pump.post(lambda: setattr(self.rule_text, "content", text))

        threading.Thread(target=work, name="cellteach-self-rule", daemon=True).start()

    def _connect(self, client) -> None:  # noqa: ANN001
        self.session.link()
        self.app.notifier.success("The robot link is connected.", client=client)
        self.refresh()

    def refresh(self) -> None:
        s = self.session
        r = s.robot
        spec = s.cell.robot_spec
        ls = s.link_settings
        tool = spec.tool
        tcp_mm = tool.T_flange_tool[2][3] * 1000.0
        lines = [f"**Robot:** {r.name}, {r.dof} axes ({', '.join(r.joint_names)})",
                 f"**Tool:** {tool.name}, TCP {tcp_mm:.1f} mm from the flange",
                 f"**Link:** {LINK_LABELS[ls.kind]}"
                 + ("" if ls.kind == "simulated" else f" at {ls.host}" if ls.kind in FIXED_PORTS
                    else f" at {ls.host}:{ls.port}")
                 + (f", RWS user {ls.rws_user}, password {masked(ls.rws_password)}"
                    if ls.kind in RWS_KINDS else "")]
        if r.dof < 6:
            lines.append(f"*{r.dof}-axis arm: taught orientations are turned into the arm's "
                         "plane; the page says by how much.*")
        self.summary.content = "\n\n".join(lines)
        self._show_rule()
        label = next((k for k, v in ROBOTS.items() if v == spec.kind), None)
        if label is not None:
            set_value(self.robot, label)
        set_value(self.tool_len, round(tcp_mm, 3))
        set_value(self.tool_rad, round(tool.body_radius * 1000.0, 3))
        set_value(self.gripper, bool(tool.has_gripper))
        set_value(self.link_kind, LINK_LABELS[ls.kind])
        set_value(self.time_scale, float(ls.time_scale))
        set_value(self.host, ls.host)
        set_value(self.port, int(ls.port))
        set_value(self.rws_user, ls.rws_user)
        self._robot_kind_changed()
        self._link_kind_changed()

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, SceneChanged) and ev.what in ("robot", "link", "all") or \
                isinstance(ev, StateChanged) and ev.state == "setup":
            self.refresh()


def mask_style(field: viser.GuiTextHandle) -> str:
    """A style that shows `field`'s characters as dots. viser 1.1 draws a labelled input as
    a Mantine Flex row: a Box with the Text holding `<label for=uuid>`, then the input."""
    uuid = field._impl.uuid  # noqa: SLF001 - the id the page knows the field by
    return (f'<style>.mantine-Flex-root:has(> div > p > label[for="{uuid}"]) input '
            "{-webkit-text-security: disc; text-security: disc;}</style>")
