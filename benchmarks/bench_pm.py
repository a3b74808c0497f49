"""Speed of the progressive mesh: build (encode) time and full decode records/s, new code beside old.

Meshes: the catalogue's bunny and igea, and igea after one midpoint subdivision (1,074,744 faces, the
mesh of bench_scale.py). Each measurement runs in a fresh subprocess of this script (``--worker``):
this checkout's code, and the old code with PYTHONPATH=<--old> (default ../main/core beside the
checkout), alternately, best of ``--repeat``. The anchor is fast_simplification.simplify decimating
the same arrays to the same vertex count, timed in the same worker. A last table times whole
processes on igea: ``pmwm embed`` (read, embed, write mesh, key and .pmwm) against a script that reads
the file with trimesh, decimates it to 1 % with fast_simplification and writes a PLY.

Run: OMP_NUM_THREADS=1 python benchmarks/bench_pm.py [--old PATH] [--repeat 3]
Writes the "pm-speed" section of BENCHMARKS.md.
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
from _report import ROOT, command, commit, load, machine, mesh_path, write_section  # noqa: E402

BASE_RATIO = 0.03  # the embedders' default base ratio
NEW_CORE = ROOT / "core"
OLD_CORE = ROOT.parent / "main" / "core"


def worker(mesh: str, repeat: int) -> None:
    """Time build_progressive_mesh, a full decode and fast_simplification on ``mesh`` (an .npz)."""
    import numpy as np

    import pmwm
    from pmwm.adjacency import build_adjacency
    from pmwm.progressive import build_progressive_mesh

    data = np.load(mesh)
    V, F = data["V"], data["F"]
    adj = build_adjacency(F, len(V))  # the embedders pass theirs: not part of the PM build
    base = max(int(round(BASE_RATIO * len(V))), 4)
    build = []
    for _ in range(repeat):
        t = time.perf_counter()
        pm, _ = build_progressive_mesh(V, F, base_vertices=base, adjacency=adj)
        build.append(time.perf_counter() - t)
    dec = []
    for _ in range(max(repeat, 3)):
        t = time.perf_counter()
        pm.decode()
        dec.append(time.perf_counter() - t)
    fs = []
    try:
        import fast_simplification

        for _ in range(repeat):
            t = time.perf_counter()
            fast_simplification.simplify(V.astype(np.float32), F.astype(np.int32), target_reduction=1 - base / len(V))
            fs.append(time.perf_counter() - t)
    except ImportError:
        pass
    print(json.dumps({
        "build_s": min(build), "decode_s": min(dec), "records": pm.n_records, "levels": len(pm.level_records),
        "fs_s": min(fs) if fs else None, "version": pmwm.__file__,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }))


def run_worker(core: Path, mesh: str, repeat: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(core))
    out = subprocess.run([sys.executable, __file__, "--worker", mesh, "--repeat", str(repeat)], env=env,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def best(a: dict, b: dict) -> dict:
    """Per field, the better of two runs of the same code (times: the smaller)."""
    return {k: (min(a[k], b[k]) if isinstance(a[k], float) else a[k]) for k in a}


def wall(cmd: list, env: dict, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, capture_output=True)
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--worker")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--old", default=str(OLD_CORE), help="the old code's core/ folder (skipped if absent)")
    a = ap.parse_args()
    if a.worker:
        worker(a.worker, a.repeat)
        return
    import numpy as np

    from pmwm.attacks import subdivide

    old = Path(a.old) if Path(a.old, "pmwm").is_dir() else None
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        meshes = {"bunny": load("bunny"), "igea": load("igea")}
        meshes["igea x4 (1M faces)"] = subdivide(*meshes["igea"], scheme="midpoint")
        for name, (V, F) in meshes.items():
            path = os.path.join(tmp, "m.npz")
            np.savez(path, V=np.asarray(V, np.float64), F=np.asarray(F, np.int64))
            rep = 1 if len(F) > 500_000 else a.repeat
            # alternate new and old, twice, so that both see the same machine load
            new = run_worker(NEW_CORE, path, rep)
            was = run_worker(old, path, rep) if old else None
            new = best(new, run_worker(NEW_CORE, path, rep))
            if old:
                was = best(was, run_worker(old, path, rep))
            rows.append((name, len(V), len(F), new, was))
        # whole processes on igea: pmwm embed vs fast_simplification to 1 %
        igea = str(mesh_path("igea"))
        env_new = dict(os.environ, PYTHONPATH=str(NEW_CORE))
        embed = [sys.executable, "-m", "pmwm", "embed", igea, "-o", os.path.join(tmp, "o.ply"), "--key",
                 os.path.join(tmp, "k.json"), "--pm", os.path.join(tmp, "o.pmwm"), "--seed", "1", "--force", "-q"]
        fs_script = ("import sys, trimesh, fast_simplification;"
                     "m = trimesh.load(sys.argv[1], process=False);"
                     "V, F = fast_simplification.simplify(m.vertices, m.faces, target_reduction=0.99);"
                     "trimesh.Trimesh(V, F, process=False).export(sys.argv[2])")
        fs_cmd = [sys.executable, "-c", fs_script, igea, os.path.join(tmp, "fs.ply")]
        t_embed_new = wall(embed, env_new, 3)
        t_fs = wall(fs_cmd, env_new, 3)
        t_embed_old = wall(embed, dict(os.environ, PYTHONPATH=str(old)), 2) if old else None

    def ms(x):
        return "–" if x is None else f"{x * 1000:,.0f} ms"

    lines = [
        "## Progressive mesh speed (issue 13)",
        "",
        f"Command: `OMP_NUM_THREADS=1 {command()}` at commit {commit()}. Machine: {machine()}.",
        f"Old code: {old if old else 'not found'} (its own commit). The machine was shared: each figure is the",
        "best of repeated runs in fresh processes, new and old alternating; compare ratios rather than seconds.",
        "",
        f"PM build = `build_progressive_mesh` to {BASE_RATIO:.0%} of the vertices (the embedders' default), "
        "adjacency given (the embedders pass theirs). Anchor: `fast_simplification.simplify` to the same "
        "vertex count on the same arrays.",
        "",
        "| mesh | vertices | faces | PM build new | old | speed-up | fast_simplification | new / anchor "
        "| levels new (old) | full decode new | old | peak RSS new (old) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, nv, nf, new, was in rows:
        sp = f"{was['build_s'] / new['build_s']:.1f}x" if was else "–"
        anchor = f"{new['build_s'] / new['fs_s']:.1f}x" if new["fs_s"] else "–"
        dec_new = new["records"] / new["decode_s"] / 1e6
        dec_old = f"{was['records'] / was['decode_s'] / 1e6:.2f} M/s" if was else "–"
        lv_old = was["levels"] if was else "–"
        mem_old = f"{was['peak_mb']:,.0f}" if was else "–"
        lines.append(
            f"| {name} | {nv:,} | {nf:,} | {ms(new['build_s'])} | {ms(was['build_s'] if was else None)} | {sp} "
            f"| {ms(new['fs_s'])} | {anchor} | {new['levels']} ({lv_old}) | {dec_new:.2f} M/s | {dec_old} "
            f"| {new['peak_mb']:,.0f} MB ({mem_old} MB) |")
    lines += [
        "",
        "Whole processes on igea (wall time, best of 3; old best of 2):",
        "",
        "| `pmwm embed` new | `pmwm embed` old | fast_simplification to 1 % (read, decimate, write) "
        "| new / anchor |",
        "|---|---|---|---|",
        f"| {t_embed_new:.2f} s | {'–' if t_embed_old is None else f'{t_embed_old:.2f} s'} | {t_fs:.2f} s "
        f"| {t_embed_new / t_fs:.2f}x |",
    ]
    write_section("pm-speed", "\n".join(lines))


if __name__ == "__main__":
    main()
