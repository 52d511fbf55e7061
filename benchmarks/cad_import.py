"""Big CAD imports: time, peak memory and collision-proxy deviation of `load_cad`, beside a peer.

Parts are generated as binary STLs (nothing large is committed): a *fixture* (a block with
grooves milled into two faces, tessellated finely as CAD tools export at default settings:
concave, so it gets the decimated proxy), a torus (*surface*: one finely subdivided closed
body) and many small separate cubes (*parts*: every fourth with an open top, so the hole fill
has work). Each import runs in its own process so its peak RSS (VmHWM) is its own.

The peer is what a plain trimesh integration does: `trimesh.load` (merging vertices) and
`simplify_quadric_decimation` to the same 20 000 triangles, no repair, no bound; its proxy is
measured afterwards with our bound, so "outside" says how far its part sticks out of the
proxy the collision checks would use (not covered by any margin there).

    python benchmarks/cad_import.py [--faces 2000000 10000000] [--kinds fixture] [--no-peer]

The last line is one JSON object with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_STL_DTYPE = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
#: The peer gets this much address space: beyond it, it is reported as out of memory
#: instead of pushing the shared machine into swap.
PEER_MEMORY_LIMIT = 8 * 2**30


def write_binary_stl(path: Path, triangles: np.ndarray, chunk: int = 1_000_000) -> None:
    """(N, 3, 3) corners -> a binary STL (normals left zero: readers recompute them)."""
    with open(path, "wb") as f:
        f.write(b"cellteach generated".ljust(80, b" "))
        f.write(np.uint32(len(triangles)).tobytes())
        for k in range(0, len(triangles), chunk):
            rec = np.zeros(min(chunk, len(triangles) - k), dtype=_STL_DTYPE)
            rec["v"] = triangles[k:k + chunk]
            f.write(rec.tobytes())


def torus_triangles(faces: int, R: float = 300.0, r: float = 100.0) -> np.ndarray:
    """A closed torus (millimetres) of about `faces` triangles: one finely subdivided body."""
    n = max(3, int(round(np.sqrt(faces / 2))))
    m = max(3, int(round(faces / (2 * n))))
    u = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = np.linspace(0, 2 * np.pi, m, endpoint=False)
    U, V = np.meshgrid(u, v, indexing="ij")
    P = np.stack([(R + r * np.cos(V)) * np.cos(U), (R + r * np.cos(V)) * np.sin(U),
                  r * np.sin(V)], axis=-1)
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    a, b = P[i, j], P[(i + 1) % n, j]
    c, d = P[(i + 1) % n, (j + 1) % m], P[i, (j + 1) % m]
    t1 = np.stack([a, b, c], axis=-2).reshape(-1, 3, 3)
    t2 = np.stack([a, c, d], axis=-2).reshape(-1, 3, 3)
    return np.concatenate([t1, t2])


_CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                    [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float)
_CUBE_F = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                    [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7], [4, 5, 6], [4, 6, 7]])


def cubes_triangles(faces: int, edge: float = 4.0, pitch: float = 6.0) -> np.ndarray:
    """Many separate small cubes (millimetres), every fourth without its top (a 4-edge hole)."""
    tri = _CUBE_V[_CUBE_F] * edge  # (12, 3, 3)
    n = max(1, faces // 12)
    k = int(np.ceil(n ** (1 / 3)))
    idx = np.arange(n)
    offs = np.stack([idx % k, (idx // k) % k, idx // (k * k)], axis=1) * pitch
    all_t = tri[None] + offs[:, None, None, :]
    open_top = (idx % 4) == 3
    keep = np.ones((n, 12), dtype=bool)
    keep[open_top, 10:] = False
    return all_t[keep]


def fixture_triangles(faces: int, size=(400.0, 60.0, 250.0), depth: float = 15.0,
                      grooves: int = 5, dtype=np.float32) -> np.ndarray:
    """A closed block (millimetres, centred on the origin) with `grooves` rounded grooves
    `depth` deep milled along x into its -y and +y faces, every face a grid of equal cells
    (two triangles each), about `faces` triangles in all: concave, like a fixture plate."""
    a, b, c = size
    area = 2 * (a * b + b * c + c * a)
    h = np.sqrt(2 * area / faces)
    na, nb, nc = (max(2, int(round(s / h))) for s in size)
    xs, ys, zs = (np.linspace(-s / 2, s / 2, n + 1) for s, n in zip(size, (na, nb, nc),
                                                                     strict=True))
    out = []

    def grid(P: np.ndarray, flip: bool) -> None:
        """Two triangles per cell of the point grid P (nu+1, nv+1, 3), wound outward."""
        p00, p10, p11, p01 = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
        t1, t2 = (p00, p10, p11), (p00, p11, p01)
        if flip:
            t1, t2 = (p00, p11, p10), (p00, p01, p11)
        for t in (t1, t2):
            out.append(np.stack(t, axis=-2).reshape(-1, 3, 3).astype(dtype))

    X, Z = np.meshgrid(xs, zs, indexing="ij")
    s, t = (X + a / 2) / a, (Z + c / 2) / c
    dent = depth * np.sin(np.pi * s) * np.sin(np.pi * t) * 0.5 * (
        1 - np.cos(2 * np.pi * grooves * t))
    for sign in (-1.0, 1.0):  # the grooved faces, y = +-(b/2 - dent)
        grid(np.stack([X, sign * (b / 2 - dent), Z], axis=-1), flip=sign > 0)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    for sign in (-1.0, 1.0):  # top and bottom
        grid(np.stack([X, Y, np.full_like(X, sign * c / 2)], axis=-1), flip=sign < 0)
    Y, Z = np.meshgrid(ys, zs, indexing="ij")
    for sign in (-1.0, 1.0):  # the ends
        grid(np.stack([np.full_like(Y, sign * a / 2), Y, Z], axis=-1), flip=sign < 0)
    return np.concatenate(out)


def make_stl(kind: str, faces: int, folder: Path) -> Path:
    path = folder / f"{kind}_{faces}.stl"
    if kind == "fixture":
        write_binary_stl(path, fixture_triangles(faces))
        return path
    tri = torus_triangles(faces) if kind == "surface" else cubes_triangles(faces)
    write_binary_stl(path, tri.astype(np.float32))
    return path


def _peak_rss_mb() -> float:
    """This process's peak RSS: VmHWM (reset by exec, unlike ru_maxrss, which a child
    started from a big parent inherits), else getrusage."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def measure_here(path: Path) -> dict:
    """Import one file in this process; time, peak RSS and what the import reported."""
    from assistant.cell.cad import CadImportError, load_cad_path

    rss0 = _peak_rss_mb()
    t0, c0 = time.perf_counter(), time.process_time()
    out: dict = {"file": path.name, "mbytes": path.stat().st_size / 2**20}
    try:
        cad = load_cad_path(path)
        out.update(ok=True, faces=len(cad.mesh.faces),
                   faces_display=len(cad.display_mesh.faces), proxy=cad.proxy.kind,
                   proxy_faces=cad.proxy.faces, proxy_parts=cad.proxy.parts,
                   outside_mm=cad.proxy.margin_m * 1000.0,
                   outside_at_vertices_mm=cad.proxy.outside_at_vertices_m * 1000.0,
                   margin_mm=max(s.margin for s in cad.collision) * 1000.0,
                   deviation_mm=cad.proxy.deviation_m * 1000.0,
                   bounded=list(cad.bounded), summary=cad.summary())
    except CadImportError as exc:
        out.update(ok=False, error=str(exc))
    out["seconds"] = time.perf_counter() - t0
    out["cpu_seconds"] = time.process_time() - c0  # what it costs on an idle machine
    out["peak_rss_mb"] = _peak_rss_mb()
    out["rss_before_mb"] = rss0
    return out


