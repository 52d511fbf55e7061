"""Predicted cycle time of a neutral program: every move time-parametrised under the limits.

A prediction, not a measurement: no controller is here to compare with, and every vendor's
interpolator is proprietary. What it models, so the figure can be judged:

- **Joint moves** (PTP/MOV/MoveJ/movej) go straight in joint space, all axes starting and
  ending together, as controllers interpolate them: one `ruckig` profile (jerk-limited,
  time-optimal, phase-synchronised) from rest to rest; speed limit = `Move.speed` x the
  robot's joint speeds, acceleration and jerk from `CycleTimeLimits`.
- **Cartesian moves** (lines, arcs, splines) run along the TCP path as a controller's CP
  interpolator does: one 1-D `ruckig` profile over the TCP arc length, its speed capped by
  the programmed TCP speed, by the robot's joint speeds along the path (dq/ds from the dense
  joint path of `simulate`) and by the joint accelerations the path's curvature needs at
  cruise speed. Why not `toppra`: it rides joint limits time-optimally (not what a CP
  interpolator does at a programmed speed), is not jerk-limited, takes 50-100 ms a move
  and imports matplotlib (2-8 s); on the thesis program both agree within 2 % per move
  at 0.1 and at 1 m/s (acceleration-limited profiles compared).
- **Speeds**: a move without a speed keeps the previous one of its kind (as OVRD/SPD/
  $VEL stay set); the first joint move without one runs at full speed, a Cartesian move
  without one is refused. `Move.acceleration` scales joint and TCP accelerations alike.
  A Cartesian move that only turns the tool is timed like a joint move at full speed.
- **Blends**: consecutive Cartesian moves joined by a blend (blend_radius > 0, nothing in
  between) pass the junction at a speed: the lower of both moves' caps, at a corner
  (> `CORNER_ANGLE`) at most sqrt(a r) (the centripetal limit on a blend arc of radius r),
  lowered until both profiles stay within their moves. A blend at a joint move saves the time
  the two stop-to-stop profiles spend within r of the junction minus the time to cross 2r at
  the slower boundary speed ("subtract the blend time"). Blends are not taken across a
  gripper action, output or wait (controllers stop there).
- **Waits** add their seconds, a gripper action `CycleTimeLimits.gripper_s`, an output
  `output_s`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from assistant.export.errors import ExportError
from assistant.export.program import (
    Comment,
    Gripper,
    Move,
    MoveKind,
    NeutralProgram,
    SetOutput,
    Wait,
)
from assistant.export.simulate import Simulation, simulate
from assistant.robots.model import Robot
from assistant.transforms import angle_between

Array = np.ndarray

#: Junctions turning more than this (rad) are corners: the blend arc limits the speed.
CORNER_ANGLE = math.radians(5.0)
#: Shown wherever the figure is: it is not a measurement.
CAVEAT = "a prediction, not measured on a controller"


@dataclass(frozen=True)
class CycleTimeLimits:
    """Acceleration/jerk limits (not in URDFs nor the RV-2AJ datasheet) and fixed times.

    Defaults: every joint reaches its full speed in 1/`acceleration_factor` = 0.25 s and its
    full acceleration in 1/`jerk_factor` = 0.1 s, typical of small industrial arms; the TCP
    accelerates at 2 m/s^2 with the same 0.1 s ramp. Per-joint values (rad/s^2, rad/s^3)
    override the factors. `jerk_factor=None` gives acceleration-limited (trapezoid) profiles.
    """

    acceleration_factor: float = 4.0  # a_max = k * v_max per joint (1/s)
    jerk_factor: float | None = 10.0  # j_max = k * a_max per joint (1/s)
    #: rad/s per joint where a dialect's controller runs slower than the robot's own joint
    #: speeds (URScript's movej: every joint at most the leading axis' speed); never above
    #: the robot's
    velocity: tuple[float, ...] | None = None
    acceleration: tuple[float, ...] | None = None  # rad/s^2 per joint, overrides the factor
    jerk: tuple[float, ...] | None = None  # rad/s^3 per joint, overrides the factor
    tcp_acceleration: float = 2.0  # m/s^2, Cartesian moves
    tcp_jerk: float | None = 20.0  # m/s^3, Cartesian moves
    gripper_s: float = 0.3  # an assumption: open/close until the fingers settle
    output_s: float = 0.0  # setting an output costs one interpreter cycle: negligible
    #: TCP step (m) of the joint path sampled for the speed caps of Cartesian moves.
    path_step: float = 0.01

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            vals = v if isinstance(v, tuple) else (v,)
            for x in vals:
                if x is None and f.name in ("jerk_factor", "tcp_jerk", "acceleration", "jerk",
                                            "velocity"):
                    continue
                if not isinstance(x, (int, float)) or not math.isfinite(x) or x < 0 or (
                        x == 0 and f.name not in ("gripper_s", "output_s")):
                    raise ExportError(f"cycle time limit {f.name} = {v!r}: give a finite "
                                      "positive number")

    def joint_limits(self, robot: Robot) -> tuple[Array, Array, Array]:
        """(v, a, j) per joint; `ExportError` for a robot without usable speed limits."""
        n = robot.dof
        v = np.asarray(getattr(getattr(robot, "limits", None), "velocity", np.zeros(0)),
                       dtype=float).reshape(-1)
        if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
            raise ExportError(f"robot {robot.name!r} has no joint speed limits for all its "
                              f"{n} joints (got {v.tolist()} rad/s): the cycle time cannot be "
                              "predicted; give each joint a <limit velocity> in rad/s")
        v = np.minimum(v, self._per_joint(self.velocity, "velocity", n, v))
        a = self._per_joint(self.acceleration, "acceleration", n, v * self.acceleration_factor)
        j_default = np.full(n, np.inf) if self.jerk_factor is None else a * self.jerk_factor
        j = self._per_joint(self.jerk, "jerk", n, j_default)
        return v, a, j

    @staticmethod
    def _per_joint(given: tuple[float, ...] | None, what: str, n: int, default: Array) -> Array:
        if given is None:
            return default
        if len(given) != n:
            raise ExportError(f"cycle time limit {what}: {len(given)} values for {n} joints")
        return np.asarray(given, dtype=float)


@dataclass(frozen=True)
class StepTime:
    """The predicted time of one timed instruction (a move, wait, gripper action, output)."""

    index: int  # position in the program's instructions
    step: str
    kind: str  # MoveKind value, "wait", "gripper" or "output"
    seconds: float
    target: str = ""  # the move's target position


@dataclass(frozen=True)
class CycleTime:
    entries: tuple[StepTime, ...]
    total_s: float
    limits: CycleTimeLimits = field(default_factory=CycleTimeLimits)
    #: Wall time the prediction took (s); not part of the result's meaning.
    compute_s: float = 0.0

    def describe(self) -> str:
        return (f"predicted cycle time {self.total_s:.1f} s (from joint speed/acceleration "
                f"limits; {CAVEAT})")

    def header_text(self) -> str:
        """The one comment line a dialect writes in the program header."""
        return f"predicted cycle time {self.total_s:.1f} s ({CAVEAT})"

    def moves_s(self) -> float:
        return sum(e.seconds for e in self.entries if e.kind in _MOVE_KINDS)

    def by_step(self) -> list[tuple[str, float]]:
        """Seconds per mission step, in program order (consecutive entries of one step)."""
        out: list[tuple[str, float]] = []
        for e in self.entries:
            if out and out[-1][0] == e.step:
                out[-1] = (e.step, out[-1][1] + e.seconds)
            else:
                out.append((e.step, e.seconds))
        return out

    def assumptions(self) -> list[str]:
        lim = self.limits
        return [CAVEAT,
                "joint speeds: the robot's own" if lim.velocity is None else
                "joint speeds as the controller runs them (" + ", ".join(
                    f"{np.degrees(v):.0f}" for v in lim.velocity) + " deg/s)",
                f"joint acceleration {lim.acceleration_factor:g} x speed limit per second"
                if lim.acceleration is None else "joint accelerations given per joint",
                "no jerk limit" if lim.jerk_factor is None and lim.jerk is None else
                f"jerk {lim.jerk_factor:g} x acceleration limit per second"
                if lim.jerk is None else "jerk given per joint",
                f"TCP acceleration {lim.tcp_acceleration:g} m/s^2",
                f"gripper action {lim.gripper_s:g} s", f"output {lim.output_s:g} s"]

    def to_json(self) -> dict:
        return {"predicted_cycle_time_s": round(self.total_s, 3),
                "moves": [{"index": e.index, "step": e.step, "kind": e.kind,
                           "target": e.target, "seconds": round(e.seconds, 3)}
                          for e in self.entries],
                "assumptions": self.assumptions()}


_MOVE_KINDS = {k.value for k in MoveKind}


# ============================================================================ prediction
@dataclass
class ProfiledMove:
    """One move on its way to a profile."""

    ins_index: int
    move: Move
    tcp: Array
    q: Array
    length: float  # TCP arc length (m)
    v: Array | float  # joint speed limits (joint) or TCP speed cap (Cartesian)
    a: Array | float
    j: Array | float
    cartesian: bool
    u_end: float = 0.0  # junction speed into the next move (Cartesian blends)
    seconds: float = 0.0
    ell_t: tuple[Array, Array] | None = None  # (t, TCP arc length) samples
    sigma_t: tuple[Array, Array] | None = None  # (t, joint-path fraction): joint moves

    def sample_times(self) -> Array:
        """Time (s from the move's start) at which the arm passes each of the move's samples
        `q`, on the move's profile; a blend's saving shortens the move evenly."""
        n = len(self.q)
        if n < 2 or self.seconds <= 0.0:
            return np.zeros(n)
        if self.cartesian and self.ell_t is not None:
            t, e = self.ell_t
            ell = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.tcp, axis=0), axis=1))]
            out = np.interp(ell, np.maximum.accumulate(e), t)
        elif self.sigma_t is not None:
            t, sig = self.sigma_t
            dq = self.q[-1] - self.q[0]
            axis = int(np.argmax(np.abs(dq)))
            frac = np.clip((self.q[:, axis] - self.q[0, axis]) / dq[axis], 0.0, 1.0)
            out = np.interp(frac, np.maximum.accumulate(sig), t)
        else:
            out = np.linspace(0.0, self.seconds, n)
        full = float(out[-1])
        out = out * (self.seconds / full) if full > 0.0 else np.linspace(0.0, self.seconds, n)
        out[0], out[-1] = 0.0, self.seconds
        return np.maximum.accumulate(out)


def predict_cycle_time(program: NeutralProgram, robot: Robot,
                       limits: CycleTimeLimits | None = None, *,
                       simulation: Simulation | None = None) -> CycleTime:
    """Per-instruction and total predicted time of `program` (as a dialect writes it).

    `simulation`: the program's dense joint paths when the caller has them (`check_program`
    returns them), else they are simulated here every `limits.path_step`.

    Raises:
        ExportError naming the step for a non-finite or non-positive value, a robot without
        joint speed limits, or a path the kinematics cannot follow.
    """
    t_start = time.perf_counter()
    lim = limits or CycleTimeLimits()
    segs = profiled_moves(program, robot, lim, simulation=simulation)
    entries = _entries(program, segs, lim)
    total = float(sum(e.seconds for e in entries))
    return CycleTime(tuple(entries), total, lim, time.perf_counter() - t_start)


def profiled_moves(program: NeutralProgram, robot: Robot, lim: CycleTimeLimits, *,
                   simulation: Simulation | None = None) -> list[ProfiledMove]:
    """Every move of `program` with its time profile: what `predict_cycle_time` sums, and
    what the simulated robot follows to run at the program's pace (`pace.py`)."""
    v_max, a_max, j_max = lim.joint_limits(robot)
    _check_program(program)
    sim = simulation or simulate(program, _path_follower(robot), max_step=lim.path_step)
    if len(sim.moves) != len(program.moves()):
        raise ExportError("the simulation given is not this program's")
    segs: list[ProfiledMove] = []
    speed_j, speed_c, accel = 1.0, None, 1.0
    moves = program.moves()
    ins_index = [i for i, ins in enumerate(program.instructions) if isinstance(ins, Move)]
    for k, (m, sm) in enumerate(zip(moves, sim.moves, strict=True)):
        accel = accel if m.acceleration is None else m.acceleration
        length = float(np.sum(np.linalg.norm(np.diff(sm.tcp, axis=0), axis=1)))
        cart = m.kind != MoveKind.JOINT and length > 1e-6
        if m.kind == MoveKind.JOINT:
            speed_j = speed_j if m.speed is None else m.speed
        else:
            speed_c = speed_c if m.speed is None else m.speed
        if cart:
            if speed_c is None:
                raise ExportError("a Cartesian move without a programmed speed", step=m.step)
            cap = min(speed_c, _joint_speed_cap(sm.q, sm.tcp, v_max, a_max * accel))
            j_tcp = math.inf if lim.tcp_jerk is None else lim.tcp_jerk
            segs.append(ProfiledMove(ins_index[k], m, sm.tcp, sm.q, length, cap,
                                     lim.tcp_acceleration * accel, j_tcp, True))
        else:  # joint moves; Cartesian moves that only turn the tool are timed like them
            sj = speed_j if m.kind == MoveKind.JOINT else 1.0
            segs.append(ProfiledMove(ins_index[k], m, sm.tcp, sm.q, length, v_max * sj,
                                     a_max * accel, j_max, False))
    _junction_speeds(program, segs)
    _cartesian_profiles(segs)
    for s in segs:
        if not s.cartesian:
            _joint_profile(s)
    _joint_blends(program, segs)
    return segs


