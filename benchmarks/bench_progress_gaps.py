"""How long the library goes without a progress call: the report's drawing and the readers.

    python benchmarks/bench_progress_gaps.py [--mesh PATH] [--repeat 1]

On the bundled bunny (default; any mesh file with --mesh): ``verify_report.build_report`` of a robust
mark's verdict, and ``pmwm.verify`` of robust and blind marks (``EmbedOptions(payload="OWNR", seed=1)``,
no progressive mesh) on the marked mesh and on attacked copies that take the readers' longer paths
(moved and simplified: registration; cropped and moved: the cut starts and the crop frames; Loop
subdivision: the coarse mesh; smoothing: the unsmoothing scan). Each run records the wall-clock time
of every ``progress(fraction, message)`` call; a gap is the time from the start to the first call,
between two calls, or from the last call to the return. Prints (and writes as the section
"progress-gaps") per run: the total time, the number of calls, the longest gap and the message it
followed, the best of --repeat runs.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from _report import commit, machine, command, write_section  # benchmarks/ is the script's folder
import pmwm
from pmwm import attacks, verify_report

PHRASE = "correct horse battery"


def timed(fn) -> tuple[float, int, float, str]:
    """(total seconds, progress calls, longest gap in seconds, the message before the longest gap)
    of ``fn(progress)``."""
    calls: list[tuple[float, str]] = []
    start = time.perf_counter()
    fn(lambda f, m: calls.append((time.perf_counter(), m)))
    end = time.perf_counter()
    marks = [(start, "(start)")] + calls + [(end, "(return)")]
    gaps = [(b[0] - a[0], a[1]) for a, b in zip(marks, marks[1:])]
    gap, after = max(gaps)
    return end - start, len(calls), gap, after


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh", default=str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    src = pmwm.read_mesh(args.mesh)
    V, F = src.vertices, src.faces
    robust = pmwm.embed(V, F, pmwm.EmbedOptions(payload="OWNR", seed=1, progressive=False))
    blind = pmwm.embed(
        V, F, pmwm.EmbedOptions(payload="OWNR", seed=1, scheme="blind", passphrase=PHRASE, progressive=False)
    )
    copies = {
        "marked": lambda M: (M, F),
        "moved + simplified 50 %": lambda M: attacks.similarity(*attacks.simplify(M, F, 0.5, seed=2), seed=3),
        "cropped 20 % + moved": lambda M: attacks.similarity(*attacks.crop_plane(M, F, 0.2, seed=2), seed=3),
        "Loop subdivision": lambda M: attacks.subdivide(M, F, "loop", seed=2),
        "smoothed (10 x 0.1)": lambda M: attacks.smooth_laplacian(M, F, lam=0.1, iterations=10, seed=2),
    }
    runs = []
    verdict = pmwm.verify(robust.vertices, F, robust.key)
    runs.append(
        (
            "build_report",
            "robust, marked",
            lambda p: verify_report.build_report(verdict, robust.key, robust.vertices, F, progress=p),
        )
    )
    for name, attack in copies.items():
        Vr, Fr = attack(robust.vertices)[:2]
        Vb, Fb = attack(blind.vertices)[:2]
        runs.append(("verify robust", name, lambda p, Vr=Vr, Fr=Fr: pmwm.verify(Vr, Fr, robust.key, progress=p)))
        runs.append(("verify blind", name, lambda p, Vb=Vb, Fb=Fb: pmwm.verify(Vb, Fb, passphrase=PHRASE, progress=p)))
    rows = []
    for what, name, fn in runs:
        best = min((timed(fn) for _ in range(args.repeat)), key=lambda r: r[2])
        total, n, gap, after = best
        rows.append(f"| {what} | {name} | {total:.2f} | {n} | {gap:.2f} | {after} |")
        print(rows[-1], flush=True)
    body = "\n".join(
        [
            f"Mesh: {Path(args.mesh).name} ({len(V):,} vertices, {len(F):,} faces). Machine: {machine()}. "
            f"Commit: {commit()}. Command: `{command()}`.",
            "",
            "| call | suspect | total (s) | progress calls | longest gap (s) | gap after |",
            "|---|---|---|---|---|---|",
            *rows,
        ]
    )
    write_section("progress-gaps", body)


if __name__ == "__main__":
    main()