def measure_peer_here(path: Path) -> dict:
    """The peer: trimesh's loader (vertices merged) and quadric decimation to 20 000
    triangles; then, untimed, how far the part lies outside that proxy (our bound)."""
    import trimesh

    from assistant.cell.cad.outside import outside_bound

    rss0 = _peak_rss_mb()
    t0, c0 = time.perf_counter(), time.process_time()
    out: dict = {"file": path.name}
    try:
        mesh = trimesh.load(str(path), force="mesh")
        proxy = mesh.simplify_quadric_decimation(face_count=20_000)
        out["seconds"] = time.perf_counter() - t0
        out["cpu_seconds"] = time.process_time() - c0
        out["peak_rss_mb"] = _peak_rss_mb()
        bound = outside_bound(mesh.vertices, mesh.faces, (proxy,), convex=False)
        # the peer keeps the file's numbers: millimetres for the parts generated here
        out.update(ok=True, faces=len(mesh.faces), proxy_faces=len(proxy.faces),
                   outside_mm=bound.distance_m, margin_mm=0.0)
    except MemoryError:
        out.update(ok=False, error=f"out of memory (limit {PEER_MEMORY_LIMIT / 2**30:.0f} GiB)",
                   seconds=time.perf_counter() - t0, peak_rss_mb=_peak_rss_mb())
    out["rss_before_mb"] = rss0
    return out


