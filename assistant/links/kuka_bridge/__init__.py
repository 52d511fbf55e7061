"""The controller side of the KUKA REST bridge (source 002's "File KRL" route), shipped with
cellteach: the KRL actuator `cellbridge.src` / `cellbridge.dat` that runs on the robot, the
REST server `bridge_server.py` (standard library only: it runs on the KR C4's Windows side
or a PC next to it) and the install sheet `INSTALL.md`. `files()` gives their paths."""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
FILES = ("cellbridge.src", "cellbridge.dat", "bridge_server.py", "INSTALL.md")


def files() -> dict[str, Path]:
    return {name: HERE / name for name in FILES}
