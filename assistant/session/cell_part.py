"""Steps 2 and 3: CAD import, primitives, object roles, placement and measured frames.

A part of the `Session`, composed (`Session.objects`): it has no state of its own: it edits the
session's cell; it reaches the rest of the session only through the parts' contract
(`PartContract`)."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import numpy as np

from assistant.cell.cad import CadImport, CadImportError, load_cad
from assistant.cell.cad.importer import MAX_PART_SIZE_M, read_cad_file
from assistant.cell.model import CellObject, ObjectRole, PrimitiveKind, PrimitiveSpec
from assistant.cell.placement import PoseFit, fit_pose
from assistant.progress import Cancelled, Progress
from assistant.session.contract import PartContract
from assistant.session.events import (
    Notice,
)
from assistant.session.frames import (
    FrameCalibration,
    frame_from_three_points,
)
from assistant.session.types import (
    EDIT_CELL,
    EDIT_PLACEMENT,
    SessionError,
    _safe_name,
    hint_for,
)
from workflow.machine import TransitionRefused

Array = np.ndarray


class CellPart:
    """Steps 2 and 3: CAD import, primitives, object roles, placement and measured frames."""

    def __init__(self, core: PartContract) -> None:
        self._core = core

    # ================================================================== 2. CAD
    def import_cad(self, data: bytes, filename: str, *, name: str | None = None,
                   units: str | None = None, dxf_extrude_height: float | None = None,
                   role: ObjectRole | str = ObjectRole.OBSTACLE,
                   T_world_object: Array | None = None) -> tuple[CellObject, CadImport]:
        """Import a CAD file (bytes as uploaded); the part lands at the world origin or at T.
        Waits for `start_import_cad`: same checks, same lock-free heavy part."""
        return self.start_import_cad(data, filename, name=name, units=units,
                                     dxf_extrude_height=dxf_extrude_height, role=role,
                                     T_world_object=T_world_object).result()

    def start_import_cad(self, data: bytes, filename: str, *, name: str | None = None,
                         units: str | None = None, dxf_extrude_height: float | None = None,
                         role: ObjectRole | str = ObjectRole.OBSTACLE,
                         T_world_object: Array | None = None) -> Future:
        """Import on the worker, with progress and Cancel; the future gives (object, import).

        Reading, repairing and the collision proxy of a big file take seconds: they run
        without the session lock (the machine is busy meanwhile, so the page keeps answering
        and edits are refused with the reason); only adding the part is a short locked
        action, checked again like any other."""
        def read(progress: Progress) -> CadImport:
            return load_cad(data, filename, units=units,
                            dxf_extrude_height=dxf_extrude_height, progress=progress)

        return self.start_cell_job(
            f"import {filename}", read,
            lambda cad: (self._add_imported(cad, filename, name, role, T_world_object), cad))

    def start_cell_job(self, task: str, read: Callable[[Progress], Any],
                       commit: Callable[[Any], Any]) -> Future:
        """`read` (seconds of parsing and repair) on the worker without the session lock, with
        progress and Cancel, while the machine is busy (edits are refused with the reason);
        then `commit(what was read)` as one short locked action. The future gives its result."""
        with self._core.lock:
            try:
                self._core.machine.require(EDIT_CELL, task)
            except TransitionRefused as exc:
                self._core.error(str(exc))
                raise
            self._core.machine.begin_busy(task)
        self._core.emit_state()
        commit_failed = False

        def work(progress: Progress) -> Any:
            nonlocal commit_failed
            got = read(progress.sub(0.0, 0.97))
            progress.update(0.98, "adding to the cell")
            with self._core.lock:  # the heavy part is over: add it as an ordinary short action
                self._core.machine.end_mode()
                commit_failed = True
                out = commit(got)
                commit_failed = False
            return out

        def done(fut: Future) -> None:
            with self._core.lock:
                self._core.machine.end_mode()
                exc = fut.exception()
                if isinstance(exc, Cancelled):
                    self._core.bus.emit(Notice(f"{task} cancelled; nothing was changed"))
                elif exc is not None and not commit_failed:  # the action reported its own
                    self._core.error(f"{task}: {exc}", hint_for(exc))
            self._core.emit_state()

        try:
            return self._core.worker.submit(task, work, done)
        except RuntimeError:
            with self._core.lock:
                self._core.machine.end_mode()
            self._core.emit_state()
            raise

    def _add_imported(self, cad: CadImport, filename: str, name: str | None,
                      role: ObjectRole | str, T_world_object: Array | None) -> CellObject:
        with self._core.action(f"import {filename}", EDIT_CELL, scene="objects"):
            base = name or Path(filename).stem
            obj_name = self._core.cell.unique_name(_safe_name(base)) if name is None else name
            obj = CellObject.from_cad(obj_name, cad, T_world_object, role=role)
            self._core.cell.add_object(obj)
            for w in cad.warnings:
                self._core.bus.emit(Notice(f"{filename}: {w}"))
            for b in cad.bounded:
                self._core.bus.emit(Notice(f"{filename}: {b}"))
            self.note_working_volume(obj)
        return obj

    def note_working_volume(self, obj: CellObject) -> None:
        """Say when a part reaches beyond the cube the world model covers (sized to the arm):
        the exact collision check sees all of it, the world model only what lies inside."""
        try:
            size = float(self._core.world_settings.world_config(self._core.robot).size)
        except Exception:  # noqa: BLE001 - a robot without a world config: nothing to say
            return
        T = np.linalg.inv(self._core.T_world_base()) @ np.asarray(obj.T_world_object, dtype=float)
        lo, hi = obj.part_mesh.bounds
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])]) @ T[:3, :3].T + T[:3, 3]
        half = size / 2.0
        if np.all(np.abs(corners).max(axis=0) <= half):
            return
        if np.any(corners.min(axis=0) > half) or np.any(corners.max(axis=0) < -half):
            self._core.bus.emit(Notice(
                f"{obj.name} lies entirely outside the robot's working volume (the "
                f"{size:.2f} m cube around its base): the robot cannot reach it; place it in "
                "the next step, or check its units if it came out far too large"))
        else:
            self._core.bus.emit(Notice(
                f"{obj.name} reaches beyond the robot's working volume (the {size:.2f} m cube "
                "around its base): collision checks see all of it, the world model only the "
                "part inside the cube"))

    def import_cad_path(self, path: str | Path, **kw: Any) -> tuple[CellObject, CadImport]:
        """`import_cad` of a file on disk: a regular file within the size limit
        (`read_cad_file`), never a device or a pipe."""
        p = Path(path)
        try:
            data = read_cad_file(p)
        except CadImportError as exc:
            raise SessionError(f"cannot import {p}: {exc.problem}"
                               + (f" — {exc.advice}" if exc.advice else "")) from None
        return self.import_cad(data, p.name, **kw)

    def add_primitive(self, kind: str, size: tuple[float, ...], *, name: str | None = None,
                      role: ObjectRole | str = ObjectRole.OBSTACLE,
                      T_world_object: Array | None = None) -> CellObject:
        """A box (x, y, z), cylinder (radius, height) or sphere (radius,), metres."""
        with self._core.action(f"add a {kind}", EDIT_CELL, scene="objects"):
            spec = PrimitiveSpec(PrimitiveKind(kind), tuple(float(v) for v in size))
            if max(spec.size) > MAX_PART_SIZE_M:
                raise SessionError(f"a {kind} of {max(spec.size):.3g} m is larger than the "
                                   f"{MAX_PART_SIZE_M:g} m a cell part can be; give its size "
                                   "in metres")
            obj = CellObject.from_primitive(name or self._core.cell.unique_name(kind), spec,
                                            T_world_object, role=role)
            self._core.cell.add_object(obj)
        return obj

    def remove_object(self, name: str) -> None:
        with self._core.action(f"remove {name}", EDIT_CELL + ("teach", "plan"), scene="objects"):
            self._core.cell.remove_object(name)

    def set_object_role(self, name: str, role: ObjectRole | str) -> None:
        from dataclasses import replace

        with self._core.action(f"change the role of {name}", EDIT_CELL, scene="objects"):
            obj = self._core.cell.get_object(name)
            role = ObjectRole(role)
            self._core.cell.objects[name] = replace(obj, role=role, color=None)

    # ================================================================== 3. placement
    def place_object(self, name: str, T_world_object: Array) -> CellObject:
        with self._core.action(f"place {name}", EDIT_PLACEMENT, scene="objects"):
            obj = self._core.cell.set_object_pose(name, np.asarray(T_world_object, dtype=float))
            self.note_working_volume(obj)
        return obj

    def fit_object_pose(self, name: str, model_points: Array, measured_points: Array) -> PoseFit:
        """N-point placement: model points (object frame) vs the same points measured."""
        with self._core.action(f"place {name} by points", EDIT_PLACEMENT, scene="objects"):
            self._core.cell.get_object(name)
            fit = fit_pose(np.asarray(model_points, float), np.asarray(measured_points, float))
            self._core.cell.set_object_pose(name, fit.T_world_object)
            for w in fit.warnings:
                self._core.bus.emit(Notice(w))
        return fit

    def measure_with_robot(self) -> Array:
        """The robot TCP position (world frame) - touch a point of the part with the tool."""
        return self._core.tcp_world()[:3, 3].copy()

    def calibrate_frame(self, name: str, origin: Array | str, x_point: Array | str,
                        xy_point: Array | str) -> FrameCalibration:
        """A named frame from three measured points (the controllers' 3-point base method):
        its origin, a point on its +x axis and a point in its XY plane on the +y side. Each
        point is a position (world, metres) or the name of a taught location (e.g. the tip
        of the tool touched to the pallet and taught from the robot pose). Re-calibrating an
        existing frame replaces it."""
        with self._core.action(f"calibrate the frame {name}", EDIT_PLACEMENT, scene="frames"):
            pts = [self._point_of(p) for p in (origin, x_point, xy_point)]
            cal = frame_from_three_points(name, *pts)
            self._core.cell.add_frame(name, cal.T_world_frame, replace_existing=True)
            self._core.bus.emit(Notice(cal.describe()))
        return cal

    def place_object_in_frame(self, name: str, frame: str, T_frame_object: Array) -> CellObject:
        """Place an object relative to a named (e.g. calibrated) frame."""
        with self._core.action(f"place {name} on {frame}", EDIT_PLACEMENT, scene="objects"):
            T_world_frame = self.frame(frame)
            obj = self._core.cell.set_object_pose(name, T_world_frame @ np.asarray(T_frame_object,
                                                                                   dtype=float))
        return obj

    def _point_of(self, p: Array | str) -> Array:
        if isinstance(p, str):
            return self._core.teaching.location(p).position.copy()
        a = np.asarray(p, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise SessionError("a measured point needs 3 finite coordinates")
        return a

    def frame(self, name: str) -> Array:
        if name not in self._core.cell.frames:
            known = ", ".join(self._core.cell.frames) or "none yet"
            raise SessionError(f"no frame named {name!r} (frames: {known}); calibrate it first")
        return np.asarray(self._core.cell.frames[name], dtype=float)
