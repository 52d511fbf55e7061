"""cellteach KUKA bridge server: the REST side of source 002's bridge, for the controller's
Windows side (KR C4) or a PC next to it that shares the controller's user-file folder.

    python bridge_server.py --channel-dir C:\\KRC\\ROBOTER\\UserFiles --port 8000

One file, Python 3.8+ standard library only (a KR C4's Windows 7 runs Python 3.8 at most).
``POST /krl/<method>`` as in 002 (§4.1.2: ptp, linmov, circ, getpos, base, tcp, gettcp,
uploadfile; query parameters x y z (mm) a b c (deg) s t, aux_x ... for circ, vel in %);
reply ``{"statuscode": 1, "position": [x, y, z, a, b, c], "axes": [a1, ..., a6]}`` (the
axes, in degrees, are ours: 002 reports the pose only). One command at a time (a
lock, 002 Listing 4.1): it is written as one line to ``cellbridge_cmd.txt`` (atomically:
a temporary file renamed over it) with a new command id, the server waits for
``cellbridge_res.txt`` to carry that id (002 Listings 4.4-4.6) and then removes the command
file, so a robot program restarted after a halt never runs a command twice; the KRL program
``cellbridge.src`` runs on the robot and executes it. Unlike 002 the wait has a deadline
(`--timeout`, statuscode -5 with what to check), so a stopped robot program never hangs a
client, and the files are never held open.

``uploadfile`` takes a motion module (.dat then .src, as cellteach's KUKA link sends them)
and runs its PTP / LIN / CIRC (SPL as LIN) one by one through the same actuator: a running
KRL program cannot link a module written after it was selected - which is why 002's
bridge kept running its first upload. Other statements of the module are not executed (the
reply's message says how many motions ran). ``/krl/stop`` is not possible through files
while a motion runs (HTTP 404: stop on the teach pendant).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import random
import re
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlsplit

METHODS = {"ptp": 1, "linmov": 2, "getpos": 3, "base": 6, "circ": 7, "tcp": 8, "gettcp": 9}
PTP_AXES = 12
CMD_FILE, RES_FILE = "cellbridge_cmd.txt", "cellbridge_res.txt"
STATUS_TIMEOUT = -5
STATUS_BAD_REQUEST = -3
STATUS_PROGRAM = -4
_AGG = re.compile(r"\{([^{}]*)\}")
_MOTION = re.compile(r"^\s*(PTP|LIN|SPL|SLIN|SPTP|CIRC)\b\s*(.*)$", re.IGNORECASE)


class Bridge:
    """Writes commands to the channel folder and waits for the robot program's answers."""

    def __init__(self, channel_dir: str, timeout_s: float = 120.0, poll_s: float = 0.01):
        self.dir = channel_dir
        self.timeout_s, self.poll_s = float(timeout_s), float(poll_s)
        self.lock = threading.Lock()
        self._cid = itertools.count(random.randint(1, 1 << 30))  # never 0; KRL INT range

    def _path(self, name: str) -> str:
        return os.path.join(self.dir, name)

    def command(self, method: int, q: dict, timeout_s: float | None = None) -> dict:
        """Run one command; returns the reply dict (statuscode, position, maybe message)."""
        vals, mask = [0.0] * 12, 0
        for i, k in enumerate(("x", "y", "z", "a", "b", "c", "aux_x", "aux_y", "aux_z",
                               "aux_a", "aux_b", "aux_c")):
            if k in q:
                vals[i] = float(q[k])
                mask |= 1 << i
        s = int(q["s"]) if "s" in q else -1
        t = int(q["t"]) if "t" in q else -1
        vel = float(q.get("vel", 0.0))
        with self.lock:
            cid = next(self._cid) % 2000000000 + 1
            line = " ".join([str(cid), str(method), str(mask)]
                            + [f"{v:.6f}" for v in vals[:6]] + [str(s), str(t)]
                            + [f"{v:.6f}" for v in vals[6:]] + [f"{vel:.3f}"]) + "\n"
            self._write(line)
            try:
                return self._wait(cid, self.timeout_s if timeout_s is None else timeout_s)
            finally:
                self._remove()  # answered or given up: a restarted program must not run it

    def _remove(self) -> None:
        deadline = time.monotonic() + 5.0
        while True:
            try:
                os.remove(self._path(CMD_FILE))
                return
            except FileNotFoundError:
                return
            except PermissionError:  # the robot program has it open this instant
                if time.monotonic() > deadline:
                    return
                time.sleep(self.poll_s)

    def _write(self, line: str) -> None:
        tmp = self._path(CMD_FILE + ".tmp")
        deadline = time.monotonic() + 5.0
        while True:
            try:
                with open(tmp, "w", encoding="ascii") as f:
                    f.write(line)
                os.replace(tmp, self._path(CMD_FILE))
                return
            except PermissionError:  # the robot program has it open this instant
                if time.monotonic() > deadline:
                    raise
                time.sleep(self.poll_s)

    def _wait(self, cid: int, timeout_s: float) -> dict:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                with open(self._path(RES_FILE), encoding="ascii", errors="replace") as f:
                    parts = f.readline().split()
            except OSError:
                parts = []
            if len(parts) >= 8 and parts[0] == str(cid):
                try:
                    out = {"statuscode": int(parts[1]),
                           "position": [round(float(v), 6) for v in parts[2:8]]}
                    if len(parts) >= 14:  # cellbridge also reports the axes (degrees)
                        out["axes"] = [round(float(v), 6) for v in parts[8:14]]
                    return out
                except ValueError:
                    pass
            time.sleep(self.poll_s)
        return {"statuscode": STATUS_TIMEOUT, "position": [],
                "message": f"the robot program did not answer command {cid} within "
                           f"{timeout_s:.0f} s: is cellbridge selected and running (AUT or "
                           "EXT, drives on), and is there a message on the teach pendant?"}

    def upload(self, filename: str, data: bytes, store: dict) -> dict:
        stem, _, ext = filename.rpartition(".")
        if not stem or ext.lower() not in ("src", "dat"):
            return {"statuscode": STATUS_PROGRAM, "position": [],
                    "message": f"{filename!r} is not a .src or .dat file"}
        store[f"{stem.upper()}.{ext.lower()}"] = data.decode("utf-8", errors="replace")
        if ext.lower() == "dat":
            return {**self.command(METHODS["getpos"], {}), "program": stem}
        try:
            motions = parse_motions(store[f"{stem.upper()}.src"],
                                    parse_points(store.get(f"{stem.upper()}.dat", "")))
        except ValueError as exc:
            return {"statuscode": STATUS_PROGRAM, "position": [], "message": str(exc)}
        reply = self.command(METHODS["getpos"], {})
        for n, (kind, target, aux) in enumerate(motions, start=1):
            reply = self.command(*_as_command(kind, target, aux))
            if reply["statuscode"] != 1:
                reply["message"] = (f"{stem}: motion {n} of {len(motions)} ended with "
                                    f"statuscode {reply['statuscode']}"
                                    + (f" ({reply['message']})" if "message" in reply else ""))
                break
        reply["program"] = stem
        reply.setdefault("message", f"{stem}: {len(motions)} motions run by the bridge")
        return reply