def _run(function: str, path: Path, timeout: float, limit: int | None = None) -> dict:
    """`function(path)` of this module in a fresh interpreter; killed after `timeout`."""
    here = str(Path(__file__).parent)
    code = (f"import json,sys; sys.path.insert(0, {here!r}); import resource; "
            + (f"resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit})); " if limit else "")
            + f"from cad_import import {function}; from pathlib import Path; "
            f"print(json.dumps({function}(Path({str(path)!r}))))")
    env = dict(os.environ, OMP_NUM_THREADS="1")
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"file": path.name, "ok": False, "error": f"killed after {timeout:.0f} s",
                "seconds": time.perf_counter() - t0}
    if p.returncode != 0:
        return {"file": path.name, "ok": False, "error": p.stderr[-2000:],
                "seconds": time.perf_counter() - t0}
    return json.loads(p.stdout.strip().splitlines()[-1])


def measure_in_subprocess(path: Path, timeout: float = 300.0) -> dict:
    """`measure_here` in a fresh interpreter (its own peak RSS); killed after `timeout`."""
    return _run("measure_here", path, timeout)


def measure_peer_in_subprocess(path: Path, timeout: float = 600.0) -> dict:
    return _run("measure_peer_here", path, timeout, PEER_MEMORY_LIMIT)


def _line(who: str, kind: str, n: int, r: dict) -> str:
    what = (f"ok {r.get('proxy', 'decimated')}, part outside the proxy by "
            f"{r.get('outside_mm', float('nan')):.2f} mm, margin {r.get('margin_mm', 0):.2f} mm"
            if r.get("ok") else str(r.get("error", ""))[:160])
    return (f"{who:5s} {kind:8s} {n:>11,d} triangles: {r.get('seconds', 0):6.1f} s "
            f"({r.get('cpu_seconds', float('nan')):.1f} s CPU), "
            f"{r.get('peak_rss_mb', float('nan')):7.0f} MB peak, {what}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faces", type=int, nargs="+", default=[2_000_000, 10_000_000])
    ap.add_argument("--kinds", nargs="+", default=["fixture"],
                    choices=["fixture", "surface", "parts"])
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--no-peer", action="store_true", help="measure our import only")
    args = ap.parse_args()
    rows = []
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for kind in args.kinds:
            for n in args.faces:
                path = make_stl(kind, n, Path(tmp))
                ours = measure_in_subprocess(path, args.timeout)
                ours.pop("summary", None)
                row = {"kind": kind, "triangles": n, "ours": ours}
                print(_line("ours", kind, n, ours), flush=True)
                if not args.no_peer:
                    row["peer"] = measure_peer_in_subprocess(path, args.timeout)
                    print(_line("peer", kind, n, row["peer"]), flush=True)
                rows.append(row)
                path.unlink()
    print(json.dumps({"imports": rows, "load_average_1min_at_start": load,
                      "cpus": os.cpu_count()}))


if __name__ == "__main__":
    main()
