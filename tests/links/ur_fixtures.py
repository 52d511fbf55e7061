"""Shared pieces of the UR link tests: the UR5 of example-robot-data, postures, starting an
emulator (on its own loopback address, so ur-rtde's fixed RTDE port 30004 is free), and
running ur-rtde's receive interface in a child process (its constructor holds the GIL while
it waits for data: in-process it would starve the emulator's threads)."""

from __future__ import annotations

import contextlib
import json
import random
import select
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from assistant.collision.reports import Obstacle
from assistant.emulators.ur_emulator import UREmulator
from assistant.links.ur import URLink
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T

UR5_URDF = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"

#: Postures: the wrist down in front of the base; an exploration sweep about J1.
HOME = np.array([-0.8, -1.1, 1.2, -1.67, -1.57, 0.0])
Q_A = np.array([-0.8, -1.57, 1.57, -1.57, -1.57, 0.0])
Q_B = np.array([0.8, -1.57, 1.57, -1.57, -1.57, 0.0])
WIRE_TOL = 1e-6  # rad: joints go out with 7 decimals


@pytest.fixture(scope="session")
def ur5():
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.model import Tool
    from assistant.robots.urdf_robot import URDFRobot

    urdf, share = installed_robot_urdf(UR5_URDF)
    T = np.eye(4)
    T[2, 3] = 0.1
    # tool0: the UR's own tool flange (the URDF's default ee_link is turned against it)
    return URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False,
                               tool_link="tool0", tool=Tool("gripper", T))


def box_on_wrist(robot, qa, qb, frac: float, size: float = 0.08) -> Obstacle:  # noqa: ANN001
    """A box around the flange at `frac` of the joint motion qa -> qb (the gripper model has
    no collision shape, the wrist has)."""
    q = qa + frac * (qb - qa)
    p = robot.with_tool(np.eye(4)).fk(q)[:3, 3]
    return Obstacle("hidden", make_T(p=p), (CollisionShape(ShapeKind.BOX, (size,) * 3),))


def start_emulator(robot, closing, *, rtde_port: int = 0, **kw) -> UREmulator:  # noqa: ANN001
    """An emulator on a random 127.x.y.z (rtde_port 30004 for ur-rtde, else any port)."""
    kw.setdefault("start_q", HOME)
    kw.setdefault("time_scale", 4.0)
    kw.setdefault("unlock_delay_s", 0.3)
    kw.setdefault("local_mode", False)  # the factory state (Local) has its own tests
    for _ in range(20):
        host = f"127.{random.randint(1, 250)}.{random.randint(1, 250)}.{random.randint(2, 250)}"
        with contextlib.suppress(OSError):
            return closing(UREmulator(robot, host=host, rtde_port=rtde_port, **kw).start())
    raise RuntimeError("no free loopback address for the UR emulator")


def connect_link(robot, emu: UREmulator, closing, **kw) -> URLink:  # noqa: ANN001
    kw.setdefault("timeout_s", 1.0)
    kw.setdefault("rtde_hz", 250.0)
    kw.setdefault("unlock_wait_s", 3.0)
    link = closing(URLink(robot, host=emu.host, script_port=emu.script_port,
                          rtde_port=emu.rtde_port, dashboard_port=emu.dashboard_port,
                          primary_port=emu.primary_port, **kw))
    link.connect()
    return link


PEER = textwrap.dedent("""
    import json, sys
    import rtde_receive
    names = json.loads(sys.argv[2])
    r = rtde_receive.RTDEReceiveInterface(sys.argv[1], 500.0, names) if names \\
        else rtde_receive.RTDEReceiveInterface(sys.argv[1])
    for line in sys.stdin:
        if line.strip() == "quit":
            break
        out = {"connected": r.isConnected(), "q": r.getActualQ(),
               "tcp": r.getActualTCPPose(), "robot_mode": r.getRobotMode(),
               "safety_mode": r.getSafetyMode(), "protective_stop": r.isProtectiveStopped(),
               "emergency_stop": r.isEmergencyStopped()}
        if not names:  # the default recipe has these too
            out.update(timestamp=r.getTimestamp(), status=r.getRobotStatus(),
                       joint_mode=r.getJointMode())
        print(json.dumps(out), flush=True)
    r.disconnect()
""")


class Peer:
    """ur-rtde's RTDEReceiveInterface in a child process: `read()` asks it for the state."""

    def __init__(self, host: str, variables: list[str] | None):
        self.proc = subprocess.Popen([sys.executable, "-c", PEER, host,
                                      json.dumps(variables or [])], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def read(self) -> dict:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write("read\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], 30.0)  # never hang the suite
        line = self.proc.stdout.readline() if ready else ""
        if not line:
            self.proc.kill()
            raise AssertionError(f"ur-rtde peer failed: {self.proc.stderr.read()[-2000:]}")
        return json.loads(line)

    def read_until(self, pred, timeout_s: float = 30.0) -> dict:  # noqa: ANN001
        """Read until `pred(state)` (the change reaches the peer within a few packages; the
        deadline is generous for a busy machine - the first state that holds returns)."""
        deadline = time.monotonic() + timeout_s
        while True:
            got = self.read()
            if pred(got) or time.monotonic() > deadline:
                return got
            time.sleep(0.01)

    def close(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            self.proc.stdin.write("quit\n")
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=5.0)
