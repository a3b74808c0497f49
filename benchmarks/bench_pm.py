"""Speed of the progressive mesh: build (encode) time and full decode records/s, new code beside old.

Meshes: the catalogue's bunny and igea, and igea after one midpoint subdivision (1,074,744 faces, the
mesh of bench_scale.py). Each measurement runs in a fresh subprocess of this script (``--worker``):
this checkout's code, and the old code with PYTHONPATH=<--old> (default ../main/core beside the
checkout), alternately, best of ``--repeat``. The anchor is fast_simplification.simplify decimating
the same arrays to the same vertex count, timed in the same worker. On bunny and igea the first worker
of each code also measures the levels of detail: the surface distance to the input of the base mesh and
of the level ending nearest half the records (``metrics.surface_distance``, seed 0). Whole processes
(``pmwm embed`` against fast-simplification, the issue's anchor) are timed by bench_core.py only.

With ``--numba-python PY`` (an interpreter with numba and numpy installed, e.g. a scratch venv), the
section adds the numba probe behind the choice of pure numpy: two kernels of one encoder pass on igea
(every corner's collapse cost with each vertex's cheapest, and one 2-ring minimum step) compiled with
numba, beside the same work in this checkout's numpy code; import, compile and cached-load times in
fresh processes.

With ``--numba-wheels DIR`` it lists the numba and llvmlite wheels found under DIR (one folder per
platform and Python, as fetched by ``pip download --no-deps --only-binary=:all: --platform P
--python-version V --implementation cp numba llvmlite -d DIR/V-P``) with their sizes: what the Blender
extension zip would have to carry.

Run: OMP_NUM_THREADS=1 python benchmarks/bench_pm.py [--old PATH] [--repeat 3] [--decode-repeat 10]
[--numba-python PY] [--numba-wheels DIR]
Writes the "pm-speed" section of the report (its fragment in benchmarks/results/).
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import ROOT, command, commit, load, machine, write_section  # noqa: E402

BASE_RATIO = 0.03  # the embedders' default base ratio
LOD_SAMPLES = 20000  # surface samples each way for the levels' distances
NUMBA_PROBE = r"""
import json, sys, time
t0 = time.perf_counter()
import numpy as np
import numba
from numba import njit
t1 = time.perf_counter()
cache = sys.argv[2] == "cache"

@njit(cache=cache)
def costs_and_best(F, Q, V, E, go, locked, bvert, bnd, cost, best):
    best[:] = np.inf
    for f in range(F.shape[0]):
        for j in range(3):
            a = F[f, j]
            b = F[f, (j + 1) % 3]
            x, y, z = V[b, 0], V[b, 1], V[b, 2]
            q = Q[a]
            c = (q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x + q[4] * y * y
                 + 2 * q[5] * y * z + 2 * q[6] * y + q[7] * z * z + 2 * q[8] * z + q[9]) + E[b]
            if not go[a] or locked[b] or bnd[f, j] != bvert[a]:
                c = np.inf
            cost[f, j] = c
            if c < best[a]:
                best[a] = c

@njit(cache=cache)
def ring_min(F, val, out):
    out[:] = val
    for f in range(F.shape[0]):
        mn = min(val[F[f, 0]], val[F[f, 1]], val[F[f, 2]])
        for j in range(3):
            if mn < out[F[f, j]]:
                out[F[f, j]] = mn

d = np.load(sys.argv[1])
V, F = d["V"], d["F"]
n = len(V)
rng = np.random.default_rng(0)
Q, E = rng.random((n, 10)), np.zeros(n)
go, locked, bvert = np.ones(n, bool), np.zeros(n, bool), np.zeros(n, bool)
bnd, cost, best = np.zeros(F.shape, bool), np.empty(F.shape), np.empty(n)
val, out = rng.permutation(n), np.empty(n, np.int64)
t2 = time.perf_counter()
costs_and_best(F, Q, V, E, go, locked, bvert, bnd, cost, best)
ring_min(F, val, out)
t3 = time.perf_counter()
runs = []
for _ in range(5):
    s = time.perf_counter()
    costs_and_best(F, Q, V, E, go, locked, bvert, bnd, cost, best)
    ring_min(F, val, out)
    runs.append(time.perf_counter() - s)