def _path_follower(robot: Robot) -> Robot:
    """The robot with numerical IK run from the previous sample only (no random restarts).

    Along a continuous path the previous sample's solution is the seed the branch continues
    from; restarts only find other branches, which the simulation discards. 60x faster on a
    UR5, the same joint path.
    """
    settings = getattr(robot, "ik_settings", None)
    if settings is None or not hasattr(robot, "with_ik_settings"):
        return robot
    return robot.with_ik_settings(dataclasses.replace(settings, restarts=0, extra_restarts=0,
                                                      max_solutions=1))


def _check_program(program: NeutralProgram) -> None:
    def finite(x, what: str, step: str, *, positive: bool = False, zero_ok: bool = True):
        if x is None:
            return
        a = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(a)):
            raise ExportError(f"{what} is not a finite number ({x!r}): no cycle time", step=step)
        if positive and np.any(a <= 0) or not zero_ok and np.any(a < 0):
            raise ExportError(f"{what} must be positive (got {x!r})", step=step)

    for ins in program.instructions:
        step = getattr(ins, "step", "")
        if isinstance(ins, Move):
            finite(ins.speed, "speed", step, positive=True)
            finite(ins.acceleration, "acceleration", step, positive=True)
            finite(ins.blend_radius, "blend radius", step, zero_ok=False)
            if ins.kind == MoveKind.JOINT and ins.speed is not None and ins.speed > 1.0:
                raise ExportError(f"joint speed {ins.speed:g} is more than the maximum (1.0)",
                                  step=step)
            if ins.acceleration is not None and ins.acceleration > 1.0:
                raise ExportError(f"acceleration {ins.acceleration:g} is more than the "
                                  "maximum (1.0)", step=step)
            for p in ins.positions():
                finite(p.T_base_tool, f"position {p.name!r}", step)
                finite(p.q, f"joints of position {p.name!r}", step)
        elif isinstance(ins, Wait):
            finite(ins.seconds, "wait", step, zero_ok=False)
    finite(program.q_start, "start posture", "")


