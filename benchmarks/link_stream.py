"""Stream a long joint trajectory to the MELFA emulator at the controller cycle; compare with
a naive send-wait-reply loop.

The emulator runs in its own process (as a controller would be another machine) at real
time with the RV-2AJ's datasheet speeds and a 7.1 ms servo cycle. Streaming is
`MelfaLink.move_path` (data link, window of unacknowledged targets, CNT blending on the
controller); the naive loop sends each target by direct execution (``EXEC J=...`` then
``EXEC MOV J``) and waits for the reply before the next - the thesis' "Controller Link"
way. Reported: achieved target rate and the jitter of the inter-command interval (p50, p99,
max) at the sender, the same for the controller's acknowledgements, the tracking error at
the end, and the rate ratio.

    python benchmarks/link_stream.py [--quick] [--targets N]

The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from assistant.links import melfa_protocol as mp  # noqa: E402
from assistant.links.melfa import MelfaLink  # noqa: E402
from assistant.links.timing import time_parametrize  # noqa: E402
from assistant.robots.rv2aj import RV2AJ  # noqa: E402

CYCLE_S = 0.0071


def interval_stats(times: list[float]) -> dict[str, float]:
    d = np.diff(np.asarray(times)) * 1000.0
    if len(d) == 0:
        return {"p50": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {"p50": round(float(np.percentile(d, 50)), 3),
            "p99": round(float(np.percentile(d, 99)), 3),
            "max": round(float(d.max()), 3)}


def rate(times: list[float]) -> float:
    return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else float("nan")


def trajectory(robot: RV2AJ, n_targets: int) -> tuple[np.ndarray, float]:
    """A smooth multi-joint curve and the speed scale that makes it n_targets cycles long."""
    s = np.linspace(0.0, 1.0, 4000)[:, None]
    lo, hi = robot.limits.lower, robot.limits.upper
    mid, amp = (lo + hi) / 2.0, (hi - lo) * 0.3
    freq = np.array([3.0, 5.0, 4.0, 7.0, 6.0]) * n_targets / 5000.0  # ~half full speed
    path = mid + amp * np.sin(2 * np.pi * freq * s + np.arange(5))
    full = time_parametrize(path, robot.limits.velocity).duration
    scale = full / (n_targets * CYCLE_S)
    if scale > 1.0:
        raise SystemExit(f"{n_targets} targets are too few for this curve at full speed")
    return path, scale


def start_emulator(delay_ms: float) -> tuple[subprocess.Popen, int, int]:
    proc = subprocess.Popen([sys.executable, "-m", "assistant.links.emulators.melfa_emulator",
                             "--port", "0", "--datalink-port", "0",
                             "--reply-delay-ms", str(delay_ms)],
                            stdout=subprocess.PIPE, text=True,
                            cwd=str(Path(__file__).resolve().parents[1]))
    line = proc.stdout.readline()
    ports = [int(p) for p in re.findall(r":(\d+)", line)]
    if len(ports) < 2:
        proc.kill()
        raise SystemExit(f"emulator did not start: {line!r}")
    return proc, ports[0], ports[1]


def stop_emulator(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=5.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5.0)
    if proc.stdout is not None:
        proc.stdout.close()


def naive_loop(link: MelfaLink, targets: np.ndarray, speed_pct: int) -> list[float]:
    """Send-wait-reply: assign, move, wait for the controller's reply; then the next."""
    link.set_override(speed_pct)
    sends = []
    for q in targets:
        lit = mp.format_joint_literal(q, link.robot.joint_names)
        link.command(f"EXECJNAIVE={lit}")
        sends.append(time.monotonic())
        link.command("EXECMOV JNAIVE", timeout_s=5.0)
    return sends


def measure(robot: RV2AJ, path: np.ndarray, scale: float, n_naive: int,
            delay_ms: float) -> dict:
    """Stream the path, then run the naive loop over its first targets, at one latency."""
    proc, port, dl_port = start_emulator(delay_ms)
    try:
        link = MelfaLink(robot, port=port, datalink_port=dl_port, stream_cycle_s=CYCLE_S,
                         stream_window=4, timeout_s=2.0)
        link.connect()
        link.move_path(path[:1])  # go to the start (not measured)
        t0 = time.monotonic()
        ev = link.move_path(path, speed_scale=scale)
        wall = time.monotonic() - t0
        if ev.kind.value != "reached":
            raise SystemExit(f"stream ended with {ev.kind.value}: {ev.message}")
        sent, acks = list(link.last_stream_send_times), list(link.last_stream_ack_times)
        err_deg = float(np.degrees(np.max(np.abs(link.current_joints() - path[-1]))))
        targets, _ = time_parametrize(path, robot.limits.velocity, scale).resample(CYCLE_S)
        link.move_path(targets[:1])
        naive = naive_loop(link, targets[1:n_naive + 1], max(1, int(np.ceil(scale * 100))))
        link.close()
    finally:
        stop_emulator(proc)
    return {
        "reply_delay_ms": delay_ms,
        "stream": {"targets": len(sent), "rate_hz": round(rate(sent), 2),
                   "send_interval_ms": interval_stats(sent),
                   "ack_rate_hz": round(rate(acks), 2), "ack_interval_ms": interval_stats(acks),
                   "wall_s": round(wall, 3), "final_error_deg": round(err_deg, 4)},
        "naive": {"targets": len(naive), "rate_hz": round(rate(naive), 2),
                  "send_interval_ms": interval_stats(naive)},
        "rate_ratio": round(rate(sent) / rate(naive), 2),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1000 targets (< 1 min)")
    ap.add_argument("--targets", type=int, default=None)
    ap.add_argument("--latency-ms", type=float, default=5.0,
                    help="second run: the controller answers this late")
    args = ap.parse_args()
    n = args.targets or (1000 if args.quick else 5000)
    n_naive = 150 if args.quick else 500
    robot = RV2AJ()
    path, scale = trajectory(robot, n)
    runs = [measure(robot, path, scale, n_naive, d) for d in (0.0, args.latency_ms)]
    print(f"{'reply delay':>12} {'':14}{'rate Hz':>9}{'p50 ms':>9}{'p99 ms':>9}{'max ms':>9}")
    for r in runs:
        for name, hz, st in (("stream (send)", r["stream"]["rate_hz"],
                              r["stream"]["send_interval_ms"]),
                             ("stream (ack)", r["stream"]["ack_rate_hz"],
                              r["stream"]["ack_interval_ms"]),
                             ("naive", r["naive"]["rate_hz"], r["naive"]["send_interval_ms"])):
            print(f"{r['reply_delay_ms']:10.1f}ms {name:14}{hz:9.1f}{st['p50']:9.2f}"
                  f"{st['p99']:9.2f}{st['max']:9.2f}")
    result = {
        "benchmark": "link_stream",
        "controller_cycle_ms": round(CYCLE_S * 1000.0, 2),
        "ideal_rate_hz": round(1.0 / CYCLE_S, 2),
        "targets": runs[0]["stream"]["targets"],
        "stream_rate_hz": runs[0]["stream"]["rate_hz"],
        "stream_jitter_ms": runs[0]["stream"]["send_interval_ms"],
        "naive_rate_hz": runs[0]["naive"]["rate_hz"],
        "rate_ratio": runs[0]["rate_ratio"],
        f"rate_ratio_at_{args.latency_ms:g}ms_reply_delay": runs[1]["rate_ratio"],
        "runs": runs,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
