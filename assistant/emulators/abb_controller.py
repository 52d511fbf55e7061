"""The RAPID side of the emulated IRC5: files, loaded modules, program pointer, execution
and the event log, driving an `EmulatedArm`.

The task starts as a shipped controller's does: with a ``MainModule`` holding the cell's own
``PROC main()`` (`FACTORY_MAIN`), so a second module with a main cannot be loaded (RAPID:
one main per task). ``resetpp`` puts the program pointer at main, "set PP to routine" at
any routine without parameters. ``start`` runs from the program pointer (flattened by
`abb_rapid_program`) in a thread;
``stop`` halts the arm and leaves the pointer at the interrupted instruction (a new start
re-runs it, as RAPID does); ``loadmod``/``unloadmod`` lose the pointer until ``resetpp``. A
hidden obstacle stops the program with event 50204 (motion supervision); a joint target
outside the controller's axis ranges with 50027, an unreachable robtarget with 50050.
A move runs at v/1000 of the arm's joint speeds (v the speeddata's TCP speed in mm/s): the
exporter's convention for MoveJ / MoveAbsJ, for MoveL / MoveC only an approximation - the
emulator checks geometry, reach and collisions, not TCP speeds. robtargets are solved with
the cf1/cf4/cf6 quadrants they carry (cfx is not checked: its meaning for a non-ABB arm is a
convention of ours).
"""

from __future__ import annotations

import datetime
import threading
import time
from dataclasses import dataclass

import numpy as np

from assistant.emulators.abb_rapid_program import (
    Module,
    Program,
    RapidError,
    RobTarget,
    Step,
    parse_module,
)
from assistant.emulators.arm import EmulatedArm, solve_wire_pose
from assistant.emulators.cartesian import arc_poses, line_poses
from assistant.links import abb_rws_protocol as rp
from assistant.links.arm_config import arm_config
from assistant.robots.model import Robot

Array = np.ndarray


#: The cell's own program a task holds when it ships (RobotStudio's new-controller template).
FACTORY_MAIN = """MODULE MainModule
    PROC main()
        WaitTime 0.1;
    ENDPROC
ENDMODULE
"""
FACTORY_MAIN_PATH = "$HOME/MainModule.mod"


class RwsError(Exception):
    """A refused request: HTTP status, RobotWare-style return code, message."""

    def __init__(self, http: int, code: int, msg: str):
        super().__init__(msg)
        self.http, self.code, self.msg = http, code, msg


class _Halt(Exception):
    """The program stops here (an error already written to the event log)."""


@dataclass
class ElogRecord:
    seqnum: int
    msgtype: int
    code: int
    title: str
    desc: str
    tstamp: str

    def state(self) -> dict:
        return {"_type": "elog-message-li", "_title": f"/rw/elog/0/{self.seqnum}",
                "msgtype": str(self.msgtype), "code": str(self.code), "tstamp": self.tstamp,
                "title": self.title, "desc": self.desc, "conseqs": "", "causes": "",
                "actions": "", "argc": "0", "argv": []}


def _off_boundary(angle: float, tol: float = 1e-4) -> bool:
    """True when the angle's quadrant survives wire rounding (not at a multiple of 90 deg)."""
    r = float(angle) % (np.pi / 2)
    return min(r, np.pi / 2 - r) > tol


def confdata(robot: Robot, q: Array) -> tuple[int, int, int, int]:
    """[cf1, cf4, cf6, cfx]: quadrants of axes 1, 4, 6 and the branch bits (ABB's table)."""
    quad = [int(np.floor(q[i] / (np.pi / 2) + 1e-12)) if i < len(q) else 0 for i in (0, 3, 5)]
    c = arm_config(robot, q)
    cfx = (0 if c.front else 4) + (0 if c.elbow_up else 2) + (1 if c.wrist_flip else 0)
    return quad[0], quad[1], quad[2], cfx