print(json.dumps({"numba": numba.__version__, "numpy": np.__version__, "python": sys.version.split()[0],
                  "import_s": t1 - t0, "first_call_s": t3 - t2, "run_s": min(runs)}))
"""
NEW_CORE = ROOT / "core"
OLD_CORE = ROOT.parent / "main" / "core"


def worker(mesh: str, repeat: int, kernels: bool, decode_repeat: int = 10, lod: bool = False) -> None:
    """Time build_progressive_mesh, a full decode and fast_simplification on ``mesh`` (an .npz); with
    ``lod``, also the surface distance of the base mesh and of a middle level to the input."""
    import numpy as np

    import pmwm
    from pmwm.adjacency import build_adjacency
    from pmwm.progressive import build_progressive_mesh

    data = np.load(mesh)
    V, F = data["V"], data["F"]
    adj = build_adjacency(F, len(V))  # the embedders pass theirs: not part of the PM build
    base_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    base = max(int(round(BASE_RATIO * len(V))), 4)
    build = []
    for _ in range(repeat):
        t = time.perf_counter()
        pm, _ = build_progressive_mesh(V, F, base_vertices=base, adjacency=adj)
        build.append(time.perf_counter() - t)
    dec = []
    for _ in range(decode_repeat):  # a decode takes milliseconds: more runs, less noise
        t = time.perf_counter()
        pm.decode()
        dec.append(time.perf_counter() - t)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # mesh, adjacency, PM build, decode
    fs = []
    try:
        import fast_simplification

        for _ in range(repeat):
            t = time.perf_counter()
            fast_simplification.simplify(V.astype(np.float32), F.astype(np.int32), target_reduction=1 - base / len(V))
            fs.append(time.perf_counter() - t)
    except ImportError:
        pass
    out = {
        "build_s": min(build),
        "decode_s": min(dec),
        "records": pm.n_records,
        "levels": len(pm.level_records),
        "fs_s": min(fs) if fs else None,
        "version": pmwm.__file__,
        "peak_mb": peak_mb,
        "base_mb": base_mb,
    }
    out["kernels_s"] = numpy_kernels(V, F, adj) if kernels else None  # after the peak memory was read
    out["lod"] = lod_distances(V, F, pm) if lod else None
    print(json.dumps(out))


def lod_distances(V, F, pm) -> list:
    """[vertices, MRMS %, Hausdorff %] of the base mesh and of the level ending nearest half the
    records, against the input (``metrics.surface_distance``, LOD_SAMPLES points each way, seed 0)."""
    import numpy as np

    from pmwm.metrics import surface_distance

    lr = pm.level_records
    mid = int(lr[np.argmin(np.abs(lr - pm.n_records / 2))])
    out = []
    for k in (0, mid):
        Vd, Fd = pm.decode(k)
        out.append([len(Vd), *surface_distance(V, F, Vd, Fd, n_samples=LOD_SAMPLES, seed=0)])
    return out


def numpy_kernels(V, F, adj) -> "float | None":
    """The numba probe's two kernels in this code's numpy (None for code without them): every corner's
    collapse cost with each vertex's cheapest (``collapse_costs``, with its set-up of the encoder's
    state), and one 1-ring minimum step (``ring_minimum``, the selection's); best of 5."""
    import numpy as np

    try:
        from pmwm.progressive.build import collapse_costs
        from pmwm.progressive.state import ring_minimum
    except ImportError:
        return None
    n = len(V)
    rng = np.random.default_rng(0)
    Q = rng.random((n, 10))
    val = np.r_[rng.permutation(n), n]
    runs = []
    for _ in range(5):
        t = time.perf_counter()
        collapse_costs(V, F, Q)
        ring_minimum(F, val)
        runs.append(time.perf_counter() - t)
    return min(runs)


def numba_probe(py: str, mesh: str) -> list:
    """Three fresh processes of ``py`` running NUMBA_PROBE: no cache, cache cold (compiles), cache warm."""
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        script = os.path.join(tmp, "numba_probe.py")  # numba caches only functions defined in a file
        Path(script).write_text(NUMBA_PROBE)
        env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "cache"))
        for mode in ("nocache", "cache", "cache"):
            res = subprocess.run([py, script, mesh, mode], env=env, check=True, capture_output=True, text=True).stdout
            out.append(json.loads(res.strip().splitlines()[-1]))
    return out


