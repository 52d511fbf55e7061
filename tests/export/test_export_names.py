"""The operator's names survive into every dialect: kept where legal, renamed once where a
controller's rules forbid them, generated points named after where they lead (issue 35)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from assistant.export import export_files, get_dialect, program_from_trajectory
from assistant.export.names import identity, legal_names
from assistant.export.samples import thesis_trajectory
from assistant.mission.model import ApplicationPath, PathSegment, SegmentKind
from assistant.mission.motion import Trajectory
from assistant.trajectory.application import application_motions, reversed_path


def _renamed_thesis(rv2aj, names: dict[str, str]):
    traj = thesis_trajectory(rv2aj)

    def nm(w):
        return None if w is None else replace(w, name=names.get(w.name, w.name))

    return Trajectory(nm(traj.start), [replace(m, target=nm(m.target), via=nm(m.via))
                                       for m in traj.motions], traj.actions_at_start)


def test_legal_names_are_kept_without_a_note(rv2aj, thesis_program):
    for dialect in ("melfa", "krl", "rapid", "fanuc", "yaskawa"):
        d = get_dialect(dialect)
        prog, notes = legal_names(thesis_program, d.rules,
                                  getattr(d, "position_identifiers", identity))
        assert notes == () and prog is thesis_program


def test_a_name_too_long_for_melfa_iv_is_renamed_once_and_kept_by_krl(rv2aj):
    traj = _renamed_thesis(rv2aj, {"P7": "SEAMSTART", "P8": "seamstart"})
    prog = program_from_trajectory(traj, rv2aj, name="T")
    melfa = export_files(prog, "melfa", rv2aj)
    assert len(melfa.renames) == 2, melfa.renames  # one line per renamed position
    assert all("MELFA BASIC IV allows at most 8" in r for r in melfa.renames)
    pos = next(f for f in melfa.files if f.name.endswith(".POS")).data.decode()
    idents = [line.split("=")[0] for line in pos.splitlines()]
    assert all(len(i) <= 8 for i in idents) and len(set(idents)) == len(idents)
    # KRL allows 24 characters but ignores case: only the second spelling is renamed
    krl = export_files(prog, "krl", rv2aj)
    assert len(krl.renames) == 1 and "seamstart" in krl.renames[0], krl.renames
    dat = next(f for f in krl.files if f.name.endswith(".dat")).data.decode()
    assert "XSEAMSTART" in dat


def test_generated_points_are_named_after_their_destination_never_a_taught_name(rv2aj):
    traj = thesis_trajectory(rv2aj)
    keep = {"P1", "P4", "P10"}

    def nm(w, name=None):
        return None if w is None else replace(w, name=name if name is not None else
                                              (w.name if w.name in keep else ""))

    # P2 is taught as "P4_V1": the generated vias on the way to P4 must skip that name
    motions = [replace(m, target=nm(m.target, "P4_V1" if m.target.name == "P2" else None),
                       via=nm(m.via)) for m in traj.motions]
    prog = program_from_trajectory(Trajectory(nm(traj.start), motions), rv2aj, name="T")
    names = [p.name for p in prog.positions()]
    assert names[0] == "P1" and names[-1] == "P10" and "P4" in names
    assert names.count("P4_V1") == 1
    generated = [n for n in names if n not in keep | {"P4_V1"}]
    assert generated and all(n.split("_V")[0] in ("P4", "P10") for n in generated), names


def test_application_path_points_keep_the_taught_names_both_ways(rv2aj):
    p7, via, p8 = (np.array([0.30, -0.06, 0.06]), np.array([0.33, 0.0, 0.06]),
                   np.array([0.30, 0.06, 0.06]))
    path = ApplicationPath("SEAM", [PathSegment(SegmentKind.ARC, (p7, via, p8),
                                                ("P7", "", "P8"))], reversible=True)
    am = application_motions(rv2aj, path)
    assert am.ok, am.failure
    assert am.start.name == "P7" and am.motions[-1].target.name == "P8"
    assert am.motions[-1].via.name == ""  # a typed via stays unnamed: generated later
    back = application_motions(rv2aj, reversed_path(path))
    assert back.ok and back.start.name == "P8" and back.motions[-1].target.name == "P7"
    # names survive a save and load of the mission
    again = ApplicationPath.from_json(path.to_json())
    assert again.segments[0].names == ("P7", "", "P8")


def test_segment_names_must_match_its_points():
    with pytest.raises(ValueError, match="point names"):
        PathSegment(SegmentKind.LINE, (np.zeros(3), np.ones(3)), ("P7",))


def test_approach_and_depart_lines_are_named_and_the_tool_works_on_the_path(rv2aj):
    from assistant.mission.motion import ToolAction, ToolActionKind

    close = ToolAction(ToolActionKind.GRIPPER_CLOSE, channel=1)
    opened = ToolAction(ToolActionKind.GRIPPER_OPEN, channel=1)
    p7, p8 = np.array([0.30, -0.06, 0.06]), np.array([0.30, 0.06, 0.06])
    path = ApplicationPath("SEAM", [PathSegment(SegmentKind.LINE, (p7, p8), ("P7", "P8"))],
                           actions_before=[close], actions_after=[opened], reversible=True,
                           approach=0.04, depart=0.02)
    am = application_motions(rv2aj, path)
    assert am.ok, am.failure
    assert [m.target.name for m in am.motions] == ["P7", "P8", "P8_DEP"]
    assert am.start.name == "P7_APP"
    # tool pointing down: the approach point is 40 mm above P7, the depart 20 mm above P8
    assert np.allclose(am.start.T_base_tool[:3, 3], p7 + [0, 0, 0.04], atol=1e-4)
    assert np.allclose(am.motions[-1].target.T_base_tool[:3, 3], p8 + [0, 0, 0.02], atol=1e-4)
    # the gripper closes on P7 (after the approach) and opens on P8 (before the depart)
    assert am.actions_before == () and am.motions[0].actions_after == (close,)
    assert am.motions[1].actions_after == (opened,) and am.motions[2].actions_after == ()
    back = application_motions(rv2aj, reversed_path(path))
    assert back.ok and back.start.name == "P8_APP"
    assert [m.target.name for m in back.motions] == ["P8", "P7", "P7_DEP"]
    assert np.allclose(back.start.T_base_tool[:3, 3], p8 + [0, 0, 0.02], atol=1e-4)
