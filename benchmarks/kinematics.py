"""Kinematics benchmark: vectorised batch FK vs a pinocchio per-call loop, closed-form vs
numeric IK. A script, not a test.

    python benchmarks/kinematics.py [--quick]

Batch FK (TCP position + orientation, one core) for the built-in RV-2AJ (`RV2AJ.batch_fk`,
closed form) and a UR5 from example-robot-data (`URDFRobot.batch_fk`, generic numpy chain),
each in float64 and float32, whole array and in chunks, against pinocchio's
`forwardKinematics` + `updateFramePlacement` called once per configuration on the same
configurations (agreement reported). IK: the RV-2AJ's closed form against damped least squares
on the pinocchio model built from the RV-2AJ's own URDF; agreement = FK of every returned
solution equals the target. Timings are the best of a few repeats (the machine is shared).
The last line printed is one JSON object with all figures.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: before numpy is imported

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from assistant.robots.catalog import installed_robot_urdf  # noqa: E402
from assistant.robots.model import BatchPoses, Tool  # noqa: E402
from assistant.robots.rv2aj import RV2AJ  # noqa: E402
from assistant.robots.urdf_robot import URDFRobot  # noqa: E402
from assistant.transforms import rotation_angle  # noqa: E402

TARGET_CONFIGS_PER_S = 5e6


def best_time(fn: Callable[[], object], repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def chunked(fn: Callable[..., BatchPoses], Q: np.ndarray, chunk: int, dtype: type
            ) -> Callable[[], None]:
    def run() -> None:
        for a in range(0, len(Q), chunk):
            fn(Q[a:a + chunk], dtype=dtype)
    return run


def batch_rates(fn: Callable[..., BatchPoses], Q: np.ndarray, repeats: int
                ) -> dict[str, dict[str, float]]:
    """configs/s per dtype for the whole array and a few chunk sizes."""
    out: dict[str, dict[str, float]] = {}
    for dtype in (np.float64, np.float32):
        rates = {"whole": len(Q) / best_time(lambda d=dtype: fn(Q, dtype=d), repeats)}
        for chunk in (16_384, 65_536, 262_144):
            rates[str(chunk)] = len(Q) / best_time(chunked(fn, Q, chunk, dtype), repeats)
        out[np.dtype(dtype).name] = rates
    return out


def pin_loop(model: pin.Model, frame: str, Q: np.ndarray, repeats: int
             ) -> tuple[float, np.ndarray, np.ndarray]:
    """Per-call pinocchio FK of one frame; returns (configs/s, positions, rotations)."""
    data = model.createData()
    fid = model.getFrameId(frame)
    P = np.empty((len(Q), 3))
    R = np.empty((len(Q), 3, 3))

    def run() -> None:
        for i, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            M = pin.updateFramePlacement(model, data, fid)
            P[i] = M.translation
            R[i] = M.rotation

    return len(Q) / best_time(run, repeats), P, R


def fk_section(name: str, fn: Callable[..., BatchPoses], model: pin.Model, frame: str,
               Q: np.ndarray, n_pin: int, repeats: int) -> dict[str, float]:
    rates = batch_rates(fn, Q, repeats)
    pin_rate, P, R = pin_loop(model, frame, Q[:n_pin], max(1, repeats - 1))
    ref = fn(Q[:n_pin])
    f32 = fn(Q[:n_pin], dtype=np.float32)
    diff64 = max(np.abs(ref.positions - P).max(), np.abs(ref.rotations - R).max())
    diff32 = max(np.abs(f32.positions - P).max(), np.abs(f32.rotations - R).max())
    best64 = max(rates["float64"].values())
    best32 = max(rates["float32"].values())
    print(f"\n{name}: batch FK, {len(Q):,} configurations (configs/s, best of {repeats})")
    print(f"  {'dtype':8s}" + "".join(f"{k:>12s}" for k in rates["float64"]))
    for dt, r in rates.items():
        print(f"  {dt:8s}" + "".join(f"{v / 1e6:11.2f}M" for v in r.values()))
    print(f"  pinocchio per-call loop ({n_pin:,} configs): {pin_rate / 1e6:.3f} M/s")
    print(f"  ratio batch/pinocchio: float64 {best64 / pin_rate:.1f}x, "
          f"float32 {best32 / pin_rate:.1f}x")
    print(f"  max |batch - pinocchio|: float64 {diff64:.1e}, float32 {diff32:.1e}")
    key = name.lower().replace("-", "")
    return {
        f"{key}_batch_fk_f64_per_s": round(best64),
        f"{key}_batch_fk_f32_per_s": round(best32),
        f"{key}_best_chunk_f64": max(rates["float64"], key=rates["float64"].get),
        f"{key}_best_chunk_f32": max(rates["float32"], key=rates["float32"].get),
        f"{key}_pin_loop_per_s": round(pin_rate),
        f"{key}_ratio_f64": round(best64 / pin_rate, 2),
        f"{key}_ratio_f32": round(best32 / pin_rate, 2),
        f"{key}_max_diff_f64": float(diff64),
        f"{key}_max_diff_f32": float(diff32),
    }


def pose_ok(robot, q: np.ndarray, T: np.ndarray) -> bool:
    T_q = robot.fk(q)
    return bool(np.linalg.norm(T_q[:3, 3] - T[:3, 3]) < 2e-6
                and rotation_angle(T_q[:3, :3].T @ T[:3, :3]) < 2e-5)


def ik_section(n_targets: int) -> dict[str, float]:
    rv = RV2AJ().with_tool(Tool.straight(0.1))
    numeric = URDFRobot.from_string(rv.urdf(), base_dir=".", tool_link="tool", load_visual=False)
    rng = np.random.default_rng(1)
    Q = rng.uniform(rv.limits.lower, rv.limits.upper, (n_targets, rv.dof))
    t_closed = t_num = t_seeded = 0.0
    ok_closed = ok_num = ok_seeded = agree = 0
    branches_found = branches_total = 0
    for q in Q:
        T = rv.fk(q)
        t = time.perf_counter()
        a = rv.ik(T)
        t_closed += time.perf_counter() - t
        t = time.perf_counter()
        b = numeric.ik(T)
        t_num += time.perf_counter() - t
        t = time.perf_counter()
        c = numeric.ik(T, seed=q + 0.05, max_solutions=1)  # jogging / path following
        t_seeded += time.perf_counter() - t
        ok_closed += a.ok
        ok_num += b.ok
        ok_seeded += c.ok
        sols = a.solutions + b.solutions + c.solutions
        agree += bool(a.ok and b.ok and all(pose_ok(rv, s, T) for s in sols))
        branches_total += len(a.solutions)
        branches_found += sum(any(np.linalg.norm(s - n) < 1e-4 for n in b.solutions)
                              for s in a.solutions)
    n = len(Q)
    print(f"\nRV-2AJ IK, {n} reachable targets (FK of random in-limit configurations)")
    print(f"  closed form : {t_closed / n * 1e3:8.3f} ms/target, solved {ok_closed}/{n}")
    print(f"  numeric DLS : {t_num / n * 1e3:8.3f} ms/target, solved {ok_num}/{n} "
          f"(up to {numeric.ik_settings.max_solutions} solutions, "
          f"{numeric.ik_settings.restarts} restarts)")
    print(f"  numeric, seeded, 1 solution: {t_seeded / n * 1e3:8.3f} ms/target, "
          f"solved {ok_seeded}/{n}")
    print(f"  agreement (every solution's FK = target): {agree}/{n}; closed-form branches "
          f"also found by DLS: {branches_found}/{branches_total}")
    return {
        "ik_targets": n,
        "ik_closed_ms": round(t_closed / n * 1e3, 4),
        "ik_numeric_ms": round(t_num / n * 1e3, 3),
        "ik_numeric_seeded_ms": round(t_seeded / n * 1e3, 3),
        "ik_speedup_closed_vs_numeric": round(t_num / t_closed, 1),
        "ik_closed_solved": ok_closed / n,
        "ik_numeric_solved": ok_num / n,
        "ik_numeric_seeded_solved": ok_seeded / n,
        "ik_agreement": agree / n,
        "ik_branches_found_by_numeric": branches_found / max(1, branches_total),
    }


def ur5_urdf() -> tuple[Path, Path]:
    try:
        return installed_robot_urdf("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    except FileNotFoundError as exc:
        raise SystemExit(str(exc)) from None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes, under a minute")
    args = ap.parse_args()
    n_batch = 1_000_000 if args.quick else 4_000_000
    n_pin = 50_000 if args.quick else 200_000
    repeats = 3 if args.quick else 5
    n_ik = 40 if args.quick else 200
    t0 = time.perf_counter()
    figures: dict[str, object] = {"quick": args.quick, "numpy": np.__version__,
                                  "pinocchio": pin.__version__}

    rv = RV2AJ().with_tool(Tool.straight(0.1))
    rng = np.random.default_rng(0)
    Q = rng.uniform(rv.limits.lower, rv.limits.upper, (n_batch, rv.dof))
    rv_model = pin.buildModelFromXML(rv.urdf())
    figures.update(fk_section("RV-2AJ", rv.batch_fk, rv_model, "tool", Q, n_pin, repeats))

    urdf, share = ur5_urdf()
    ur5 = URDFRobot.from_file(urdf, package_dirs=[share], tool_link="tool0", load_visual=False)
    Q = rng.uniform(ur5.limits.lower, ur5.limits.upper, (n_batch, ur5.dof))
    figures.update(fk_section("UR5", ur5.batch_fk, pin.buildModelFromUrdf(str(urdf)), "tool0",
                              Q, n_pin, repeats))
    del Q

    figures.update(ik_section(n_ik))
    figures["rv2aj_target_5M_f64_met"] = figures["rv2aj_batch_fk_f64_per_s"] >= \
        TARGET_CONFIGS_PER_S
    figures["rv2aj_target_5M_f32_met"] = figures["rv2aj_batch_fk_f32_per_s"] >= \
        TARGET_CONFIGS_PER_S
    figures["seconds"] = round(time.perf_counter() - t0, 1)
    print(f"\nRV-2AJ batch FK: {figures['rv2aj_batch_fk_f64_per_s'] / 1e6:.2f} M/s float64, "
          f"{figures['rv2aj_batch_fk_f32_per_s'] / 1e6:.2f} M/s float32 (target "
          f"{TARGET_CONFIGS_PER_S / 1e6:.0f} M/s); ratio to pinocchio loop "
          f"{figures['rv2aj_ratio_f64']}x / {figures['rv2aj_ratio_f32']}x")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