def run_worker(
    core: Path, mesh: str, repeat: int, kernels: bool = False, decode_repeat: int = 10, lod: bool = False
) -> dict:
    env = dict(os.environ, PYTHONPATH=str(core))
    cmd = [sys.executable, __file__, "--worker", mesh, "--repeat", str(repeat), "--decode-repeat", str(decode_repeat)]
    cmd += ["--kernels"] if kernels else []
    cmd += ["--lod"] if lod else []
    out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def best(a: dict, b: dict) -> dict:
    """Two runs of the same code merged: the smaller time, the larger peak memory, a value over None."""
    out = {}
    for k in a:
        x, y = a[k], b[k]
        if x is None or y is None:
            out[k] = y if x is None else x
        elif k in ("peak_mb", "base_mb"):
            out[k] = max(x, y)
        else:
            out[k] = min(x, y) if isinstance(x, float) else x
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--worker")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--kernels", action="store_true", help="(worker) also time the numba probe's kernels in numpy")
    ap.add_argument("--decode-repeat", type=int, default=10, help="full decodes per worker (the best counts)")
    ap.add_argument("--lod", action="store_true", help="(worker) also measure the levels' surface distances")
    ap.add_argument("--old", default=str(OLD_CORE), help="the old code's core/ folder (skipped if absent)")
    ap.add_argument("--numba-python", help="an interpreter with numba, for the numba probe")
    ap.add_argument("--numba-wheels", help="a folder of downloaded numba/llvmlite wheels, to list their sizes")
    a = ap.parse_args()
    if a.worker:
        worker(a.worker, a.repeat, a.kernels, a.decode_repeat, a.lod)
        return
    import numpy as np

    from pmwm.attacks import subdivide

    old = Path(a.old) if Path(a.old, "pmwm").is_dir() else None
    rows = []
    probe = None
    with tempfile.TemporaryDirectory() as tmp:
        meshes = {"bunny": load("bunny"), "igea": load("igea")}
        meshes["igea x4 (1M faces)"] = subdivide(*meshes["igea"], scheme="midpoint")
        for name, (V, F) in meshes.items():
            path = os.path.join(tmp, "m.npz")
            np.savez(path, V=np.asarray(V, np.float64), F=np.asarray(F, np.int64))
            rep = 1 if len(F) > 500_000 else a.repeat
            # alternate new and old, twice, so that both see the same machine load
            dr = a.decode_repeat
            lod = len(F) <= 500_000  # the levels' distances on bunny and igea (deterministic: one run each)
            new = run_worker(NEW_CORE, path, rep, decode_repeat=dr, lod=lod)
            was = run_worker(old, path, rep, decode_repeat=dr, lod=lod) if old else None
            new = best(new, run_worker(NEW_CORE, path, rep, kernels=name == "igea", decode_repeat=dr))
            if old:
                was = best(was, run_worker(old, path, rep, decode_repeat=dr))
            rows.append((name, len(V), len(F), new, was))
            if name == "igea" and a.numba_python:
                probe = numba_probe(a.numba_python, path)

    def ms(x):
        return "–" if x is None else f"{x * 1000:,.0f} ms"

    lines = [
        "## Progressive mesh speed",
        "",
        f"Command: `OMP_NUM_THREADS=1 {command()}` at commit {commit()}. Machine: {machine()}.",
        f"Old code: {old if old else 'not found'} (its own commit). The machine was shared: each figure is the",
        "best of repeated runs in fresh processes, new and old alternating; compare ratios rather than seconds.",
        "",
        f"PM build = `build_progressive_mesh` to {BASE_RATIO:.0%} of the vertices (the embedders' default), "
        f"adjacency given (the embedders pass theirs). Full decode = `pm.decode()` (every record), best of "
        f"{a.decode_repeat} per worker, records per second. Anchor: `fast_simplification.simplify` to the same "
        "vertex count on the same arrays. Memory: the growth of the worker's peak RSS over the mesh and its "
        "adjacency, through the PM builds and decodes (before the anchor runs).",
        "",
        "| mesh | vertices | faces | PM build new | old | speed-up | fast_simplification | new / anchor "
        "| levels new (old) | full decode new | old | PM build + decode: peak RSS growth new (old) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, nv, nf, new, was in rows:
        sp = f"{was['build_s'] / new['build_s']:.1f}x" if was else "–"
        anchor = f"{new['build_s'] / new['fs_s']:.1f}x" if new["fs_s"] else "–"
        dec_new = new["records"] / new["decode_s"] / 1e6
        dec_old = f"{was['records'] / was['decode_s'] / 1e6:.2f} M/s" if was else "–"
        lv_old = was["levels"] if was else "–"
        mem_old = f"{was['peak_mb'] - was['base_mb']:,.0f}" if was else "–"
        lines.append(
            f"| {name} | {nv:,} | {nf:,} | {ms(new['build_s'])} | {ms(was['build_s'] if was else None)} | {sp} "
            f"| {ms(new['fs_s'])} | {anchor} | {new['levels']} ({lv_old}) | {dec_new:.2f} M/s | {dec_old} "
            f"| +{new['peak_mb'] - new['base_mb']:,.0f} MB (+{mem_old} MB) |"
        )
    lod_rows = [(name, new, was) for name, _, _, new, was in rows if new.get("lod")]
    if lod_rows:
        lines += [
            "",
            f"Levels of detail against the input (`metrics.surface_distance`, {LOD_SAMPLES:,} samples each way, "
            "seed 0): MRMS % / Hausdorff % of the bounding-box diagonal, for the base mesh and for the level "
            "ending nearest half the records (its vertex count beside it).",
            "",
            "| mesh | base new | base old | middle level new | middle level old |",
            "|---|---|---|---|---|",
        ]

        def dist(x):
            return f"{x[1]:.4f} / {x[2]:.3f} ({x[0]:,} v)"

        for name, new, was in lod_rows:
            old_lod = was.get("lod") if was else None
            lines.append(
                f"| {name} | {dist(new['lod'][0])} | {dist(old_lod[0]) if old_lod else '–'} "
                f"| {dist(new['lod'][1])} | {dist(old_lod[1]) if old_lod else '–'} |"
            )
    if probe:
        cold, first, warm = probe
        igea_new = next(r[3] for r in rows if r[0] == "igea")
        lines += [
            "",
            f"Numba probe (why the encoder stays numpy): numba {cold['numba']}, numpy {cold['numpy']}, Python "
            f"{cold['python']}, igea. The same two kernels (all corners' collapse costs with each vertex's "
            "cheapest; one 2-ring minimum step):",
            "",
            "| numba run | numpy run (this code) | `import numba` | first call, no cache (compile) "
            "| first call, cache cold | first call, cache warm |",
            "|---|---|---|---|---|---|",
            f"| {ms(cold['run_s'])} | {ms(igea_new['kernels_s'])} | {cold['import_s']:.2f} s "
            f"| {cold['first_call_s']:.2f} s | {first['first_call_s']:.2f} s | {warm['first_call_s']:.2f} s |",
        ]
    if a.numba_wheels:
        wheels = sorted(Path(a.numba_wheels).rglob("*.whl"))
        total = sum(w.stat().st_size for w in wheels)
        lines += [
            "",
            "Numba wheels per platform and Python (what the extension zip would carry):",
            "",
            "| wheel | MB |",
            "|---|---|",
        ]
        lines += [f"| {w.name} | {w.stat().st_size / 1e6:.1f} |" for w in wheels]
        lines.append(f"| total ({len(wheels)} wheels) | {total / 1e6:.0f} |")
    write_section("pm-speed", "\n".join(lines))


if __name__ == "__main__":
    main()
