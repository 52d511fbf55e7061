"""Big CAD imports: time and peak memory of `load_cad` on generated binary STLs.

Two shapes matter: one finely subdivided closed surface (a torus), and many small separate
parts (cubes, every fourth with an open top, so the hole fill has components to look at).
Each measurement runs in its own process so its peak RSS is its own.

    python benchmarks/cad_import.py [--faces 20000 200000 2000000] [--kinds surface parts]

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


def write_binary_stl(path: Path, triangles: np.ndarray) -> None:
    """(N, 3, 3) corners -> a binary STL (normals left zero: readers recompute them)."""
    rec = np.zeros(len(triangles), dtype=_STL_DTYPE)
    rec["v"] = triangles
    with open(path, "wb") as f:
        f.write(b"cellteach generated".ljust(80, b" "))
        f.write(np.uint32(len(triangles)).tobytes())
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


def make_stl(kind: str, faces: int, folder: Path) -> Path:
    tri = torus_triangles(faces) if kind == "surface" else cubes_triangles(faces)
    path = folder / f"{kind}_{faces}.stl"
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
    t0 = time.perf_counter()
    out: dict = {"file": path.name, "mbytes": path.stat().st_size / 2**20}
    try:
        cad = load_cad_path(path)
        out.update(ok=True, faces_display=len(cad.mesh.faces), proxy=cad.proxy.kind,
                   proxy_faces=cad.proxy.faces, proxy_parts=cad.proxy.parts,
                   bounded=list(getattr(cad, "bounded", ())), summary=cad.summary())
    except CadImportError as exc:
        out.update(ok=False, error=str(exc))
    out["seconds"] = time.perf_counter() - t0
    out["peak_rss_mb"] = _peak_rss_mb()
    out["rss_before_mb"] = rss0
    return out


def measure_in_subprocess(path: Path, timeout: float = 300.0) -> dict:
    """`measure_here` in a fresh interpreter (its own peak RSS); killed after `timeout`."""
    here = str(Path(__file__).parent)
    code = (f"import json,sys; sys.path.insert(0, {here!r}); from cad_import import "
            f"measure_here; from pathlib import Path; "
            f"print(json.dumps(measure_here(Path({str(path)!r}))))")
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faces", type=int, nargs="+", default=[20_000, 200_000, 2_000_000])
    ap.add_argument("--kinds", nargs="+", default=["surface", "parts"])
    ap.add_argument("--timeout", type=float, default=300.0)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in args.kinds:
            for n in args.faces:
                path = make_stl(kind, n, Path(tmp))
                r = measure_in_subprocess(path, args.timeout)
                r.pop("summary", None)
                r["kind"] = kind
                rows.append(r)
                print(f"{kind:8s} {n:>9,d} faces: {r.get('seconds', 0):6.1f} s, "
                      f"{r.get('peak_rss_mb', float('nan')):7.0f} MB peak, "
                      f"{'ok ' + str(r.get('proxy')) if r.get('ok') else r.get('error')}",
                      flush=True)
                path.unlink()
    print(json.dumps({"imports": rows}))


if __name__ == "__main__":
    main()
