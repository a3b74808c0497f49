"""The blind scheme against Blender's own subdivision: each model marked, then given the
Subdivision Surface modifier (Catmull-Clark, one level) in headless Blender, with its default limit
surface and without; read as the add-on reads an object (Blender's triangulation of the quads) and as
a PLY file Blender exported is read. Unmarked copies given the same modifier, read with every key's
pass phrase, count the false positives. Section ``blind-subsurf`` of the report.

Run (needs the ``bpy`` module): python benchmarks/bench_subsurf.py [--keys 5]
     [--models bunny,dragon,venus-head,igea] [--no-write]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # the add-on package, blender_pmwm
from _report import command, commit, load, machine, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm.schemes import blind  # noqa: E402
from pmwm.subdivision import coarse_mesh  # noqa: E402

PAYLOAD_BITS = 32


def subsurf(V: np.ndarray, F: np.ndarray, limit: bool, ply: Path) -> tuple[tuple, tuple]:
    """The mesh V, F with Blender's Subdivision Surface (one level, ``use_limit_surface=limit``)
    applied: (as the add-on reads the object: positions and ``calc_loop_triangles``), (as
    ``pmwm.read_mesh`` reads Blender's PLY export of it)."""
    import bpy

    from blender_pmwm import meshdata  # the add-on's own mesh transfer

    bpy.ops.wm.read_homefile(use_empty=True)
    mesh = bpy.data.meshes.new("m")
    meshdata.set_geometry(mesh, V, F)
    ob = bpy.data.objects.new("m", mesh)
    bpy.context.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    ob.select_set(True)
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.use_limit_surface = 1, limit
    bpy.ops.object.modifier_apply(modifier=mod.name)
    as_object = (meshdata.read_positions(ob.data), meshdata.read_triangles(ob.data))
    bpy.ops.wm.ply_export(
        filepath=str(ply),
        export_selected_objects=True,
        export_normals=False,
        export_uv=False,
        export_colors="NONE",
        apply_modifiers=False,
    )
    src = pmwm.read_mesh(str(ply))
    return as_object, (src.vertices, src.faces)


def as_it_is(Vs: np.ndarray, Fs: np.ndarray, phrase: str):
    """``blind.verify`` without the reading plan's "coarse" and "unsmoothed" stages: no subdivision step
    undone and no smoothing taken back."""
    return blind.verify(Vs, Fs, phrase, config=blind.READER.without("coarse", "unsmoothed"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keys", type=int, default=5)
    ap.add_argument("--models", default="bunny,dragon,venus-head,igea")
    ap.add_argument("--no-write", action="store_true", help="print only")
    a = ap.parse_args(argv)
    import bpy

    rows, fp_rows = [], []
    with tempfile.TemporaryDirectory(prefix="pmwm-subsurf-") as tmp:
        ply = Path(tmp) / "copy.ply"
        for model in a.models.split(","):
            V, F = load(model)
            got: dict[tuple[bool, str], list] = {}
            phrases = []
            for k in range(a.keys):
                seed = 3000 + k
                phrase = f"pmwm-bench:{seed}"
                phrases.append(phrase)
                payload = np.random.default_rng(seed).integers(0, 2, PAYLOAD_BITS).astype(np.uint8)
                res = pmwm.embed(
                    V,
                    F,
                    pmwm.EmbedOptions(scheme="blind", bits=payload, seed=seed, passphrase=phrase, progressive=False),
                )
                for limit in (True, False):
                    for route, (Vs, Fs) in zip(("object", "PLY"), subsurf(res.vertices, F, limit, ply)):
                        t = time.perf_counter()
                        v = pmwm.verify(Vs, Fs, passphrase=phrase)
                        dt = time.perf_counter() - t
                        c = coarse_mesh(Vs, Fs)
                        want = "".join(map(str, payload.tolist()))
                        ok = bool(v.marked and v.bits == want)
                        v0 = as_it_is(Vs, Fs, phrase)
                        got.setdefault((limit, route), []).append(
                            (
                                ok,
                                v.detail.mesh,
                                c.residual if c is not None else np.nan,
                                dt,
                                len(Vs),
                                bool(v0.marked and v0.bits == want),
                            )
                        )
                print(
                    f"{model} key {k}: "
                    + ", ".join(
                        f"{'limit' if lim else 'plain'} {r} {sum(x[0] for x in g)}" for (lim, r), g in got.items()
                    ),
                    file=sys.stderr,
                    flush=True,
                )
            for (limit, route), g in got.items():
                meshes = sorted({x[1] for x in g})
                rows.append(
                    f"| {model} | {g[0][4]:,} | {'on (default)' if limit else 'off'} | {route} | "
                    f"{sum(x[0] for x in g)}/{len(g)} ({sum(x[5] for x in g)}) | {', '.join(meshes)} | "
                    f"{np.nanmax([x[2] for x in g]):.1e} | {np.median([x[3] for x in g]):.2f} s |"
                )
            # the unmarked model, subdivided, read with every key's phrase: no "marked"
            for limit in (True, False):
                Vs, Fs = subsurf(V, F, limit, ply)[0]
                verdicts = [pmwm.verify(Vs, Fs, passphrase=p) for p in phrases]
                fp_rows.append(
                    f"| {model} | {'on (default)' if limit else 'off'} | "
                    f"{sum(v.marked for v in verdicts)} of {len(verdicts)} | "
                    f"{min(v.p_value for v in verdicts):.2e} | {verdicts[0].detail.mesh} |"
                )
    body = "\n".join(
        [
            f"Command: `{command()}` at commit {commit()}. Machine: {machine()}. Blender {bpy.app.version_string} "
            "(the `bpy` module), headless.",
            "",
            f"{a.keys} keys per model (one pass phrase and random {PAYLOAD_BITS}-bit payload each, default strength). "
            "Each marked mesh is given Blender's Subdivision Surface modifier (Catmull-Clark, 1 level), applied, "
            "with the modifier's limit surface (its default) and without; the copy is read as the add-on reads "
            "the object (its positions and Blender's triangulation of the quads) and as `pmwm.read_mesh` reads "
            "Blender's PLY export of it. Whole payload: marked (p < 1e-6) with the exact payload; in brackets, "
            "the same copies read as they are (no subdivision step undone, no smoothing taken back: the reader "
            "before d46800f). Mesh read: the "
            "verdict's `mesh`. Residual: `pmwm.subdivision.coarse_mesh`'s RMS residual, a share of the "
            "bounding-box diagonal (largest over the keys). Verify: `pmwm.verify` alone, median.",
            "",
            "| model | vertices after | limit surface | read from | whole payload | mesh read | residual | verify |",
            "|---|---|---|---|---|---|---|---|",
            *rows,
            "",
            "The unmarked models with the same modifier, read with the same pass phrases (false positives; "
            "smallest p-value; the mesh read):",
            "",
            "| model | limit surface | marked | smallest p | mesh read |",
            "|---|---|---|---|---|",
            *fp_rows,
        ]
    )
    print(body) if a.no_write else write_section("blind-subsurf", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
