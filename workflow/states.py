"""The numbered states of the operator workflow (SPEC §1) as a small tree.

Main states are numbered along the standard path; a composite state's children are numbered
below it (3.1, 3.2). The UI shows the panel of the current *leaf*. Previous/Next follow the
thesis' rule: Next = next higher sibling, else the parent's Next; Previous = next lower
sibling, else the parent's Previous. Entering a composite state forwards lands on its first
child, backwards on its last child (so Previous from 4.1 returns to 3.2, the step just done).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class StateSpec:
    id: str  # dotted path, e.g. "place.cameras"
    title: str
    help: str = ""
    children: tuple[StateSpec, ...] = field(default=())

    @property
    def is_leaf(self) -> bool:
        return not self.children


WORKFLOW = (
    StateSpec("setup", "Set up robot & link",
              "Choose the robot, its tool and how the assistant talks to it."),
    StateSpec("cad", "Import CAD", "Upload the parts of the cell (STL, OBJ, PLY, GLB, 3MF, DXF, "
              "STEP) and confirm their units."),
    StateSpec("place", "Place models", "", (
        StateSpec("place.objects", "Place objects",
                  "Drag, type exact numbers, or measure 3-4 points on the real part."),
        StateSpec("place.cameras", "Calibrate cameras",
                  "Check the camera views and calibrate the pointer colour."),
    )),
    StateSpec("teach", "Teach mission", "", (
        StateSpec("teach.locations", "Teach locations",
                  "Teach start, goal and points by CAD click, robot pose or the pointer."),
        StateSpec("teach.paths", "Application paths",
                  "Define the lines, arcs and curves the tool follows, with gripper actions."),
    )),
    StateSpec("explore", "Explore workspace",
              "Build the reachability table and the roadmap; optionally move the robot around."),
    StateSpec("plan", "Plan & execute",
              "Plan, watch the robot, press Collision! when it would hit something."),
    StateSpec("export", "Export program", "Preview and download the robot program."),
)


def _index() -> tuple[dict[str, StateSpec], dict[str, str | None], dict[str, str]]:
    by_id: dict[str, StateSpec] = {}
    parent: dict[str, str | None] = {}
    number: dict[str, str] = {}

    def walk(specs: tuple[StateSpec, ...], par: str | None, prefix: str) -> None:
        for i, s in enumerate(specs, start=1):
            by_id[s.id] = s
            parent[s.id] = par
            number[s.id] = f"{prefix}{i}"
            walk(s.children, s.id, f"{prefix}{i}.")

    walk(WORKFLOW, None, "")
    return by_id, parent, number


STATES, PARENT, NUMBER = _index()


def siblings(state_id: str) -> tuple[StateSpec, ...]:
    par = PARENT[state_id]
    return WORKFLOW if par is None else STATES[par].children


def first_leaf(state_id: str) -> str:
    s = STATES[state_id]
    while s.children:
        s = s.children[0]
    return s.id


def last_leaf(state_id: str) -> str:
    s = STATES[state_id]
    while s.children:
        s = s.children[-1]
    return s.id


def next_state(state_id: str) -> str | None:
    """Next higher sibling (entered at its first leaf), else the parent's next; None at the end."""
    sib = siblings(state_id)
    ids = [s.id for s in sib]
    i = ids.index(state_id)
    if i + 1 < len(ids):
        return first_leaf(ids[i + 1])
    par = PARENT[state_id]
    return None if par is None else next_state(par)


def previous_state(state_id: str) -> str | None:
    """Next lower sibling (entered at its last leaf), else the parent's previous."""
    sib = siblings(state_id)
    ids = [s.id for s in sib]
    i = ids.index(state_id)
    if i > 0:
        return last_leaf(ids[i - 1])
    par = PARENT[state_id]
    return None if par is None else previous_state(par)


def main_state(state_id: str) -> str:
    """The top-level state a leaf belongs to ("teach.paths" -> "teach")."""
    return state_id.split(".")[0]


def leaves() -> list[str]:
    out: list[str] = []

    def walk(specs: tuple[StateSpec, ...]) -> None:
        for s in specs:
            if s.children:
                walk(s.children)
            else:
                out.append(s.id)

    walk(WORKFLOW)
    return out
