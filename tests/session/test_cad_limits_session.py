"""Issues 33 and 54: bad or big CAD never leaves the session stuck.

After each bad input the session is idle, unchanged and the next command succeeds; a big
import runs off the session lock (queries answer at once, edits are refused at once with the
reason instead of waiting), reports progress and can be cancelled without a trace.
"""

from __future__ import annotations

import queue
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from bench_modules import load_benchmark
from test_file_guard import zip_bomb

from assistant.cell.cad import CadImportError
from assistant.progress import Cancelled
from assistant.session.events import ProgressChanged
from workflow.machine import TransitionRefused

make_stl = load_benchmark("cad_import").make_stl
write_binary_stl = load_benchmark("cad_import").write_binary_stl


def _at_cad(s):
    s.next()
    assert s.machine.state == "cad"
    return s


def _bad_inputs(tmp_path: Path) -> list[tuple[str, bytes, str]]:
    over = tmp_path / "over.stl"
    tri = np.random.default_rng(3).random((260_000, 3, 3)).astype(np.float32) * 100
    write_binary_stl(over, tri)
    return [
        ("huge.obj", b"v 0 0 0\nv 1e27 0 0\nv 0 1e27 0\nf 1 2 3\n", "m across"),
        ("far.obj", b"v 1e9 0 0\nv 1e9 1 0\nv 1e9 0 1\nf 1 2 3\n", "from its own origin"),
        ("nan.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
        ("inf.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex inf 0 0\n"
                    b"vertex 0 1 0\nendloop\nendfacet\nendsolid x\n", "NaN or infinite"),
        ("over.stl", over.read_bytes(), "260,000 triangles, more than the 100,000"),
        ("fixture.3mf", zip_bomb(), "would expand from 2 MiB to 2,048 MiB"),
        ("broken.stl", b"\x00" * 84 + b"\x01\x02", "no triangle faces|could not be read"),
    ]


def test_session_stays_usable_after_each_bad_cad_input(empty_session, tmp_path,
                                                        monkeypatch):
    import assistant.cell.cad.importer as importer

    monkeypatch.setattr(importer, "MAX_FACES", 100_000)  # over.stl is over it, and small
    s = _at_cad(empty_session)
    for filename, data, says in _bad_inputs(tmp_path):
        before = s.document().obstacles_key()
        t0 = time.perf_counter()
        with pytest.raises(CadImportError, match=says) as info:
            s.import_cad(data, filename)
        assert time.perf_counter() - t0 < 30.0
        assert "\n" not in str(info.value) and "Traceback" not in str(info.value)
        assert s.machine.mode.value == "idle", filename
        assert s.document().obstacles_key() == before
        # Another command succeeds at once.
        box = s.add_primitive("box", (0.1, 0.1, 0.1), name=f"after_{filename.split('.')[0]}")
        assert box.name in s.cell.objects
        s.remove_object(box.name)


def test_a_huge_primitive_is_refused_and_the_session_goes_on(empty_session):
    s = _at_cad(empty_session)
    with pytest.raises(Exception, match="larger than the 1000 m"):
        s.add_primitive("box", (1e27, 1.0, 1.0))
    assert s.add_primitive("sphere", (0.05,)).name in s.cell.objects


class _ProgressGate:
    """Holds the import's worker inside its progress reports, one report at a time.

    While the worker is held the import is provably mid-way, so a probe that returns then was
    not queued behind it - no clock involved, so a busy machine cannot fail the test.
    """

    def __init__(self, bus, task: str, reports: int):
        self._task, self._left = task, reports
        self.held: queue.Queue[ProgressChanged] = queue.Queue()
        self._go: queue.Queue[None] = queue.Queue()
        bus.subscribe(self._on)

    def _on(self, ev) -> None:
        if (isinstance(ev, ProgressChanged) and ev.task == self._task and not ev.done
                and self._left > 0):
            self._left -= 1
            self.held.put(ev)
            self._go.get(timeout=120)  # never for ever: a failed test must not hang the run

    def release(self) -> None:
        self._go.put(None)


def _answers(fn, deadline_s: float = 30.0):
    """fn() run in a thread: its result, or a failure if it waits `deadline_s` (queued)."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(fn).result(timeout=deadline_s)


def _refused_while(s, task: str) -> bool:
    assert s.transitions() and s.document() is not None and s.scene_objects() is not None
    with pytest.raises(TransitionRefused, match=f"Wait for '{task}'"):
        s.add_primitive("box", (0.1, 0.1, 0.1))
    return True


def test_a_big_import_does_not_block_the_session_and_can_be_cancelled(empty_session,
                                                                        tmp_path):
    s = _at_cad(empty_session)
    data = make_stl("surface", 200_000, tmp_path).read_bytes()
    gate = _ProgressGate(s.bus, "import big.stl", reports=1)

    fut = s.start_import_cad(data, "big.stl")
    gate.held.get(timeout=60)  # the import is held inside a progress report
    assert not fut.done()

    # A second command is answered while the import cannot move on: not queued behind it.
    for _ in range(3):
        assert _answers(lambda: _refused_while(s, "import big.stl"))
    assert not fut.done()
    # Cancel: the import stops, nothing is added, the session is idle and usable.
    s.cancel()
    gate.release()
    with pytest.raises(Cancelled):
        fut.result(timeout=60)
    assert not s.cell.objects and s.machine.mode.value == "idle"
    assert s.add_primitive("box", (0.1, 0.1, 0.1)).name in s.cell.objects


def test_a_big_import_finishes_with_a_report_while_the_session_answers(empty_session,
                                                                        tmp_path):
    s = _at_cad(empty_session)
    data = make_stl("surface", 120_000, tmp_path).read_bytes()
    gate = _ProgressGate(s.bus, "import ring.stl", reports=6)
    fut = s.start_import_cad(data, "ring.stl")
    probed = 0
    while not fut.done():
        try:
            gate.held.get(timeout=0.5)
        except queue.Empty:
            continue
        # Held at each of its first progress reports, the import holds no session lock there:
        # an edit (a locked action) is refused with the reason instead of waiting.
        assert _answers(lambda: _refused_while(s, "import ring.stl"))
        probed += 1
        gate.release()
    obj, cad = fut.result()
    assert probed >= 2  # more than one stage of the import was probed
    assert obj.name == "ring" and s.machine.mode.value == "idle"
    assert len(cad.display_mesh.faces) <= 100_000 < len(cad.mesh.faces)  # drawn decimated
    assert obj.full_mesh is cad.mesh and obj.display_mesh is cad.display_mesh
    assert cad.proxy.kind != "mesh" and cad.proxy.faces <= 20_000
    assert any("drawn with 100,000 of its" in b for b in cad.bounded)
    assert "bounded:" in cad.summary()


def test_import_waits_synchronously_for_scripts(empty_session):
    s = _at_cad(empty_session)
    box = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"
    obj, cad = s.import_cad(box.encode(), "tet.obj", units="m")
    assert obj.name in s.cell.objects and threading.active_count() >= 1


def test_a_part_beyond_the_working_volume_is_announced(empty_session):
    s = _at_cad(empty_session)
    notes: list[str] = []
    s.bus.subscribe(lambda ev: notes.append(getattr(ev, "message", "")))
    plate = ("v -3 -3 0\nv 3 -3 0\nv 3 3 0\nv -3 3 0\nv -3 -3 0.01\nv 3 -3 0.01\nv 3 3 0.01\n"
             "v -3 3 0.01\nf 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\n"
             "f 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n")
    s.import_cad(plate.encode(), "floor.obj", units="m")
    assert any("reaches beyond the robot's working volume" in n for n in notes), notes
    T = np.eye(4)
    T[:3, 3] = (50.0, 0.0, 0.0)
    s.place_object("floor", T)
    assert any("entirely outside the robot's working volume" in n for n in notes), notes


def test_importing_a_pipe_or_a_device_path_is_refused_at_once(empty_session, tmp_path):
    """A FIFO named as a CAD file has no writer: reading it would hang the session."""
    import os

    from assistant.session.types import SessionError

    s = _at_cad(empty_session)
    os.mkfifo(tmp_path / "part.stl")
    for path, what in ((tmp_path / "part.stl", "named pipe"), ("/dev/zero", "character device")):
        t0 = time.perf_counter()
        with pytest.raises(SessionError, match=what):
            s.import_cad_path(path)
        assert time.perf_counter() - t0 < 30.0
        assert s.machine.mode.value == "idle" and not s.cell.objects