def _joint_speed_cap(q: Array, tcp: Array, v: Array, a: Array) -> float:
    """Highest TCP speed (m/s) at which no joint exceeds its speed, nor the acceleration the
    path's curvature needs at constant speed (q'' v^2), anywhere on the sampled path."""
    ds = np.linalg.norm(np.diff(tcp, axis=0), axis=1)
    ok = ds > 1e-9
    if not np.any(ok):
        return math.inf
    dq = np.abs(np.diff(q, axis=0))[ok] / ds[ok, None]  # |dq/ds| per segment
    with np.errstate(divide="ignore"):
        cap = float(np.min(v[None, :] / np.maximum(dq, 1e-12)))
    if int(np.sum(ok)) >= 2:
        qp = np.diff(q, axis=0)[ok] / ds[ok, None]
        mid = 0.5 * (ds[ok][1:] + ds[ok][:-1])
        qpp = np.abs(np.diff(qp, axis=0)) / mid[:, None]
        cap = min(cap, float(np.min(np.sqrt(a[None, :] / np.maximum(qpp, 1e-12)))))
    return cap


def _junction_speeds(program: NeutralProgram, segs: list[ProfiledMove]) -> None:
    """Speeds (m/s) at which blended Cartesian moves pass into the next one."""
    for k in range(len(segs) - 1):
        a, b = segs[k], segs[k + 1]
        r = a.move.blend_radius
        if r <= 0 or not (a.cartesian and b.cartesian) or not _adjacent(program, a, b):
            continue
        u = min(float(a.v), float(b.v))
        if _turn(a.tcp, b.tcp) > CORNER_ANGLE:
            r_eff = min(r, a.length / 2.0, b.length / 2.0)
            u = min(u, math.sqrt(min(float(a.a), float(b.a)) * r_eff))
        a.u_end = u


