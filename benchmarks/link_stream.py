"""Link streams against our emulators: the MELFA joint stream, and the UR state stream.

MELFA: stream a long joint trajectory to the MELFA emulator at the controller cycle; compare
with a naive send-wait-reply loop. The emulator runs in its own process (as a controller
would be another machine) at real time with the RV-2AJ's datasheet speeds and a 7.1 ms servo
cycle. Streaming is `MelfaLink.move_path` (data link, window of unacknowledged targets, CNT
blending on the controller); the naive loop sends each target by direct execution (``EXEC
J=...`` then ``EXEC MOV J``) and waits for the reply before the next - the thesis'
"Controller Link" way. Reported: achieved target rate and the jitter of the inter-command
interval (p50, p99, max) at the sender, the same for the controller's acknowledgements, the
tracking error at the end, and the rate ratio.

UR: the UR emulator (UR5 model, its own process) streams RTDE at 500 Hz while the arm moves;
our `URLink`'s RTDE client and ur-rtde's `RTDEReceiveInterface` (UR's well-kept C++ client,
in a process of its own) read it in turn for the same time. Both are sampled the same way -
a Python loop noting when a new state becomes visible to the caller - and ours also records
each package's arrival in its reader thread. Reported per client: achieved rate, intervals
p50/p99/max, packages more than 1.5 periods apart, and the emulator's own send intervals
(from the controller timestamps).

    python benchmarks/link_stream.py [--quick] [--targets N] [--link melfa|ur|both]

The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import threading
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
    proc = subprocess.Popen([sys.executable, "-m", "assistant.emulators.melfa_emulator",
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


# ---------------------------------------------------------------------- UR (RTDE state)
RTDE_HZ = 500.0
UR_HOST = "127.0.0.91"  # a loopback address of its own: ur-rtde's RTDE port is fixed (30004)

UR_PEER = """
import json, sys, time
import rtde_receive
r = rtde_receive.RTDEReceiveInterface(sys.argv[1], float(sys.argv[2]),
                                      ["timestamp", "actual_q", "actual_TCP_pose",
                                       "robot_mode", "safety_mode"])
seen, stamps, last = [], [], None
end = time.monotonic() + float(sys.argv[3])
while time.monotonic() < end:
    ts = r.getTimestamp()
    if ts != last:
        seen.append(time.monotonic())
        stamps.append(ts)
        last = ts
        q = r.getActualQ()
    time.sleep(0.0001)
