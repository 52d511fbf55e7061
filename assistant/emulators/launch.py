"""Start one controller emulator on the vendor's usual ports (``cellteach emulate``).

Each starts in its controller's factory state: the UR as a shipped e-Series in Local control
(`remote=True` switches it, as the pendant's toggle), the IRC5 and the OmniCore with a task
that holds its own ``main``, the KUKA controller running the bridge's KRL program behind
the shipped bridge server, the MELFA with its command and data-link ports. `any_port` picks
free ports instead (tests, or a machine where the usual ones are taken).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

VENDORS = ("ur", "abb", "omnicore", "kuka", "melfa")


@dataclass
class Running:
    emulator: Any
    endpoints: list[tuple[str, str, int]]  # (name, host, port)

    def lines(self) -> list[str]:
        return [f"{name} {host}:{port}" for name, host, port in self.endpoints]

    def close(self) -> None:
        self.emulator.close()


def _ur5(tool_link: str):  # noqa: ANN202
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.urdf_robot import URDFRobot

    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                               tool_link=tool_link)


def start(vendor: str, *, host: str = "127.0.0.1", remote: bool = False,
          any_port: bool = False, time_scale: float = 1.0) -> Running:
    """Start the emulator of `vendor`; raises OSError if a port is taken."""
    if vendor not in VENDORS:
        raise ValueError(f"no emulator {vendor!r}; known: {', '.join(VENDORS)}")
    p = (lambda n: 0) if any_port else (lambda n: n)  # noqa: E731
    if vendor == "ur":
        from assistant.emulators.ur_emulator import UREmulator

        emu = UREmulator(_ur5("tool0"), host=host, rtde_port=p(30004), script_port=p(30002),
                         dashboard_port=p(29999), primary_port=p(30001),
                         realtime_port=p(30003), time_scale=time_scale,
                         start_q=np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0]),
                         local_mode=not remote).start()
        return Running(emu, [("ur-dashboard", host, emu.dashboard_port),
                             ("ur-primary", host, emu.primary_port),
                             ("ur-secondary", host, emu.script_port),
                             ("ur-realtime", host, emu.realtime_port),
                             ("ur-rtde", host, emu.rtde_port)])
    if vendor in ("abb", "omnicore"):
        from assistant.emulators.abb_rws_emulator import AbbRwsEmulator

        v = 2 if vendor == "omnicore" else 1
        emu = AbbRwsEmulator(_ur5("tool0"), host=host, port=p(443 if v == 2 else 80),
                             rws_version=v, time_scale=time_scale).start()
        return Running(emu, [(f"{vendor}-rws{'2' if v == 2 else '1'}", host, emu.port)])
    if vendor == "kuka":
        from assistant.emulators.kuka_krc_emulator import KukaKrcEmulator

        emu = KukaKrcEmulator(host=host, port=p(8000), time_scale=time_scale).start()
        return Running(emu, [("kuka-bridge", host, emu.port)])
    from assistant.emulators.melfa_emulator import MelfaEmulator
    from assistant.robots.rv2aj import RV2AJ

    emu = MelfaEmulator(RV2AJ(), host=host, port=p(10001),
                        datalink_ports={2: p(10002)}, time_scale=time_scale).start()
    return Running(emu, [("melfa-command", host, emu.port),
                         ("melfa-datalink", host, emu.datalink_port(2))])