def _adjacent(program: NeutralProgram, a: ProfiledMove, b: ProfiledMove) -> bool:
    """Nothing but comments between the two moves (a gripper action or wait stops the arm)."""
    between = program.instructions[a.ins_index + 1:b.ins_index]
    return all(isinstance(i, Comment) for i in between)


def _turn(tcp_a: Array, tcp_b: Array) -> float:
    da = tcp_a[-1] - tcp_a[max(0, len(tcp_a) - 3)]
    db = tcp_b[min(2, len(tcp_b) - 1)] - tcp_b[0]
    na, nb = float(np.linalg.norm(da)), float(np.linalg.norm(db))
    if na < 1e-12 or nb < 1e-12:
        return math.pi
    return angle_between(da, db)


def _ruckig(p0: Array, p1: Array, v: Array, a: Array, j: Array, *, v0: float = 0.0,
            v1: float = 0.0, step: str = "") -> Trajectory:
    n = len(p0)
    otg, inp, traj = Ruckig(n), InputParameter(n), Trajectory(n)
    inp.current_position, inp.target_position = list(map(float, p0)), list(map(float, p1))
    if n == 1:
        inp.current_velocity, inp.target_velocity = [float(v0)], [float(v1)]
    inp.max_velocity = list(map(float, v))
    inp.max_acceleration = list(map(float, a))
    inp.max_jerk = list(map(float, j))
    inp.synchronization = Synchronization.Phase
    res = otg.calculate(inp, traj)
    if res not in (Result.Working, Result.Finished):
        raise ExportError(f"no time profile for this move under the limits ({res.name})",
                          step=step)
    return traj