r.disconnect()
print(json.dumps({"seen": seen, "stamps": stamps}))
"""


def stream_stats(times: list[float], period_s: float) -> dict:
    d = np.diff(np.asarray(times))
    return {"packages": len(times), "rate_hz": round(rate(times), 2),
            "interval_ms": interval_stats(times),
            "late_pct": round(100.0 * float(np.mean(d > 1.5 * period_s)), 3) if len(d) else None}


def poll_visible(get_stamp, seconds: float) -> tuple[list[float], list[float]]:
    """When a new state becomes visible to a polling caller (the same loop for both)."""
    seen, stamps, last = [], [], None
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        ts = get_stamp()
        if ts != last:
            seen.append(time.monotonic())
            stamps.append(ts)
            last = ts
        time.sleep(0.0001)
    return seen, stamps


def start_ur_emulator() -> tuple[subprocess.Popen, dict[str, int]]:
    proc = subprocess.Popen([sys.executable, "-m", "assistant.emulators.ur_emulator",
                             "--host", UR_HOST, "--rtde-port", "30004", "--script-port", "0",
                             "--dashboard-port", "0"], stdout=subprocess.PIPE, text=True,
                            cwd=str(Path(__file__).resolve().parents[1]))
    line = proc.stdout.readline()
    ports = dict(re.findall(r"(rtde|script|dashboard) :(\d+)", line))
    if len(ports) != 3:
        proc.kill()
        raise SystemExit(f"UR emulator did not start: {line!r}")
    return proc, {k: int(v) for k, v in ports.items()}


def measure_ur(seconds: float) -> dict:
    """Our RTDE client, then ur-rtde's, each `seconds` long while the arm sweeps."""
    from assistant.links.ur import URLink
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.urdf_robot import URDFRobot

    urdf, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    robot = URDFRobot.from_file(urdf, package_dirs=[share], load_visual=False)
    period = 1.0 / RTDE_HZ
    proc, ports = start_ur_emulator()
    try:
        link = URLink(robot, host=UR_HOST, script_port=ports["script"],
                      rtde_port=ports["rtde"], dashboard_port=ports["dashboard"],
                      rtde_hz=RTDE_HZ, timeout_s=1.0, keep_arrivals=200_000)
        link.connect()
        q0 = link.current_joints()
        q1 = q0 + np.array([1.2, 0.3, -0.4, 0.5, 0.6, 0.8])
        sweep = np.array([q0, q1, q0, q1, q0])
        # The arm moves through both windows: a slow back and forth (on its own thread).
        mover = threading.Thread(target=link.move_path, args=(sweep,),
                                 kwargs={"speed_scale": 0.05})
        mover.start()
        link.rtde.arrivals.clear()
        ours_seen, ours_stamps = poll_visible(lambda: link.rtde.latest().seq, seconds)
        arrivals = list(link.rtde.arrivals)
        peer = subprocess.run([sys.executable, "-c", UR_PEER, UR_HOST, str(RTDE_HZ),
                               str(seconds)], capture_output=True, text=True,
                              timeout=seconds + 60.0)
        if peer.returncode != 0:
            raise SystemExit(f"ur-rtde peer failed: {peer.stderr[-1000:]}")
        theirs = json.loads(peer.stdout.strip().splitlines()[-1])
        link.stop()
        mover.join(timeout=10.0)
        link.close()
    finally:
        stop_emulator(proc)
    ours_ctrl = [ts for _, ts in arrivals]
    return {
        "requested_hz": RTDE_HZ, "seconds": seconds,
        "load_average_1min": round(os.getloadavg()[0], 2),  # 2 shared cores: say how busy
        "ours_reader": stream_stats([t for t, _ in arrivals], period),
        "ours_visible": stream_stats(ours_seen, period),
        "ur_rtde_visible": stream_stats(theirs["seen"], period),
        "emulator_send_interval_ms_ours": interval_stats(ours_ctrl),
        "emulator_send_interval_ms_ur_rtde": interval_stats(theirs["stamps"]),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1000 targets, 3 s of RTDE (< 1 min)")
    ap.add_argument("--targets", type=int, default=None)
    ap.add_argument("--latency-ms", type=float, default=5.0,
                    help="second MELFA run: the controller answers this late")
    ap.add_argument("--link", choices=("melfa", "ur", "both"), default="both")
    ap.add_argument("--ur-seconds", type=float, default=None,
                    help="how long each UR client reads the stream (default 10, quick 3)")
    args = ap.parse_args()
    result: dict = {"benchmark": "link_stream"}
    if args.link in ("melfa", "both"):
        result.update(run_melfa(args))
    if args.link in ("ur", "both"):
        ur = measure_ur(args.ur_seconds or (3.0 if args.quick else 10.0))
        print(f"{'UR RTDE ' + str(int(RTDE_HZ)) + ' Hz':24}{'rate Hz':>9}{'p50 ms':>9}"
              f"{'p99 ms':>9}{'max ms':>9}{'late %':>8}")
        for name in ("ours_reader", "ours_visible", "ur_rtde_visible"):
            st = ur[name]
            iv = st["interval_ms"]
            print(f"{name:24}{st['rate_hz']:9.1f}{iv['p50']:9.2f}{iv['p99']:9.2f}"
                  f"{iv['max']:9.2f}{st['late_pct']:8.2f}")
        result["ur"] = ur
        result["ur_rate_hz"] = ur["ours_reader"]["rate_hz"]
        result["ur_jitter_ms"] = ur["ours_reader"]["interval_ms"]
        result["ur_rtde_rate_hz"] = ur["ur_rtde_visible"]["rate_hz"]
    print(json.dumps(result))


def run_melfa(args: argparse.Namespace) -> dict:
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
    return {
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


if __name__ == "__main__":
    main()
