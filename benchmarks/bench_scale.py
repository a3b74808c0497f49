"""Scale: `pmwm embed` of a mesh of over one million faces, its time and peak memory.

The mesh is the catalogue's igea (igea_cyberware.ply) (268,686 faces) after one midpoint subdivision
(1,074,744 faces, 537,374 vertices). Run: python benchmarks/bench_scale.py [--repeat N] [--old-core DIR]
[--print-only]. Writes the "scale" section of the report (its fragment in benchmarks/results/)
(``--print-only``: prints it only).

``--repeat N`` runs the command N times and keeps the fastest (the machine is shared); ``--old-core
DIR`` also runs the command with another checkout's library (PYTHONPATH=DIR, e.g. main's ``core``),
alternating with this one, so that both figures come from the same run.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, commit, load, machine, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm.attacks import subdivide  # noqa: E402


def _embed(cmd: list[str], core: str | None) -> tuple[float, float]:
    """(wall time s, peak RSS MB) of one run of ``cmd`` in a fresh process (PYTHONPATH=core if given)."""
    env = dict(os.environ, PYTHONPATH=core) if core else None
    code = (
        "import resource, subprocess, sys, time; t = time.perf_counter(); subprocess.run(sys.argv[1:], check=True); "
        "print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024)"
    )
    out = subprocess.run([sys.executable, "-c", code, *cmd], check=True, env=env, capture_output=True, text=True)
    wall, peak = map(float, out.stdout.split())
    return wall, peak


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of the command; the fastest is kept")
    ap.add_argument("--old-core", default=None, help="also time this library folder (PYTHONPATH), alternating")
    ap.add_argument("--old-label", default=None, help="how the section names --old-core (e.g. its commit)")
    ap.add_argument("--print-only", action="store_true", help="print the section, do not write its fragment")
    a = ap.parse_args()
    V, F = subdivide(*load("igea"), scheme="midpoint")
    with tempfile.TemporaryDirectory() as tmp:
        big = os.path.join(tmp, "igea_x4.ply")
        pmwm.write_mesh(big, V, F)
        out = os.path.join(tmp, "marked.ply")
        cmd = [
            sys.executable,
            "-m",
            "pmwm",
            "embed",
            big,
            "-o",
            out,
            "--key",
            os.path.join(tmp, "k.json"),
            "--pm",
            os.path.join(tmp, "big.pmwm"),
            "--seed",
            "1",
            "-q",
            "--force",
        ]
        runs: dict[str, list[tuple[float, float]]] = {"this": [], "old": []}
        for _ in range(max(a.repeat, 1)):
            if a.old_core:
                runs["old"].append(_embed(cmd, a.old_core))
            runs["this"].append(_embed(cmd, None))
        elapsed, peak_mb = min(runs["this"])[0], max(p for _, p in runs["this"])
        verify = subprocess.run(
            [sys.executable, "-m", "pmwm", "verify", out, "--key", os.path.join(tmp, "k.json")],
            capture_output=True,
            text=True,
        )
        pm_size = os.path.getsize(os.path.join(tmp, "big.pmwm"))
    body = "\n".join(
        [
            "## Scale: one million faces",
            "",
            f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.",
            "",
            f"`pmwm embed` (read PLY, embed, write marked PLY, key and .pmwm) on igea after one midpoint subdivision: "
            f"{len(V):,} vertices, {len(F):,} faces.",
            "",
            "| wall time | peak memory (max RSS of the process) | .pmwm size | verify of the written file |",
            "|---|---|---|---|",
            f"| {elapsed:.1f} s | {peak_mb:,.0f} MB | {pm_size / 2**20:.1f} MiB | "
            f"{verify.stdout.splitlines()[0] if verify.stdout else verify.stderr.strip()} |",
            "",
            f"Targets: under 1 GB peak: {'met' if peak_mb < 1024 else 'NOT met'}; embed under 10 s: "
            f"{'met' if elapsed < 10 else 'NOT met'} ({elapsed:.1f} s for the whole command"
            + (f", fastest of {len(runs['this'])} runs" if len(runs["this"]) > 1 else "")
            + ").",
        ]
    )
    if runs["old"]:
        o_wall, o_peak = min(runs["old"])[0], max(p for _, p in runs["old"])
        body += (
            f"\n\nIn the same run, alternating, the library {a.old_label or f'at `{a.old_core}`'}: "
            f"{o_wall:.1f} s, {o_peak:,.0f} MB "
            f"(this checkout: {elapsed:.1f} s, {peak_mb:,.0f} MB; all runs, s: this "
            f"{', '.join(f'{w:.1f}' for w, _ in runs['this'])}; old {', '.join(f'{w:.1f}' for w, _ in runs['old'])})."
        )
    if a.print_only:
        print(body)
    else:
        write_section("scale", body)


if __name__ == "__main__":
    main()
