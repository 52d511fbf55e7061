"""The seams between the page, the session and the links carry types, not sentences: a toolbar
command is a `PageCommand`, a halt is `LinkEvent.halt`, a collision is recorded in one place,
and an upload is decided (layout or part) by the session."""

from __future__ import annotations

import threading
from concurrent.futures import wait
from pathlib import Path

import numpy as np
import pytest

from assistant.session.commands import PageCommand
from assistant.session.events import CollisionRecorded, Event, RobotHalted
from assistant.session.session import Session
from assistant.session.types import HiddenObstacle

ROOT = Path(__file__).resolve().parents[2]

#: Events arrive on the link's thread: waited for with a generous deadline (a busy machine).
DEADLINE_S = 60.0


def _collect(s: Session) -> list[Event]:
    seen: list[Event] = []
    s.bus.subscribe(seen.append)
    return seen


@pytest.mark.parametrize("command", [PageCommand.COLLISION, "collision"])
def test_collision_on_a_standing_robot_is_recorded_once(command):
    """The enum and the old name do the same; the one record, the count and the event agree."""
    s = Session()
    seen = _collect(s)
    q = s.current_joints()
    s.fire(command)
    recorded = [e for e in seen if isinstance(e, CollisionRecorded)]
    assert len(recorded) == 1 and recorded[0].count == 1 and recorded[0].source == "operator"
    assert len(s.recorded_collisions) == 1 and s.counters.collision_indications == 1
    assert np.array_equal(s.recorded_collisions[0], q)  # where the robot stands
    assert s.recorded_collisions is s.planning.recorded_collisions  # one list, in one part


def test_page_commands_are_the_machines_event_names():
    from workflow.machine import MODE_EVENTS

    modes = {ev for events in MODE_EVENTS.values() for ev, _label in events}
    assert modes <= {c.value for c in PageCommand}
    assert {"next", "previous", "exit"} <= {c.value for c in PageCommand}


def test_a_halt_is_announced_once_from_the_links_typed_field_and_collision_ends_it():
    """The page's simulated robot halts against a hidden box on its way and waits; the
    session learns it from `LinkEvent.halt` (once per halt, however long it stands), and
    Collision! records that posture once, as the operator's."""
    s = Session()  # the RV-2AJ
    s.set_simulation_speed(20.0)
    q0, q1 = np.radians([-45.0, 45.0, 45.0, 30.0, 0.0]), np.radians([60.0, 45.0, 45.0, 30.0, 0.0])
    s.jog_joints(q0)  # nothing hidden yet: it gets there
    mid = s.tcp_world(0.5 * (q0 + q1))  # the box stands on the TCP's way, half-way
    s.set_hidden_obstacles([HiddenObstacle("crate", "box", (0.08, 0.08, 0.08), mid)])
    s.set_operator_confirms_contacts(True)
    halted = threading.Event()
    seen = _collect(s)
    s.bus.subscribe(lambda e: isinstance(e, RobotHalted) and halted.set())
    link_halts = []
    s.link().subscribe(lambda e: e.halt is not None and link_halts.append(e.halt))
    fut = s.jog_joints(q1, wait=False)
    assert halted.wait(DEADLINE_S)
    wait([fut], timeout=1.5)  # it waits there (longer than its 0.5 s look at the buttons)
    assert not fut.done() and s.setup.halted
    s.fire(PageCommand.COLLISION)
    fut.exception(timeout=DEADLINE_S)
    halts = [e for e in seen if isinstance(e, RobotHalted)]
    assert len(halts) == 1 and len(link_halts) == 1
    assert halts[0].what == link_halts[0].touching and "crate" in halts[0].what
    recorded = [e for e in seen if isinstance(e, CollisionRecorded)]
    assert len(recorded) == 1 and recorded[0].source == "operator"
    assert len(s.recorded_collisions) == 1 and not s.setup.halted
    s.close()