def _sample(traj: Trajectory, axis: int, n: int = 64) -> tuple[Array, Array]:
    t = np.linspace(0.0, traj.duration, n)
    return t, np.array([traj.at_time(float(x))[0][axis] for x in t])


def _cartesian_profiles(segs: list[ProfiledMove]) -> None:
    """1-D profiles along each Cartesian move; junction speeds lowered until every profile
    stays inside its move (no overshoot past the junction, no backing up)."""
    cart = [k for k, s in enumerate(segs) if s.cartesian]
    trajs: dict[int, Trajectory] = {}
    for _ in range(60):
        bad = False
        for k in cart:
            s = segs[k]
            u0 = segs[k - 1].u_end if k > 0 and segs[k - 1].cartesian else 0.0
            traj = _ruckig([0.0], [s.length], [s.v], [s.a], [s.j], v0=u0, v1=s.u_end,
                           step=s.move.step)
            ext = traj.position_extrema[0]
            over, back = ext.max > s.length + 1e-9, ext.min < -1e-9
            if over or back:
                # Past the end: it came in too fast to slow down; before the start: it needs
                # a run-up to leave as fast as asked. Lower the offending junction speed.
                bad = True
                lower_start = (over and u0 > 0) or (back and s.u_end == 0)
                if lower_start and k > 0:
                    segs[k - 1].u_end *= 0.7
                else:
                    s.u_end *= 0.7
                continue
            trajs[k] = traj
        if not bad:
            break
    else:  # did not settle: every blended junction from rest
        for k in cart:
            segs[k].u_end = 0.0
        _cartesian_profiles(segs)
        return
    for k in cart:
        segs[k].seconds = trajs[k].duration
        segs[k].ell_t = _sample(trajs[k], 0)


