"""The thesis scenario in the page, driven as an operator would, counting what they do.

Shared by `tests/web/test_web_scenario.py` (which asserts on it) and
`benchmarks/operator_effort.py` (which reports it). Only what a person sees and uses: labelled
buttons and fields, the file chooser, the Space key; waits are for what the page shows.

Counted as operator actions: clicks, fields typed (a field is one action however many keys),
choices, uploads, key presses, the download. Not counted but reported as `world`: the ball's
position typed into the synthetic camera - it stands in for the operator holding the pointer
at the spot, which with real cameras is not a page action at all.
"""

from __future__ import annotations

import re
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from web_ui import UI

#: World build, planning and a run at real time with re-plans on a loaded 2-core machine.
LONG_MS = 600_000


@dataclass
class Effort:
    """What the operator did and how long they waited, per workflow step."""

    actions: Counter = field(default_factory=Counter)  # kind -> count
    log: list[tuple[str, str, str]] = field(default_factory=list)  # (step, kind, what)
    world: list[str] = field(default_factory=list)  # stand-ins for the physical pointer
    machine_wait_s: dict[str, float] = field(default_factory=dict)  # step -> seconds
    robot_run_s: float = 0.0  # Execute -> goal reached (robot time at 1x, re-plans, halts)
    #: The synthetic pointer's dwells: the ball held still (1 s) plus rendering its frames;
    #: with real cameras the operator's hold, not the machine's work.
    pointer_s: float = 0.0
    shots: list[Path] = field(default_factory=list)
    download: tuple[str, bytes] | None = None
    moves_shown: int | None = None

    @property
    def total(self) -> int:
        return sum(self.actions.values())


class Operator:
    """A person at the page: each method is one action (or one wait) and is recorded."""

    def __init__(self, ui: UI):
        self.ui = ui
        self.effort = Effort()
        self.where = "1"

    def _act(self, kind: str, what: str) -> None:
        self.effort.actions[kind] += 1
        self.effort.log.append((self.where, kind, what))

    def click(self, name: str) -> None:
        self._act("click", name)
        self.ui.click(name)

    def type(self, label: str, value: str) -> None:
        self._act("typed", f"{label} = {value}")
        self.ui.fill(label, value)

    def upload(self, button: str, path: Path) -> None:
        self._act("upload", path.name)
        self.ui.upload(button, path)

    def key(self, key: str, what: str) -> None:
        self._act("key", f"{key} ({what})")
        self.ui.page.keyboard.press(key)

    def download(self, button: str) -> tuple[str, bytes]:
        self._act("click", button)
        return self.ui.download(button)

    def hold_pointer_at(self, point_mm: tuple[float, float, float]) -> None:
        """The ball held still at a spot: with the synthetic camera, typed as its position."""
        self.effort.world.append(f"pointer at {point_mm} mm")
        self.ui.fill_vec("Point (mm)", point_mm)

    def wait(self, fn, *args, **kw):
        """A machine wait of the current step (the operator can do nothing meanwhile)."""
        t0 = time.perf_counter()
        out = fn(*args, **kw)
        self.effort.machine_wait_s[self.where] = \
            self.effort.machine_wait_s.get(self.where, 0.0) + time.perf_counter() - t0
        return out

    def dwell(self, name: str) -> None:
        """The pointer held still until the dwell teaches `name` (see `Effort.pointer_s`)."""
        t0 = time.perf_counter()
        self.ui.wait_cell(name)
        self.effort.pointer_s += time.perf_counter() - t0

    def at(self, number: str) -> None:
        self.ui.step(number)
        self.where = number

    def shot(self, name: str) -> None:
        self.effort.shots.append(self.ui.shot(name))