class RapidController:
    """One motion task (T_ROB1) of an IRC5 with a model arm behind it."""

    def __init__(self, robot: Robot, arm: EmulatedArm, time_scale: float = 1.0):
        self.robot = robot
        self.arm = arm
        self.time_scale = time_scale
        self.lock = threading.RLock()
        self.files: dict[str, bytes] = {}  # KEY (upper case) -> contents
        self.names: dict[str, str] = {}  # KEY -> the path as written
        self.modules: dict[str, tuple[Module, str]] = {}  # NAME -> (module, file key)
        self.pp: int | None = None
        self.entry = "MAIN"  # the routine the program pointer was set to
        self.cycle = "once"
        self.motors_on = True
        self.running = False
        self.outputs: dict[str, float] = {}
        self.elog: list[ElogRecord] = []
        #: Main modules started, in order (tests read it).
        self.runs: list[str] = []
        self._seq = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._tools: dict[bytes, Robot] = {}
        #: Called with "running" / "stopped" on every change (RWS subscriptions).
        self.on_exec_change = lambda state: None
        self.on_log = lambda seqnum: None
        self.put_file(FACTORY_MAIN_PATH, FACTORY_MAIN.encode())
        self.modules["MAINMODULE"] = (parse_module(FACTORY_MAIN), self.key(FACTORY_MAIN_PATH))

    # ------------------------------------------------------------------ event log
    def log(self, msgtype: int, code: int, title: str, desc: str = "") -> None:
        with self.lock:
            self._seq += 1
            now = datetime.datetime.now().strftime("%Y-%m-%d T  %H:%M:%S")
            self.elog.append(ElogRecord(self._seq, msgtype, code, title, desc, now))
            del self.elog[:-200]  # the controller keeps a bounded log too
            seq = self._seq
        self.on_log(seq)

    # ------------------------------------------------------------------ files and modules
    @staticmethod
    def key(path: str) -> str:
        return path.strip("/").upper()

    def put_file(self, path: str, data: bytes) -> bool:
        with self.lock:
            new = self.key(path) not in self.files
            self.files[self.key(path)] = data
            self.names[self.key(path)] = path.strip("/")
            return new

    def load(self, path: str, replace: bool) -> str:
        with self.lock:
            self._idle("load a module")
            data = self.files.get(self.key(path))
            if data is None:
                raise RwsError(400, rp.RC_LOAD_ERROR, f"file {path} not found")
            try:
                mod = parse_module(data.decode("utf-8", errors="replace"))
            except RapidError as exc:
                raise RwsError(400, rp.RC_LOAD_ERROR, f"{path}: {exc}") from None
            name = mod.name.upper()
            if name in self.modules and not replace:
                raise RwsError(400, rp.RC_LOAD_ERROR, f"module {mod.name} is already loaded")
            others = [m for n, (m, _) in self.modules.items() if n != name]
            try:
                Program(others + [mod], self.robot.dof)
            except RapidError as exc:
                raise RwsError(400, rp.RC_LOAD_ERROR, f"{path}: {exc}") from None
            self.modules[name] = (mod, self.key(path))
            self.pp = None
            return mod.name

    def unload(self, name: str) -> None:
        with self.lock:
            self._idle("unload a module")
            if self.modules.pop(name.upper(), None) is None:
                raise RwsError(400, rp.RC_LOAD_ERROR, f"module {name} is not loaded")
            self.pp = None

    def _idle(self, what: str) -> None:
        if self.running:
            raise RwsError(400, rp.RC_RUNNING, f"cannot {what} while the program runs")

    # ------------------------------------------------------------------ execution
    def resetpp(self) -> None:
        with self.lock:
            self._idle("move the program pointer")
            try:
                self._program().steps()  # refuses a task without main
            except RapidError as exc:
                raise RwsError(400, rp.RC_LOAD_ERROR, str(exc)) from None
            self.pp, self.entry = 0, "MAIN"
            self.log(rp.ELOG_INFO, rp.ELOG_PP_RESET, "Program pointer has been reset")

    def set_pp_routine(self, module: str, routine: str) -> None:
        """The program pointer to the first instruction of `routine` in `module`."""
        with self.lock:
            self._idle("move the program pointer")
            mod = self.modules.get(module.upper())
            if mod is None:
                raise RwsError(400, rp.RC_NOT_FOUND, f"module {module} is not loaded")
            if routine.upper() not in mod[0].procs:
                raise RwsError(400, rp.RC_NOT_FOUND, f"no routine {routine} in {module}")
            try:
                self._program().steps(routine)
            except RapidError as exc:
                raise RwsError(400, rp.RC_LOAD_ERROR, str(exc)) from None
            self.pp, self.entry = 0, routine.upper()

    def _program(self) -> Program:
        try:
            return Program([m for m, _ in self.modules.values()], self.robot.dof)
        except RapidError as exc:
            raise RwsError(400, rp.RC_LOAD_ERROR, str(exc)) from None

    def start(self, cycle: str) -> None:
        with self.lock:
            self._idle("start")
            if not self.motors_on:
                raise RwsError(400, rp.RC_MOTORS_OFF, "motors are off")
            if self.pp is None:
                raise RwsError(400, rp.RC_PP_LOST, "program pointer lost: reset it (resetpp)")
            try:
                steps = self._program().steps(self.entry)
            except RapidError as exc:
                raise RwsError(400, rp.RC_LOAD_ERROR, str(exc)) from None
            if cycle != "asis":
                self.cycle = cycle
            main = self._program().procs[self.entry][0]
            self.runs.append(main)
            self.arm.clear_fault()  # the last collision was reported; start = regain
            self._stop.clear()
            self.running = True
            self.on_exec_change("running")
            self.log(rp.ELOG_INFO, rp.ELOG_PROGRAM_STARTED, "Program started", main)
            self._thread = threading.Thread(target=self._run, args=(steps,), daemon=True,
                                            name="rapid-T_ROB1")
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self.arm.stop_all("stopped")
        th = self._thread
        if th is not None and th is not threading.current_thread():
            th.join(timeout=2.0)

    def _run(self, steps: list[Step]) -> None:
        try:
            while True:
                while self.pp is not None and self.pp < len(steps):
                    if self._stop.is_set():
                        raise _Halt
                    self._execute(steps[self.pp])
                    with self.lock:
                        self.pp += 1
                with self.lock:
                    self.pp = 0
                if self.cycle != "forever" or self._stop.is_set():
                    break
                time.sleep(0.01)
        except _Halt:
            pass
        finally:
            with self.lock:
                self.running = False
            self.log(rp.ELOG_INFO, rp.ELOG_PROGRAM_STOPPED, "Program stopped")
            self.on_exec_change("stopped")

    def _execute(self, s: Step) -> None:
        if s.kind == "SETDO":
            with self.lock:
                self.outputs[s.signal] = s.value
            return
        if s.kind == "WAIT":
            if self._stop.wait(s.value / self.time_scale):
                raise _Halt
            return
        start = self.arm.q
        robot = self._with_tool(s.tool)
        if s.kind == "MOVEABSJ":
            assert s.q is not None
            if not self.robot.limits.contains(s.q):
                self._error(rp.ELOG_JOINT_OUT_OF_RANGE, "Joint Out of Range", s, ", ".join(
                    self.robot.limits.violations(s.q, self.robot.joint_names)))
            waypoints = [s.q]
        elif s.kind == "MOVEJ":
            assert s.target is not None
            waypoints = [self._solve(robot, s.wobj @ s.target.T, s.target, start, s)]
        else:
            assert s.target is not None
            T0 = robot.fk(start)
            if s.kind == "MOVEL":
                poses = line_poses(T0, s.wobj @ s.target.T)
            else:
                assert s.via is not None
                try:
                    poses = arc_poses(T0, s.wobj @ s.via.T, s.wobj @ s.target.T)
                except ValueError as exc:
                    self._error(rp.ELOG_OUTSIDE_REACH, "Circle not possible", s, str(exc))
            waypoints = self._cartesian(robot, poses, start, s)
        m = self.arm.enqueue(np.array(waypoints), min(1.0, s.speed_mm_s / 1000.0), s.where)
        outcome = self.arm.wait(m)
        if outcome == "collision":
            info = self.arm.last_collision
            self._error(rp.ELOG_MOTION_SUPERVISION, "Motion supervision", s,
                        info.description if info else "contact")
        if outcome != "reached":
            raise _Halt

    def _error(self, code: int, title: str, s: Step, why: str) -> None:
        self.log(rp.ELOG_ERROR, code, title, f"Task T_ROB1, {s.where}: {s.line} ({why})")
        raise _Halt

    def _with_tool(self, T_tool: Array) -> Robot:
        if np.allclose(T_tool, self.robot.T_flange_tool, atol=1e-9):
            return self.robot
        key = np.round(T_tool, 9).tobytes()
        if key not in self._tools:
            self._tools[key] = self.robot.with_tool(T_tool)
        return self._tools[key]

    def _solve(self, robot: Robot, T: Array, t: RobTarget, seed: Array, s: Step) -> Array:
        def accept(q: Array) -> bool:  # cf1/cf4/cf6: the quadrants the target asks for
            mine = confdata(robot, q)
            return all(a == b for a, b, i in zip(mine[:3], t.conf[:3], (0, 3, 5), strict=True)
                       if i < len(q) and _off_boundary(q[i]))

        q, why = solve_wire_pose(robot, T, seed, accept)
        if q is None:
            self._error(rp.ELOG_OUTSIDE_REACH, "Position outside reach", s, why)
        return q

    def _cartesian(self, robot: Robot, poses: list[Array], seed: Array, s: Step) -> list[Array]:
        out, q = [], seed
        for T in poses:
            qn, why = solve_wire_pose(robot, T, q, lambda c: True, project_tol_rad=np.pi)
            if qn is None or np.max(np.abs(qn - q)) > 0.35:
                self._error(rp.ELOG_OUTSIDE_REACH, "Position outside reach", s,
                            why or "the path passes a singularity")
            out.append(qn)
            q = qn
        return out

    # ------------------------------------------------------------------ RWS views
    def symbol(self, module: str | None, name: str) -> str:
        with self.lock:
            for mod, _ in self.modules.values():
                if module is None or mod.name.upper() == module.upper():
                    hit = mod.data.get(name.upper())
                    if hit is not None:
                        return hit[2]
        raise RwsError(400, rp.RC_NOT_FOUND, f"symbol {name} not found")

    def frame(self, name: str, typ: str) -> Array:
        if name.lower() in ("tool0", "wobj0"):
            return np.eye(4)
        with self.lock:
            prog = self._program()
        try:
            return prog.frame(name, typ)
        except (KeyError, ValueError, IndexError) as exc:
            raise RwsError(400, rp.RC_BAD_REQUEST, f"{typ} {name}: {exc}") from None
