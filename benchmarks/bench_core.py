"""Speed and size of the core: embed end to end, full decode, verify, bytes per record.

Run: python benchmarks/bench_core.py  (meshes from $PMWM_TEST_DATA or ../shared/data beside the checkout)
Writes the "core" section of BENCHMARKS.md.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, commit, machine, mesh_path, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm.pmfile import to_bytes  # noqa: E402

MODELS = ("bunny", "igea")  # names in the catalogue, pmwm_bench.models


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    rows = []
    lod_rows: list = []
    lod_bits = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in MODELS:
            src_path = str(mesh_path(name))
            out = os.path.join(tmp, f"{name}_marked.ply")
            key = os.path.join(tmp, f"{name}.key.json")
            pmf = os.path.join(tmp, f"{name}.pmwm")
            cli = [sys.executable, "-m", "pmwm", "embed", src_path, "-o", out, "--key", key, "--pm", pmf,
                   "--payload", "bench", "--seed", "1", "--force", "-q"]
            t_cli = best_of(lambda: subprocess.run(cli, check=True), 2)
            t_py0 = best_of(lambda: subprocess.run([sys.executable, "-c", "import pmwm.cli"], check=True), 2)
            src = pmwm.read_mesh(src_path)
            t_read = best_of(lambda: pmwm.read_mesh(src_path))
            res = None

            def run_embed():
                nonlocal res
                res = pmwm.embed(src.vertices, src.faces, pmwm.EmbedOptions(payload="bench", seed=1))

            t_embed = best_of(run_embed, 2)
            pm = res.pm
            t_decode = best_of(lambda: pm.decode(), 7)
            marked = pmwm.read_mesh(out)
            k = pmwm.read_key(key)
            t_verify = best_of(lambda: pmwm.verify(marked.vertices, marked.faces, k))
            perm = np.random.default_rng(0).permutation(len(marked.vertices))
            inv = np.argsort(perm)
            Vp, Fp = marked.vertices[perm], inv[marked.faces]
            t_verify_pos = best_of(lambda: pmwm.verify(Vp, Fp, k))
            if name == "bunny":
                lod_rows = pmwm.ber_per_level(pm, res.key)
                lod_bits = res.key.n_bits
            size = len(to_bytes(pm))
            head = size - pm.n_records * 24  # header, base mesh, level table, checksum
            rows.append((name, len(src.vertices), t_cli, t_py0, t_read, t_embed, pm.n_records, t_decode,
                         t_verify, t_verify_pos, size, len(pm.level_records), head))
    lines = [
        "## Core speed and size",
        "",
        f"Command: `{command()}` at commit {commit()}. Machine: {machine()}. Best of 2-3 runs (decode: best of 7).",
        "",
        "| mesh | vertices | `pmwm embed` CLI end to end | of which Python start + import | read mesh | `pmwm.embed()` | records | full decode | records/s | verify (index) | verify (re-ordered copy) | .pmwm bytes | bytes/record |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (name, n, t_cli, t_py0, t_read, t_embed, nrec, t_dec, t_ver, t_verp, size, _, head) in rows:
        lines.append(
            f"| {name} | {n:,} | {t_cli:.2f} s | {t_py0:.2f} s | {t_read:.3f} s | {t_embed:.2f} s | {nrec:,} | "
            f"{t_dec * 1000:.0f} ms | {nrec / t_dec / 1e6:.2f} M | {t_ver * 1000:.1f} ms | {t_verp * 1000:.1f} ms | "
            f"{size:,} | 24 (+ {head:,} B of header, base mesh and levels) |"
        )
    ig = [r for r in rows if r[0] == "igea"][0]
    per100k = ig[5] * 100_000 / ig[1]
    lines += [
        "",
        "Against the targets of issue 2 (measured above):",
        f"- embed of a 100k-vertex mesh under 2 s: `pmwm.embed()` takes {ig[5]:.2f} s on 134k vertices "
        f"(scaled linearly, about {per100k:.1f} s per 100k vertices: {per100k / 2:.1f}x the target); the command "
        "line adds reading, writing three files and Python start-up. The progressive-mesh encoder dominates: "
        f"{ig[11]} batched passes of numpy work, each rebuilding the adjacency; a pass can only collapse "
        "vertices whose closed 1-rings are disjoint (about 10 % of the vertices).",
        f"- full decode above 1 M records/s: {ig[6] / ig[7] / 1e6:.2f} M records/s on igea, "
        f"{rows[0][6] / rows[0][7] / 1e6:.2f} M on the bunny.",
        f"- verify under 0.5 s beyond loading: {ig[8] * 1000:.0f} ms (index) and {ig[9] * 1000:.0f} ms "
        "(re-ordered copy, carriers found by position).",
        "- at most 24 bytes per record: 24 (float32 position, 32-bit vertex with 2 flag bits, 64-bit face mask).",
    ]
    lines += [
        "",
        "Watermark read from the progressive mesh of the bunny at every level of detail (payload \"bench\", "
        f"{lod_bits} bits, seed 1): BER per level, base mesh first.",
        "",
        "| vertices | " + " | ".join(f"{n:,}" for _, n, _ in lod_rows) + " |",
        "|---|" + "---|" * len(lod_rows),
        "| BER | " + " | ".join(f"{b:.2f}" for _, _, b in lod_rows) + " |",
    ]
    write_section("core", "\n".join(lines))


if __name__ == "__main__":
    main()