def _as_command(kind: str, target: dict, aux: dict | None) -> tuple[int, dict]:
    if any(k.startswith("A") and k[1:].isdigit() for k in target):
        q = {k: target[f"A{i}"] for i, k in enumerate("xyzabc", start=1) if f"A{i}" in target}
        return PTP_AXES, q
    q = {k.lower(): target[k] for k in ("X", "Y", "Z", "A", "B", "C") if k in target}
    if kind == "PTP":
        q.update({k.lower(): int(target[k]) for k in ("S", "T") if k in target})
        return METHODS["ptp"], q
    if kind == "CIRC" and aux is not None:
        q.update({f"aux_{k.lower()}": aux[k] for k in ("X", "Y", "Z", "A", "B", "C") if k in aux})
        return METHODS["circ"], q
    return METHODS["linmov"], q


def parse_aggregate(text: str) -> dict:
    out = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        m = re.fullmatch(r"([A-Za-z]\w*)\s+(.+)", item)
        if not m:
            raise ValueError(f"bad aggregate item {item!r}")
        val = m.group(2).strip()
        b = re.fullmatch(r"'B([01]+)'", val)
        out[m.group(1).upper()] = float(int(b.group(1), 2)) if b else float(val)
    return out


def parse_points(dat: str) -> dict:
    return {m.group(1).upper(): parse_aggregate(m.group(2)) for m in re.finditer(
        r"DECL\s+(?:E6POS|POS|E6AXIS|AXIS|FRAME)\s+(\w+)\s*=\s*\{([^{}]*)\}", dat, re.I)}


