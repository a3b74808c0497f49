"""What an attacker without the pass phrase does to the blind scheme's keyed waves, and false positives.

For each mesh (the report-only data meshes and generated shapes of fresh seeds, one per family), the owner
marks ``PAYLOAD`` with ``pmwm.embed(scheme="blind")``; the attacker has pmwm and the marked copy, not the
phrase:

- overmarking: another phrase's keyed waves written over the owner's copy at the largest public step whose
  MRMS stays within 1 and 2 times the owner's marking (the marking of ``pmwm.schemes.blind.waves.mark``,
  without the read-back check an attacker skips);
- band strip: the attacker's best key-free estimate of where the mark is, the carrier's public band: a
  least-energy field in the span of keyed waves of a phrase of its own, leaving the solid's frame in place,
  with random projections, scaled to 0.5, 1, 2 and 3 times the owner's MRMS;
- Gaussian noise at 1 and 3 times the owner's MRMS (untargeted baselines).

The owner's ``pmwm.verify`` must say marked with the owner's payload. MRMS: ``metrics.displaced_surface_distance``
(5,000 samples) from the copy attacked. False positives (``--fp N``): N keyed-waves readings
(``waveread.read``) of unmarked generated shapes (all families, fresh seeds) with random secrets, p-values
counted at 1e-2, 1e-3, 1e-6 (``--fp-minutes``: stop after that long; the count says how many were read).

Run: python benchmarks/bench_blind_waves_attacks.py [--data] [--generated 1] [--fp 0] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

import pmwm
from pmwm import metrics
from pmwm.errors import PmwmError
from pmwm.meshio import read_mesh
from pmwm.schemes.blind import solid, waveread, waves, word
from pmwm_bench import corpus, split
from pmwm_bench.report import commit, machine

PAYLOAD = "ACME-2026"
OWNER = "the owner's own pass phrase"
ROOT = Path(__file__).resolve().parents[1]
SAMPLES = 5000


def data_dir() -> Path:
    return Path(os.environ.get("PMWM_BENCH_DATA", ROOT.parent / "shared" / "data"))


def mrms(A, B, F) -> float:
    return float(metrics.displaced_surface_distance(A, B, F, SAMPLES, seed=0)[0])


def overmark(Vm, F, phrase: str, budget: float, rng) -> tuple[np.ndarray, float]:
    """Another phrase's keyed waves over ``Vm``: the largest public step within ``budget`` % MRMS."""
    payload = rng.integers(0, 2, 64).astype(np.uint8)
    secret = word.derive_secret(phrase)
    w = waveread.word_of(secret, "bits", payload)
    spread = waves.spread_of(secret, len(w))
    keyed = waves.waves_of(secret)
    best = (Vm, 0.0)
    for step in waves.STEPS:
        Vo = waves.mark(Vm, F, keyed, spread, w ^ spread.scramble, step)
        m = mrms(Vm, Vo, F)
        if m > budget:
            break
        best = (Vo, m)
    return best


def band_strip(Vm, F, target: float, seed: int) -> np.ndarray:
    """A field in the carrier's public band (keyed waves of the attacker's own phrase), random projections,
    the solid's frame kept, scaled to ``target`` % MRMS."""
    secret = f"attacker {seed}"
    keyed, spread = waves.waves_of(secret), waves.spread_of(secret, 192)
    frame = solid.solid_frame(Vm, F)
    Y = frame.local(Vm)
    move, N = waves.field(Y, F, keyed, spread, np.random.default_rng(seed).normal(size=192))
    delta = frame.world(move[:, None] * N)
    return Vm + delta * (target / mrms(Vm, Vm + delta, F))


def run(name, V, F, seed, out):
    rec = {"mesh": name, "vertices": len(V), "commit": commit()}
    t0 = time.time()
    try:
        res = pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind", passphrase=OWNER, payload=PAYLOAD, progressive=False))
    except PmwmError as exc:
        rec["refused"] = str(exc)
        out.write(json.dumps(rec) + "\n")
        return
    Vm = res.vertices
    own = mrms(V, Vm, F)
    rec.update(embed_s=round(time.time() - t0, 1), mrms=own, notes=list(res.notes), rows={})
    rng = np.random.default_rng(seed)

    def read(label, X, cost):
        v = pmwm.verify(X, F, passphrase=OWNER)
        ok = bool(v.marked and v.payload == PAYLOAD)
        rec["rows"][label] = {"read": ok, "p": v.p_value, "cost": cost / own, "reader": type(v.detail).__name__}
        print(f"  {name} {label:24s} {'READ' if ok else '----'} cost {cost / own:.2f}x p={v.p_value:.1e}", flush=True)

    for k in (1, 2):
        Vo, m = overmark(Vm, F, f"pirate {seed} {k}", k * own, rng)
        read(f"overmark {k}x", Vo, m)
    for r in (0.5, 1, 2, 3):
        Vs = band_strip(Vm, F, r * own, seed + int(10 * r))
        read(f"band strip {r:g}x", Vs, mrms(Vm, Vs, F))
    sigma = metrics.bbox_diagonal(V) / 100 / np.sqrt(3)
    for r in (1, 3):
        Vn = Vm + rng.normal(size=Vm.shape) * sigma * r * own
        read(f"noise {r}x", Vn, mrms(Vm, Vn, F))
    out.write(json.dumps(rec) + "\n")
    out.flush()


