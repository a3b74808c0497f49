"""The robust embed's self-check: what it changes for a user (embeds whose own output does not read) and what it
costs (embed time on bunny-size meshes).

Run (each with the pmwm to measure first on the path; the first run with the code before the check, OLD):
    PYTHONPATH=OLD/core:tests nice -n 10 python benchmarks/bench_robust_selfcheck.py run before.json --label OLD
    PYTHONPATH=core:tests nice -n 10 python benchmarks/bench_robust_selfcheck.py run after.json
    python benchmarks/bench_robust_selfcheck.py write before.json after.json   (the fragment robust-selfcheck.md)

``run``: (1) the small blob of ``tests/meshes.py`` (2,906 vertices, the size where a bit's sites crowd), seeds
``--seeds`` (0-39), the default 64-bit random payload and ``--payload``: each embed (no progressive mesh, as
``pmwm embed`` without ``--pm``) is "refused" (a PmwmError), or its output is read as written and in
``--poses`` poses and vertex orders of its own (similarity + reorder, float32, seeds 7919 * seed + k, not the
self-check's), each read MARKED with the payload confirmed or not; (2) the embed time (wall, median of
``--repeats``) of the bunny shipped with pmwm and a generated organic shape of the same size, with and without
the progressive mesh. The rows go to the JSON file, rewritten after each.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm import attacks  # noqa: E402
from pmwm.errors import PmwmError  # noqa: E402
from pmwm_bench import corpus  # noqa: E402
from pmwm_bench.report import commit, machine  # noqa: E402

NAME = "robust-selfcheck"


def _reads(V, F, key) -> bool:
    v = pmwm.verify(V, F, key)
    return bool(v.marked and v.payload_confirmed)


def outcomes(seeds: range, poses: int, payload: str | None, rows: list, save) -> None:
    import meshes  # tests/meshes.py: the small blob

    V, F = meshes.blob()
    for seed in seeds:
        told: list[str] = []
        t0 = time.perf_counter()
        row = {"part": "blob", "seed": seed, "payload": payload}
        try:
            res = pmwm.embed(
                V,
                F,
                pmwm.EmbedOptions(seed=seed, payload=payload, progressive=False),
                progress=lambda f, m: told.append(m) if m.startswith("layout ") else None,
            )
        except PmwmError as exc:
            row.update(outcome="refused", message=str(exc), embed_s=time.perf_counter() - t0, layouts=told)
            rows.append(row)
            save()
            continue
        row.update(embed_s=time.perf_counter() - t0, layouts=told)
        written = _reads(res.vertices, res.faces, res.key)
        posed = []
        for k in range(poses):
            Vp, Fp = attacks.reorder(*attacks.similarity(res.vertices, res.faces, seed=7919 * seed + k), seed=k)
            posed.append(_reads(Vp.astype(np.float32).astype(np.float64), Fp, res.key))
        row.update(outcome="returned", as_written=written, posed=posed)
        rows.append(row)
        save()
        print(json.dumps(row), flush=True)


def costs(repeats: int, rows: list, save) -> None:
    bunny = Path(pmwm.__file__).parent / "data" / "bunny.off"
    src = pmwm.read_mesh(bunny)
    shapes = {"bunny": (src.vertices, src.faces), "organic 11": corpus.generate("organic", 11, vertices=35000)}
    for name, (V, F) in shapes.items():
        for progressive in (False, True):
            times, reads, layouts = [], [], []
            for r in range(repeats):
                told: list[str] = []
                t0 = time.perf_counter()
                res = pmwm.embed(
                    V,
                    F,
                    pmwm.EmbedOptions(seed=r, progressive=progressive),
                    progress=lambda f, m: told.append(m) if m.startswith("layout ") else None,
                )
                times.append(time.perf_counter() - t0)
                layouts.append(len(told) + 1)
                if not progressive:  # one reading of the copies the check reads (where this pmwm has them)
                    reads.append(_copies_read_s(res))
            row = {"part": "cost", "mesh": name, "vertices": len(V), "progressive": progressive, "times": times}
            row.update(reads=reads, layouts=layouts)
            rows.append(row)
            save()
            print(json.dumps(row), flush=True)


def _copies_read_s(res) -> float | None:
    """Seconds to read the light copies of an embed's output with its key, as the self-check does once (None
    when this pmwm has no ``pmwm.readback``)."""
    try:
        from pmwm.readback import light_copies
    except ImportError:
        return None
    t0 = time.perf_counter()
    for _, V, F in light_copies(res.vertices, res.faces, res.key.secret):
        pmwm.verify(V, F, res.key)
    return time.perf_counter() - t0


def run(args) -> None:
    rows: list = []
    meta = {"label": args.label or commit(), "machine": machine(), "command": command()}

    def save() -> None:
        Path(args.out).write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))

    if args.part in ("all", "outcomes"):
        outcomes(range(args.seeds[0], args.seeds[1]), args.poses, None, rows, save)
        if args.payload:
            outcomes(range(args.seeds[0], args.seeds[1]), args.poses, args.payload, rows, save)
    if args.part in ("all", "cost"):
        costs(args.repeats, rows, save)


def _summary(rows: list, payload) -> dict:
    blob = [r for r in rows if r["part"] == "blob" and r["payload"] == payload]
    back = [r for r in blob if r["outcome"] == "returned"]
    return {
        "embeds": len(blob),
        "refused": len(blob) - len(back),
        "silent as written": sum(not r["as_written"] for r in back),
        "posed": sum(len(r["posed"]) for r in back),
        "posed unread": sum(len(r["posed"]) - sum(r["posed"]) for r in back),
        "returned with a posed copy unread": sum(not all(r["posed"]) for r in back),
        "embeds that needed a second layout": sum(bool(r.get("layouts")) for r in back),
        "seeds": f"{min(r['seed'] for r in blob)}-{max(r['seed'] for r in blob)}" if blob else "",
        "median embed s": statistics.median(r["embed_s"] for r in blob) if blob else float("nan"),
    }


def _merged(paths: str) -> dict:
    """The runs of the comma-separated JSON files ``paths``: the first one's meta, every row."""
    runs = [json.loads(Path(p).read_text()) for p in paths.split(",")]
    return {
        "meta": runs[0]["meta"],
        "commands": [r["meta"]["command"] for r in runs],
        "rows": [row for r in runs for row in r["rows"]],
    }