def parse_motions(src: str, points: dict) -> list:
    """(kind, target, aux) of each motion statement; SPL/SLIN are run as LIN, SPTP as PTP."""
    out = []
    for no, raw in enumerate(src.splitlines(), start=1):
        m = _MOTION.match(raw.split(";", 1)[0])
        if not m:
            continue
        kw, rest = m.group(1).upper(), m.group(2)
        kind = {"SPL": "LIN", "SLIN": "LIN", "SPTP": "PTP"}.get(kw, kw)
        aggs = [parse_aggregate(a) for a in _AGG.findall(rest)]
        for name in re.findall(r"(?<![\w{])([A-Za-z_]\w*)(?![\w}])", _AGG.sub(" ", rest)):
            if name.upper() in ("C_PTP", "C_DIS", "C_VEL", "C_ORI", "C_SPL", "CA"):
                continue
            if name.upper() not in points:
                raise ValueError(f"line {no}: unknown point {name}")
            aggs.append(points[name.upper()])
        need = 2 if kind == "CIRC" else 1
        if len(aggs) < need:
            raise ValueError(f"line {no}: {kw} needs {need} point(s)")
        out.append((kind, aggs[-1], aggs[0] if kind == "CIRC" else None))
    if not out:
        raise ValueError("no motion statement in the module")
    return out


def _multipart(body: bytes, ctype: str) -> tuple[str, bytes] | None:
    m = re.search(r"boundary=\"?([^\";]+)\"?", ctype)
    if not m:
        return None
    for part in body.split(b"--" + m.group(1).encode())[1:]:
        head, _, data = part.partition(b"\r\n\r\n")
        fm = re.search(rb'name="file"; filename="([^"]*)"', head)
        if fm:
            return fm.group(1).decode(), data[:-2] if data.endswith(b"\r\n") else data
    return None


def make_server(host: str, port: int, bridge: Bridge) -> ThreadingHTTPServer:
    uploads: dict = {}

    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"
        timeout = 30.0

        def log_message(self, *args: object) -> None:
            return

        def _reply(self, code: int, payload: dict) -> None:
            data = json.dumps(payload).encode()
            self.send_response(code)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def do_GET(self) -> None:  # noqa: N802 (http.server naming)
            self._reply(405, {"detail": "the bridge accepts POST only"})

        def do_POST(self) -> None:  # noqa: N802
            url = urlsplit(self.path)
            body = self.rfile.read(int(self.headers.get("Content-Length") or 0))
            parts = url.path.strip("/").split("/")
            name = parts[1] if len(parts) == 2 and parts[0] == "krl" else ""
            q = {k: v[-1] for k, v in parse_qs(url.query).items()}
            if name == "uploadfile":
                got = _multipart(body, self.headers.get("Content-Type", ""))
                if got is None:
                    self._reply(200, {"statuscode": STATUS_BAD_REQUEST, "position": [],
                                      "message": "multipart field 'file' missing"})
                    return
                self._reply(200, bridge.upload(got[0], got[1], uploads))
                return
            if name not in METHODS:
                self._reply(404, {"detail": "Not Found" if name != "stop" else
                                  "stop is not possible through File KRL while a motion "
                                  "runs: stop on the teach pendant"})
                return
            try:
                self._reply(200, bridge.command(METHODS[name], q))
            except ValueError as exc:
                self._reply(200, {"statuscode": STATUS_BAD_REQUEST, "position": [],
                                  "message": str(exc)})

    class Server(ThreadingHTTPServer):
        daemon_threads = True
        allow_reuse_address = True

    return Server((host, port), Handler)


def main(argv: list | None = None) -> None:
    ap = argparse.ArgumentParser(description="cellteach KUKA bridge server (File KRL)")
    ap.add_argument("--channel-dir", required=True,
                    help="the folder cellbridge.src reads and writes: on the KR C4 "
                         r"C:\KRC\ROBOTER\UserFiles, from a PC its shared folder")
    ap.add_argument("--host", default="0.0.0.0")
    ap.add_argument("--port", type=int, default=8000)
    ap.add_argument("--timeout", type=float, default=120.0,
                    help="longest wait for the robot program's answer, s (default 120)")
    args = ap.parse_args(argv)
    srv = make_server(args.host, args.port, Bridge(args.channel_dir, args.timeout))
    print(f"cellteach KUKA bridge on http://{args.host}:{srv.server_address[1]}/krl/ "
          f"(channel {args.channel_dir}); Ctrl-C to stop", flush=True)
    try:
        srv.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        srv.server_close()


if __name__ == "__main__":
    main()