def false_positives(n: int, out, minutes: float = 0.0) -> None:
    seeds = split.fresh_seeds(len(corpus.FAMILIES))
    shapes = [corpus.generate(f, s, 3000) for f, s in zip(corpus.FAMILIES, seeds)]
    rng = np.random.default_rng(seeds[0])
    counts = {"readings": 0, "p<0.01": 0, "p<0.001": 0, "p<1e-06": 0, "smallest p": 1.0}
    t0 = time.time()
    for i in range(n):
        if minutes and time.time() - t0 > 60 * minutes:
            break  # (the readings done are counted and said)
        V, F = shapes[i % len(shapes)]
        p = waveread.read(V, F, rng.bytes(16).hex()).p_value
        counts["readings"] += 1
        counts["smallest p"] = min(counts["smallest p"], p)
        for t in (1e-2, 1e-3, 1e-6):
            counts[f"p<{t:g}"] += int(p < t)
    counts.update(seconds=round(time.time() - t0), families=list(corpus.FAMILIES), seeds=seeds)
    out.write(json.dumps({"false_positives": counts}) + "\n")
    print(counts, flush=True)


ROWS = (
    "overmark 1x",
    "overmark 2x",
    "band strip 0.5x",
    "band strip 1x",
    "band strip 2x",
    "band strip 3x",
    "noise 1x",
    "noise 3x",
)


def markdown(path: str) -> str:
    """The fragment ``blind-waves-attacks``: the rows of the results file ``path`` (every run in it)."""
    runs, recs, fps = [], [], []
    for line in Path(path).read_text().splitlines():
        d = json.loads(line)
        if "run" in d:
            runs.append(
                f"`{' '.join(['python benchmarks/bench_blind_waves_attacks.py', *d['argv']])}` at commit {d['commit']}"
            )
        elif "generated_seeds" in d:
            runs[-1] += "; generated seeds " + "; ".join(
                f"{f}: {', '.join(map(str, s))}" for f, s in d["generated_seeds"].items()
            )
        elif "false_positives" in d:
            fps.append(d["false_positives"])
        elif "rows" in d and not d.get("notes"):
            recs.append(d)
    lines = [
        "## Blind keyed waves against an attacker without the pass phrase",
        "",
        "Command: " + "; ".join(runs) + ". The owner marks `ACME-2026` (`--scheme blind`); the attacker has pmwm "
        "and the marked copy. Cost: the attack's MRMS (from the marked copy) over the marking's, median (range). "
        "Read: the owner's verify says marked with the owner's payload.",
        "",
        f"Copies: {len(recs)} ({', '.join(r['mesh'].split(':')[0] for r in recs)}): those the runs finished; refused "
        "or marked by the baseline carrier are left out.",
        "",
        "| attack | cost | owner reads |",
        "|---|---|---|",
    ]
    for row in ROWS:
        got = [r["rows"][row] for r in recs if row in r["rows"]]
        if not got:
            continue
        c = np.array([g["cost"] for g in got])
        read = sum(g["read"] for g in got)
        lines.append(f"| {row} | {np.median(c):.2f} ({c.min():.2f}-{c.max():.2f}) | {read} of {len(got)} |")
    for f in fps:
        lines += [
            "",
            f"False positives: {f['readings']:,} keyed-waves readings of unmarked generated shapes (families "
            f"{', '.join(f['families'])}, 3,000 vertices, seeds {', '.join(map(str, f['seeds']))}) with random "
            f"secrets in {f['seconds']} s: {f['p<0.01']} below p = 1e-2, {f['p<0.001']} below 1e-3, "
            f"{f['p<1e-06']} below 1e-6; smallest p {f['smallest p']:.2g}.",
        ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", action="store_true", help="the report-only data meshes")
    ap.add_argument("--generated", type=int, default=0, help="generated shapes per family (fresh seeds)")
    ap.add_argument("--fp", type=int, default=0, help="keyed-waves readings of unmarked shapes, random secrets")
    ap.add_argument("--fp-minutes", type=float, default=0.0, help="stop the false positives after this long")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "blind_waves_attacks.jsonl"))
    ap.add_argument("--markdown", help="write the fragment of --out's results to this file, and stop")
    a = ap.parse_args(argv)
    if a.markdown:
        Path(a.markdown).write_text(markdown(a.out))
        return 0
    with open(a.out, "a") as out:
        out.write(json.dumps({"run": machine(), "commit": commit(), "argv": sys.argv[1:]}) + "\n")
        if a.data:
            for i, name in enumerate(split.REPORT_ONLY):
                m = read_mesh(str(data_dir() / name))
                run(name, np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), 1000 + i, out)
        if a.generated:
            seeds = {f: split.fresh_seeds(a.generated) for f in corpus.FAMILIES}
            out.write(json.dumps({"generated_seeds": seeds}) + "\n")
            for fam, ss in seeds.items():
                for sd in ss:
                    run(f"{fam}:{sd}", *corpus.generate(fam, sd), sd % 100000, out)
        if a.fp:
            false_positives(a.fp, out, a.fp_minutes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
