"""Add-on overhead: the pmwm.watermark operator against the core alone on the same ~100k-vertex mesh.

    python benchmarks/bench_addon.py [--mesh PATH] [--vertices 100000] [--repeat 3]

The mesh (default: the catalogue's Igea statue, from $PMWM_TEST_DATA or ../shared/data, decimated
with fast-simplification to about 100k vertices) becomes a Blender object. "core" times what the operator delegates:
``pmwm.embed`` + ``pmwm.write_key`` on the same float32-rounded arrays. "operator" times
``bpy.ops.pmwm.watermark`` as a script calls it, and as a panel click does (with an undo push).
The difference is the add-on's overhead: mesh transfer (foreach_get, loop triangulation), write
back (foreach_set, mesh.update) and Blender's operator machinery. Runs are interleaved and the
best of --repeat is kept, in wall time and in process CPU time (the CPU figure is the steadier one
on a shared machine); the mesh is reset to the unmarked positions before each operator run.
Prints a markdown table.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import tempfile
import time
from pathlib import Path

import bpy  # first: a process imports bpy once
from _report import commit, machine, mesh_path, write_section  # benchmarks/ is the script's folder, first on sys.path
import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def load_addon():
    folder = ROOT / "blender_pmwm"
    spec = importlib.util.spec_from_file_location(
        "blender_pmwm", folder / "__init__.py", submodule_search_locations=[str(folder)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["blender_pmwm"] = module
    spec.loader.exec_module(module)
    module.register()
    return module


def bench_mesh(path: Path, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    import pmwm

    src = pmwm.read_mesh(str(path))
    V, F = src.vertices, src.faces
    if len(V) > 1.05 * n_vertices:
        import fast_simplification

        V, F = fast_simplification.simplify(V.astype(np.float32), F.astype(np.int32), target_count=2 * n_vertices)
    return np.asarray(V, np.float32).astype(np.float64), np.asarray(F, np.int64)


def make_object(addon, V, F):
    mesh = bpy.data.meshes.new("bench")
    addon.meshdata.set_geometry(mesh, V, F)
    ob = bpy.data.objects.new("bench", mesh)
    bpy.context.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    return ob


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", type=Path, default=None, help="mesh file (default: the catalogue's igea)")
    ap.add_argument("--vertices", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    args.mesh = args.mesh or mesh_path("igea")

    import pmwm

    addon = load_addon()
    bpy.ops.wm.read_homefile(use_empty=True)
    V, F = bench_mesh(args.mesh, args.vertices)
    n_source = len(pmwm.read_mesh(str(args.mesh)).vertices)
    ob = make_object(addon, V, F)
    V = addon.meshdata.read_positions(ob.data)  # exactly what the operator will read
    F = addon.meshdata.read_triangles(ob.data)
    original = V.astype(np.float32).ravel()
    opts = dict(payload="ACME 2026", seed=1)

    tmp = tempfile.mkdtemp(prefix="pmwm-bench-")
    keys = ("core", "script", "click", "read", "write")
    wall: dict[str, list[float]] = {k: [] for k in keys}
    cpu: dict[str, list[float]] = {k: [] for k in keys}

    def timed(name, fn):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        wall[name].append(time.perf_counter() - w)
        cpu[name].append(time.process_time() - c)
        return out

    def core_run(r):
        res = pmwm.embed(V, F, pmwm.EmbedOptions(**opts))
        pmwm.write_key(os.path.join(tmp, f"core{r}.json"), res.key)
        return res

    for r in range(args.repeat):
        res = timed("core", lambda: core_run(r))
        for mode in ("script", "click"):
            ob.data.vertices.foreach_set("co", original)
            ob.data.update()
            key = os.path.join(tmp, f"{mode}{r}.json")
            call = ("EXEC_DEFAULT", True) if mode == "click" else ()
            assert timed(mode, lambda: bpy.ops.pmwm.watermark(*call, key_path=key, **opts)) == {"FINISHED"}
        timed("read", lambda: (addon.meshdata.read_positions(ob.data), addon.meshdata.read_triangles(ob.data)))
        timed("write", lambda: addon.meshdata.write_base_positions(ob.data, res.vertices))

    bw = {k: min(v) for k, v in wall.items()}
    bc = {k: min(v) for k, v in cpu.items()}

    def pct(d, k):
        return f"{100 * (d[k] - d['core']) / d['core']:+.1f} %"

    out: list[str] = []
    out.append(f"## Blender add-on overhead ({len(V):,} vertices, {len(F):,} triangles, {res.bits.size} bits)\n")
    out.append(
        f"Machine: {machine()}, bpy {bpy.app.version_string}; load average at the end {os.getloadavg()[0]:.1f}  "
    )
    out.append(
        f"Command: `python benchmarks/bench_addon.py --vertices {args.vertices} --repeat {args.repeat}` "
        f"at commit {commit()}  "
    )
    out.append(
        f"Mesh: {args.mesh.name}"
        + (f" ({n_source:,} vertices) decimated with fast-simplification" if len(V) < n_source else "")
        + f"; best of {args.repeat} interleaved runs\n"
    )
    out.append("| step | wall ms | CPU ms | overhead vs core (wall / CPU) |")
    out.append("|---|---:|---:|---:|")
    out.append(
        f"| core alone: `pmwm.embed` + `pmwm.write_key` | {bw['core'] * 1e3:.0f} | {bc['core'] * 1e3:.0f} | reference |"
    )
    for k, name in (
        ("script", "`bpy.ops.pmwm.watermark` called from a script"),
        ("click", "`bpy.ops.pmwm.watermark` with an undo push (a panel click)"),
    ):
        out.append(f"| {name} | {bw[k] * 1e3:.0f} | {bc[k] * 1e3:.0f} | {pct(bw, k)} / {pct(bc, k)} |")
    for k, name in (
        ("read", "of which mesh transfer in (foreach_get co, calc_loop_triangles)"),
        ("write", "of which write back (foreach_set co, mesh.update)"),
    ):
        out.append(f"| {name} | {bw[k] * 1e3:.0f} | {bc[k] * 1e3:.0f} | {100 * bw[k] / bw['core']:.1f} % of core |")
    write_section("addon", "\n".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
