"""Fingerprint tracing in any pose: near-symmetric shapes never tuned on, posed, mirrored half the time, damaged.

Shapes of the near-symmetric families of ``pmwm_bench.corpus`` (ellipsoid, bilateral, cad2, cad4; fresh seeds,
printed), each analysed once for fingerprinting with a registry of ``--recipients`` recipients. Each trial leaks
one copy (or the average of two, a collusion), puts it in a random pose (rotation, scale, translation),
mirrors it across a coordinate plane half the time, and applies one damage drawn as ``bench_pose`` draws them
(simplification 10-50 %, noise, Laplacian smoothing, quantization, a chain). ``pmwm.fingerprint``'s reading and
accusation (``pmwm.fingerprint.trace``: every plausible pose, the union bound paid) then name recipients at
p < 1e-6. Counted: the leakers named, innocents named (the target is none).

Run: nice -n 10 python benchmarks/bench_pose_trace.py --trials 200 --out pose_trace.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import pmwm  # noqa: E402
from pmwm import attacks  # noqa: E402
from pmwm.fingerprint import FingerprintOptions, analyse_asset  # noqa: E402
from pmwm.fingerprint.codes import codewords, pack_codeword  # noqa: E402
from pmwm.fingerprint.registry import FingerprintKey, Registry, RegistryEntry  # noqa: E402
from pmwm.fingerprint.trace import trace  # noqa: E402

from bench_pose import FAMILIES, damage, mirror  # noqa: E402
from pmwm_bench import corpus  # noqa: E402

KINDS = ("simplify", "noise", "smooth", "quantize", "chain")


def one_shape(family: str, shape_seed: int, rng: np.random.Generator, trials: int, n_recipients: int, out):
    """``trials`` leaks of one marked shape, each a row written to ``out``."""
    V, F = corpus.generate(family, shape_seed)
    try:
        an = analyse_asset(V, F, FingerprintOptions(seed=int(rng.integers(1 << 31))), progressive=False)
    except pmwm.PayloadError as exc:  # a shape too small for the sites: recorded, not counted
        out.write(json.dumps({"family": family, "shape_seed": shape_seed, "refused": str(exc)}) + "\n")
        return []
    fk = FingerprintKey(an.key, an.options, an.asset_sha256)
    ids = [f"r{i:05d}" for i in range(n_recipients)]
    C = codewords(an.key.secret, ids, an.n_sites)
    registry = Registry.for_key(fk)
    registry.entries = {r: RegistryEntry(pack_codeword(c)) for r, c in zip(ids, C)}
    rows = []
    for _ in range(trials):
        who = [int(i) for i in rng.choice(n_recipients, size=1 if rng.random() < 0.7 else 2, replace=False)]
        W, G = sum(an.marked(C[i]) for i in who) / len(who), F
        mirrored = bool(rng.random() < 0.5)
        if mirrored:
            W, G = mirror(W, G, rng)
        W, G = attacks.similarity(W, G, seed=int(rng.integers(1 << 31)))
        W, G, params = damage(W, G, KINDS[int(rng.integers(len(KINDS)))], rng)
        r = trace(W, G, fk, registry)
        T = r.scores
        named = {ids.index(a.recipient) for a in r.accused}
        row = {
            "family": family,
            "shape_seed": shape_seed,
            "leakers": len(who),
            "mirrored": mirrored,
            "attack": params,
            "named_leakers": len(named & set(who)),
            "innocents_named": len(named - set(who)),
            "max_leaker_score": float(T[who].max()),
            "max_innocent_score": float(np.delete(T, who).max()),
            "poses_read": r.detail.poses_read if r.detail else None,
            "mirror_said": r.detail.mirrored if r.detail else None,
        }
        rows.append(row)
        out.write(json.dumps(row) + "\n")
        out.flush()
    return rows


def summary(rows: list[dict]) -> str:
    one = [r for r in rows if r["leakers"] == 1]
    two = [r for r in rows if r["leakers"] == 2]
    lines = [
        "| leaked | trials | a leaker named | both named | innocents named |",
        "|---|---|---|---|---|",
        f"| one copy | {len(one)} | {sum(r['named_leakers'] >= 1 for r in one)} | - | "
        f"{sum(r['innocents_named'] for r in one)} |",
        f"| average of two | {len(two)} | {sum(r['named_leakers'] >= 1 for r in two)} | "
        f"{sum(r['named_leakers'] == 2 for r in two)} | {sum(r['innocents_named'] for r in two)} |",
    ]
    per = {}
    for r in one:
        k = next(iter(r["attack"]))
        n, m = per.get(k, (0, 0))
        per[k] = (n + (r["named_leakers"] >= 1), m + 1)
    lines += ["", "One copy, per damage: " + ", ".join(f"{k} {n}/{m}" for k, (n, m) in sorted(per.items()))]
    mir = [r for r in one if r["mirrored"]]
    lines += [f"One copy, mirrored: {sum(r['named_leakers'] >= 1 for r in mir)}/{len(mir)} named."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--per-shape", type=int, default=8)
    ap.add_argument("--recipients", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=None, help="replay a run (default: fresh)")
    ap.add_argument("--out", default="pose_trace.jsonl")
    ap.add_argument("--summarize", default=None, help="print the table of an earlier run's JSON lines")
    a = ap.parse_args()
    if a.summarize:
        print(summary([json.loads(line) for line in open(a.summarize) if '"leakers"' in line]))
        return
    seed = a.seed if a.seed is not None else int.from_bytes(os.urandom(4), "little")
    print(f"run seed {seed} (replay with --seed {seed})", flush=True)
    rng = np.random.default_rng(seed)
    rows: list = []
    with open(a.out, "a") as out:
        out.write(json.dumps({"run_seed": seed, "recipients": a.recipients}) + "\n")
        while len(rows) < a.trials:
            family = FAMILIES[int(rng.integers(len(FAMILIES)))]
            rows += one_shape(
                family, int(rng.integers(1 << 31)), rng, min(a.per_shape, a.trials - len(rows)), a.recipients, out
            )
            print(f"{len(rows)} trials", flush=True)
    print(summary(rows))


if __name__ == "__main__":
    main()
