"""Scale: `pmwm embed` of a mesh of over one million faces, its time and peak memory.

The mesh is the catalogue's igea (igea_cyberware.ply) (268,686 faces) after one midpoint subdivision
(1,074,744 faces, 537,370 vertices). Run: python benchmarks/bench_scale.py
Writes the "scale" section of BENCHMARKS.md.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, commit, load, machine, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm.attacks import subdivide  # noqa: E402


def main() -> None:
    V, F = subdivide(*load("igea"), scheme="midpoint")
    with tempfile.TemporaryDirectory() as tmp:
        big = os.path.join(tmp, "igea_x4.ply")
        pmwm.write_mesh(big, V, F)
        out = os.path.join(tmp, "marked.ply")
        cmd = [sys.executable, "-m", "pmwm", "embed", big, "-o", out, "--key", os.path.join(tmp, "k.json"),
               "--pm", os.path.join(tmp, "big.pmwm"), "--seed", "1", "-q"]
        t = time.perf_counter()
        subprocess.run(cmd, check=True)
        elapsed = time.perf_counter() - t
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        verify = subprocess.run([sys.executable, "-m", "pmwm", "verify", out, "--key", os.path.join(tmp, "k.json")],
                                capture_output=True, text=True)
        pm_size = os.path.getsize(os.path.join(tmp, "big.pmwm"))
    body = "\n".join([
        "## Scale: one million faces",
        "",
        f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.",
        "",
        f"`pmwm embed` (read PLY, embed, write marked PLY, key and .pmwm) on igea after one midpoint subdivision: "
        f"{len(V):,} vertices, {len(F):,} faces.",
        "",
        "| wall time | peak memory (max RSS of the process) | .pmwm size | verify of the written file |",
        "|---|---|---|---|",
        f"| {elapsed:.1f} s | {peak_mb:,.0f} MB | {pm_size / 2**20:.1f} MiB | {verify.stdout.splitlines()[0] if verify.stdout else verify.stderr.strip()} |",
        "",
        f"Targets: under 1 GB peak (issue 6): {'met' if peak_mb < 1024 else 'NOT met'}; embed under 10 s "
        f"(issue 13): {'met' if elapsed < 10 else 'NOT met'} ({elapsed:.1f} s for the whole command).",
    ])
    write_section("scale", body)


if __name__ == "__main__":
    main()