def test_an_upload_is_decided_by_the_session_reading_the_layout_once(monkeypatch):
    """The thesis' layout DXF is imported as a layout (its parts where drawn, its start and
    goal taught), a one-part DXF as a part; the session reads each for a layout once, and
    ezdxf parses the layout once for its layout and both its parts."""
    from ezdxf import recover

    from assistant.cell.cad import layout as layout_module
    from assistant.session import layout_part

    reads: list[str] = []
    real = layout_module.read_layout

    def counted(data: bytes, filename: str):  # noqa: ANN202
        reads.append(filename)
        return real(data, filename)

    parses: list[int] = []
    real_parse = recover.read

    def parse(stream, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        parses.append(len(stream.getvalue()))
        return real_parse(stream, *args, **kwargs)

    monkeypatch.setattr(layout_part, "read_layout", counted)
    monkeypatch.setattr(recover, "read", parse)
    s = Session.from_sample("thesis_rv2aj", with_objects=False, with_mission=False)
    s.goto("cad")
    parses.clear()  # the sample's saved cell was read
    dxf = ROOT / "sample_cells" / "thesis_rv2aj" / "dxf"
    job = s.start_import_file((dxf / "cell_layout.dxf").read_bytes(), "cell_layout.dxf")
    assert job.layout is not None and set(job.layout.parts) == {"O1", "O2"}
    objs = job.future.result(timeout=DEADLINE_S)
    assert sorted(o.name for o in objs) == ["O1", "O2"]
    assert parses == [len((dxf / "cell_layout.dxf").read_bytes())]  # once, not 1 + 2 parts
    assert s.mission.start == "P1"
    assert s.mission.goal == "P10"
    part = s.start_import_file((dxf / "O1.dxf").read_bytes(), "O1.dxf")
    assert part.layout is None
    obj, cad = part.future.result(timeout=DEADLINE_S)
    assert obj.name in s.cell.objects and cad.units == "mm"
    assert reads == ["cell_layout.dxf", "O1.dxf"]
    assert len(parses) == 2  # the part: parsed once by its import (no LOCATIONS layer)


def test_the_record_is_the_one_list_of_indications_and_forgetting_follows_it(tmp_path):
    """`recorded_collisions` is the one list of indications (saved, learnt by every world
    model); a world model keeps what they taught. Forgetting learnt entry n (numbered as a
    re-plan and the page name them) takes from the record the indication behind it, found
    by its posture (the same posture again is the next entry), not every one near it; an
    indication no world learnt yet stays. With no world built, n counts the record."""
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.next()
    s.add_primitive("box", (0.05, 0.05, 0.05), name="keep",
                    T_world_object=np.array([[1, 0, 0, 0.5], [0, 1, 0, 0.5],
                                             [0, 0, 1, 0.025], [0, 0, 0, 1.0]]))
    s.goto("place")
    s.build_world()
    world = s.planning.backend.world
    a = np.radians([10.0, 20.0, 60.0, 10.0, 0.0])
    b = np.radians([-30.0, 30.0, 50.0, 20.0, 0.0])
    c = np.radians([40.0, 10.0, 70.0, 0.0, 0.0])
    for q in (a, b, a):  # a standing robot's Collision!, learnt at once
        s.planning.record_collision(q, "operator", learnt_by_run=False)
    # a link's report that no run fed to this world (e.g. Collision! while jogging)
    s.planning.record_collision(c, "operator", learnt_by_run=True)
    assert [len(s.recorded_collisions), len(world.collisions)] == [4, 3]
    assert len(s.learnt_indications()) == 3
    first = world.collisions[0]
    assert s.forget_indication(3) == {"forgotten": 3, "learnt": 2}
    assert [r.tolist() for r in s.recorded_collisions] == [a.tolist(), b.tolist(), c.tolist()]
    assert len(world.collisions) == 2 and world.collisions[0] is first
    assert np.array_equal(world.collisions[1].q, b)
    s.forget_indication(1)
    assert [r.tolist() for r in s.recorded_collisions] == [b.tolist(), c.tolist()]
    assert [rc.q.tolist() for rc in world.collisions] == [b.tolist()]
    back = Session.load(s.folder, autosave=False)  # no world model built yet
    assert [r.tolist() for r in back.recorded_collisions] == [b.tolist(), c.tolist()]
    assert back.forget_indication(2) == {"forgotten": 2, "learnt": 1}
    assert [r.tolist() for r in back.recorded_collisions] == [b.tolist()]
    back.forget_indication(1)
    with pytest.raises(Exception, match="no indication 1 to forget: 0 learnt"):
        back.forget_indication(1)