def _joint_profile(s: ProfiledMove) -> None:
    q0, q1 = s.q[0], s.q[-1]
    dq = q1 - q0
    if float(np.max(np.abs(dq))) < 1e-12:
        s.seconds, s.ell_t = 0.0, (np.zeros(2), np.zeros(2))
        return
    traj = _ruckig(q0, q1, s.v, s.a, s.j, step=s.move.step)
    s.seconds = traj.duration
    # Phase synchronisation: every joint follows one profile sigma(t) along the straight
    # joint path; the TCP arc length follows from the simulated samples (uniform in sigma).
    axis = int(np.argmax(np.abs(dq)))
    t, p = _sample(traj, axis)
    sigma = np.clip((p - q0[axis]) / dq[axis], 0.0, 1.0)
    s.sigma_t = (t, sigma)
    ell = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(s.tcp, axis=0), axis=1))]
    s.ell_t = (t, np.interp(sigma, np.linspace(0.0, 1.0, len(ell)), ell))


def _joint_blends(program: NeutralProgram, segs: list[ProfiledMove]) -> None:
    """Blends at joint moves: subtract the time saved within the blend zone (module doc)."""
    for k in range(len(segs) - 1):
        a, b = segs[k], segs[k + 1]
        r = a.move.blend_radius
        if r <= 0 or (a.cartesian and b.cartesian) or not _adjacent(program, a, b):
            continue
        r_eff = min(r, a.length / 2.0, b.length / 2.0)
        if r_eff <= 1e-9 or a.ell_t is None or b.ell_t is None:
            continue
        ta, va = _time_at(a.ell_t, a.length - r_eff)
        tb, vb = _time_at(b.ell_t, r_eff)
        v_pass = min(va, vb)
        if v_pass <= 1e-9:
            continue
        saved = (a.seconds - ta) + tb - 2.0 * r_eff / v_pass
        a.seconds -= max(0.0, min(saved, a.seconds))


def _time_at(ell_t: tuple[Array, Array], ell: float) -> tuple[float, float]:
    """Time at which the TCP has covered `ell` along the move, and its speed there."""
    t, e = ell_t
    e = np.maximum.accumulate(e)
    ti = float(np.interp(ell, e, t))
    speed = np.gradient(e, t) if len(t) > 1 and t[-1] > 0 else np.zeros_like(t)
    return ti, float(np.interp(ti, t, speed))


def _entries(program: NeutralProgram, segs: list[ProfiledMove],
             lim: CycleTimeLimits) -> list[StepTime]:
    by_index = {s.ins_index: s for s in segs}
    out: list[StepTime] = []
    for i, ins in enumerate(program.instructions):
        if isinstance(ins, Move):
            s = by_index[i]
            out.append(StepTime(i, ins.step, ins.kind.value, s.seconds, ins.target.name))
        elif isinstance(ins, Wait):
            out.append(StepTime(i, ins.step, "wait", float(ins.seconds)))
        elif isinstance(ins, Gripper):
            out.append(StepTime(i, ins.step, "gripper", lim.gripper_s))
        elif isinstance(ins, SetOutput):
            out.append(StepTime(i, ins.step, "output", lim.output_s))
    return out
