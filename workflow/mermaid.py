"""A Mermaid state diagram generated from the workflow tables (pasted into the README).

`python -m workflow.mermaid` prints it; a test checks the README holds the current one.
"""

from __future__ import annotations

from workflow.machine import JUMPS, MODE_EVENTS
from workflow.states import NUMBER, WORKFLOW, StateSpec, leaves, next_state


def _node(state_id: str) -> str:
    return state_id.replace(".", "_")


def diagram() -> str:
    lines = ["stateDiagram-v2"]

    def declare(specs: tuple[StateSpec, ...], indent: str) -> None:
        for s in specs:
            label = f"{NUMBER[s.id]} {s.title}"
            if s.children:
                lines.append(f'{indent}state "{label}" as {_node(s.id)} {{')
                declare(s.children, indent + "    ")
                lines.append(f"{indent}}}")
            else:
                lines.append(f'{indent}state "{label}" as {_node(s.id)}')

    declare(WORKFLOW, "    ")
    lines.append(f"    [*] --> {_node(leaves()[0])}")
    for leaf in leaves():
        nxt = next_state(leaf)
        if nxt is not None:
            lines.append(f"    {_node(leaf)} --> {_node(nxt)}: Next")
    for j in JUMPS:
        lines.append(f"    {_node(j.source)} --> {_node(j.target)}: {j.label}")
    modes = ", ".join(f"{m.value}: {' / '.join(lbl for _, lbl in evs)}"
                      for m, evs in MODE_EVENTS.items())
    lines.append(f"    note right of {_node(leaves()[-1])}")
    lines.append(f"        Modes over any step - {modes}")
    lines.append("        Previous goes back along the same numbering")
    lines.append("    end note")
    return "\n".join(lines)


if __name__ == "__main__":
    print(diagram())