def write(args) -> None:
    runs = before, after = [_merged(p) for p in (args.before, args.after)]
    payloads = sorted({r["payload"] or "" for r in after["rows"] if r["part"] == "blob"})
    lines = [
        f"## Robust embed self-check (`{NAME}`)",
        "",
        f"Commands: {', '.join(f'`{c}`' for c in before['commands'] + after['commands'])}; code before: "
        f"{before['meta']['label']}, after: {after['meta']['label']}; {after['meta']['machine']} (shared with "
        "other jobs: times are indicative).",
        "",
        "### Embeds on the small blob (2,906 vertices): outcomes",
        "",
        "Each embed's output read as written and in poses and vertex orders the self-check does not use; "
        '"unread": not MARKED with the payload confirmed.',
        "",
    ]
    for payload in payloads:
        b, a = (_summary(d["rows"], payload or None) for d in (before, after))
        lines += [
            f"Payload: {'random 64 bits' if not payload else repr(payload)}, seeds {a['seeds']}.",
            "",
            "| | before | after |",
            "|---|---|---|",
        ]
        for k in a:
            if k != "seeds":
                fmt = (lambda x: f"{x:.2f}") if k == "median embed s" else str
                lines.append(f"| {k} | {fmt(b[k])} | {fmt(a[k])} |")
        lines.append("")
    lines += [
        "### Embed time (s, wall, median of the repeats, seeds 0, 1, 2)",
        "",
        "\"reads\": one reading of the check's three copies of the output (after; the check's cost when the first "
        'layout reads back); "layouts": layouts read back per embed.',
        "",
        "| mesh | vertices | progressive mesh | before | after | reads | layouts |",
        "|---|---|---|---|---|---|---|",
    ]
    cost_b, cost_a = ({(r["mesh"], r["progressive"]): r for r in d["rows"] if r["part"] == "cost"} for d in runs)
    for key, r in cost_a.items():  # (the last run of each)
        b = cost_b.get(key)
        reads = [x for x in r.get("reads", []) if x is not None]
        lines.append(
            f"| {r['mesh']} | {r['vertices']} | {'yes' if r['progressive'] else 'no'} | "
            + (f"{statistics.median(b['times']):.2f}" if b else "-")
            + f" | {statistics.median(r['times']):.2f} | "
            + (f"{statistics.median(reads):.2f}" if reads else "-")
            + f" | {', '.join(map(str, r.get('layouts', [])))} |"
        )
    write_section(NAME, "\n".join(lines))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run")
    r.add_argument("out")
    r.add_argument("--label")
    r.add_argument("--seeds", type=int, nargs=2, default=(0, 40))
    r.add_argument("--poses", type=int, default=4)
    r.add_argument("--payload", default="OWNR-26")
    r.add_argument("--repeats", type=int, default=3)
    r.add_argument("--part", choices=("all", "outcomes", "cost"), default="all")
    w = sub.add_parser("write")
    w.add_argument("before", help="the runs before, FILE[,FILE]")
    w.add_argument("after", help="the runs after, FILE[,FILE]")
    args = p.parse_args()
    (run if args.what == "run" else write)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