def run_thesis_scenario(ui: UI, sample: Path,
                        after_goal: Callable[[UI], None] | None = None) -> Effort:
    """From an empty page (robot, link and hidden O3 only) to the downloaded MELFA program.

    `after_goal`: done at the goal, before step 7, and not counted (a measurement of the
    caller's, e.g. driving the final program once)."""
    op = Operator(ui)
    op.at("1")
    op.shot("1-setup")
    op.click("Next")
    op.at("2")
    # 2. The work table in one click; O1, O2 and the start/goal P1/P10 from the cell layout.
    op.click("Add the work table")
    op.wait(ui.wait_cell, "table")
    op.upload("Upload CAD file", sample / "dxf" / "cell_layout.dxf")
    op.wait(ui.wait_text, re.compile(r"Imported O1, O2 from the cell layout"), LONG_MS)
    op.shot("2-cad")
    # The parts stand where drawn: placing waits (the cameras were calibrated with the cell).
    op.click("Skip to teaching")
    op.at("4.1")
    ui.wait_cell("P1")
    ui.wait_cell("P10")
    # 4.1 P7 and P8 by pointer dwell; the name after P7 is suggested.
    op.type("Name", "P7")
    op.hold_pointer_at((340, -70, 60))
    op.click("Teach by pointer dwell")
    op.dwell("P7")
    _wait_value(ui, "Name", "P8")
    op.hold_pointer_at((340, 70, 60))
    op.click("Teach by pointer dwell")
    op.dwell("P8")
    op.shot("4-taught")
    op.click("Next")
    op.at("4.2")
    # 4.2 The seam through the points just taught (offered in the Through field).
    _wait_value(ui, "Through", "P7, P8")
    op.type("Path name", "SEAM")
    op.click("Add path")
    op.wait(ui.wait_cell, "SEAM")
    op.shot("4-paths")
    op.click("Next")
    op.at("5")
    # 5. Entering the step builds the world model.
    op.wait(ui.wait_text, "World model ready", LONG_MS)
    op.shot("5-world")
    op.click("Next")
    op.at("6")
    # 6. Entering the step plans; the operator executes and presses Collision! at each halt.
    op.wait(ui.wait_enabled, "Execute on the robot", LONG_MS)
    op.shot("6-planned")
    op.click("Execute on the robot")
    t0 = time.perf_counter()
    press_collision_at_each_halt(ui, lambda: op.key("Space", "Collision!"),
                                 first=lambda: op.shot("6-halted"))
    op.effort.robot_run_s = time.perf_counter() - t0
    ui.wait_text(re.compile(r"Goal reached: the robot is at P10"))
    op.shot("6-executed")
    if after_goal is not None:
        after_goal(ui)
    moves = re.search(r"Mission planned: (\d+) moves", ui.page.inner_text("body"))
    op.effort.moves_shown = int(moves.group(1)) if moves else None
    op.click("Next")
    op.at("7")
    # 7. Entering the step writes the program in the robot's language.
    op.wait(ui.wait_enabled, "Download", LONG_MS)
    op.wait(ui.wait_text, ".MB4")
    op.shot("7-export")
    op.effort.download = op.download("Download")
    return op.effort


def press_collision_at_each_halt(ui: UI, press, first=None) -> int:
    """Until "Goal reached": at each halt of the simulated robot (numbered in the plan panel,
    so a halt right after the last press is not missed and none is pressed twice), `press`
    Collision! and wait until it is recorded. Returns the number of presses."""
    pressed = 0
    while True:
        found = ui.page.wait_for_function(
            """([halt]) => {
                const t = document.body.innerText;
                if (t.includes('Goal reached')) return 'goal';
                if (t.includes(halt)) return 'halted';
                const errs = [...document.querySelectorAll('.mantine-Notification-root')]
                    .filter(e => e.innerText.includes('Could not do that'));
                return errs.length ? 'ERROR: ' + errs[0].innerText : false;
            }""", arg=[f"(halt {pressed + 1} of this run)"], timeout=LONG_MS,
            polling=200).json_value()
        if found == "goal":
            return pressed
        if found != "halted":
            raise AssertionError(f"the run ended with {found}")
        if pressed == 0 and first is not None:
            first()
        press()
        pressed += 1
        ui.wait_text(re.compile(rf"Collision #{pressed} recorded"))


def _wait_value(ui: UI, label: str, value: str) -> None:
    """Until the field shows `value` (a suggestion the page made)."""
    box = ui.row(label).locator("input:not([type=hidden])").first
    deadline = time.monotonic() + 30
    while box.input_value() != value:
        if time.monotonic() > deadline:
            raise AssertionError(f"{label!r} shows {box.input_value()!r}, not {value!r}")
        ui.page.wait_for_timeout(100)
