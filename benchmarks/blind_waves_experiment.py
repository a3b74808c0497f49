"""Measure the keyed-waves prototype carrier (``pmwm_bench.keyed_waves``) where nobody tuned it.

For each mesh (the report-only data meshes, and generated shapes of fresh seeds, one per family): the owner
marks a 64-bit payload within 0.03 % MRMS, then every attack of the held-out benchmark
(``bench_heldout.ATTACKS``) is read with the owner's phrase; then the attacker without the phrase:
(a) another phrase marks the owner's copy again at the owner's step and at twice it, (b) a random field in
the carrier's public band (random keyed waves of a phrase the attacker draws, a least-energy field setting
random projections) at 1, 2 and 3 times the marking's MRMS, (c) Gaussian noise at 3 times; and false
positives: the unmarked mesh with the owner's phrase, the marked one with a wrong phrase.

The reader tries only the embedder's sign choice of the frame (``read(..., signs=1)``) to save time: it can
miss marks that the full reader (all 8 choices, which its p-value already pays) would find, never find more.

Run: python benchmarks/blind_waves_experiment.py --data | --generated N  [--out results.jsonl]
Decision record: docs/decisions/141-keyed-waves-prototype.md.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_heldout import ATTACKS  # noqa: E402

from pmwm import metrics  # noqa: E402
from pmwm.meshio import read_mesh  # noqa: E402
from pmwm_bench import corpus, split  # noqa: E402
from pmwm_bench import keyed_waves as kw  # noqa: E402
from pmwm_bench.report import commit, machine  # noqa: E402

OWNER = "the owner's pass phrase, kept secret"
ROOT = Path(__file__).resolve().parents[1]


def data_dir() -> Path:
    return Path(os.environ.get("PMWM_BENCH_DATA", ROOT.parent / "shared" / "data"))


def band_field(V, F, mrms_target, seed, samples=5000):
    """The attacker's key-free strip: a least-energy field in the public band setting the projections of a
    phrase of its own to random values, scaled to ``mrms_target`` % (MRMS from V)."""
    rng = np.random.default_rng(seed)
    B = kw.basis(f"attacker {seed}", 128)
    fr = kw.solid_frame(V, F)
    Y = fr.local(V)
    N, a = kw._vertex_normals_areas(Y, F)
    SP = np.cos(Y @ B.omega + B.phase) @ B.spread.T
    G = SP.T @ (a[:, None] * SP)
    delta = SP @ np.linalg.solve(G + 1e-12 * np.trace(G) / len(G) * np.eye(len(G)), rng.normal(size=len(G)))
    move = fr.scale * delta[:, None] * (N @ fr.axes.T)
    m1 = metrics.displaced_surface_distance(V, V + move, F, samples, seed=0)[0]
    return V + move * (mrms_target / m1)


def run(name, V, F, out, seed):
    payload = np.random.default_rng(seed).integers(0, 2, 64).astype(np.uint8)
    t0 = time.time()
    Vm, step, mrms = kw.embed(V, F, OWNER, payload)
    rec = {"mesh": name, "vertices": len(V), "embed_s": round(time.time() - t0, 1), "commit": commit()}
    if Vm is None:
        rec.update(refused=True, mrms_smallest=mrms)
        out.write(json.dumps(rec) + "\n")
        out.flush()
        print(name, "refused", mrms, flush=True)
        return
    rec.update(step=step, mrms=mrms, reads={})

    def read(label, V2, F2, phrase=OWNER):
        t = time.time()
        r = kw.read(np.asarray(V2, np.float64), np.asarray(F2, np.int64), phrase, signs=1)
        ok = bool(r.marked and r.payload is not None and np.array_equal(r.payload, payload))
        rec["reads"][label] = dict(
            read=ok, marked=bool(r.marked), p=r.p_value, m=r.matches, undo=r.undo, s=round(time.time() - t, 1)
        )
        print(f"  {name} {label:40s} {'READ' if ok else '----'} p={r.p_value:.1e} m={r.matches} {r.undo}", flush=True)

    for i, (label, fn) in enumerate(ATTACKS.items()):
        try:
            V2, F2 = fn(Vm, F, seed + i)
        except Exception as e:  # (an attack that cannot run on this mesh: recorded)
            rec["reads"][label] = dict(error=str(e)[:200])
            continue
        read(label, V2, F2)
    # the attacker without the phrase
    for k in (1, 2):
        other = np.random.default_rng(seed + 100 + k).integers(0, 2, 64).astype(np.uint8)
        w = kw.word_of(f"pirate {k}", other)
        B = kw.basis(f"pirate {k}", len(w))
        Vo = kw.mark(Vm, F, B, w ^ B.scramble, k * step)
        rec["reads"][f"overmark {k}x: attack MRMS / marking"] = (
            metrics.displaced_surface_distance(Vm, Vo, F, 5000, seed=0)[0] / mrms
        )
        read(f"overmark {k}x", Vo, F)
    for r_ in (1, 2, 3):
        read(f"band strip {r_}x", band_field(Vm, F, r_ * mrms, seed + r_), F)
    sigma = 3 * mrms / 100 * metrics.bbox_diagonal(V)
    read("noise 3x", Vm + np.random.default_rng(seed).normal(size=Vm.shape) * sigma / np.sqrt(3), F)
    read("false positive: unmarked", V, F)
    read("false positive: wrong phrase", Vm, F, "a wrong phrase")
    out.write(json.dumps(rec) + "\n")
    out.flush()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", action="store_true", help="the report-only data meshes")
    ap.add_argument("--generated", type=int, default=0, help="shapes per family, fresh seeds")
    ap.add_argument("--families", default="organic,cad,scan,thin,open")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "blind_waves.jsonl"))
    a = ap.parse_args(argv)
    with open(a.out, "a") as out:
        out.write(json.dumps({"run": machine(), "commit": commit(), "argv": sys.argv[1:]}) + "\n")
        if a.data:
            for i, name in enumerate(split.REPORT_ONLY):
                m = read_mesh(str(data_dir() / name))
                run(name, np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), out, 20261207 + i)
        if a.generated:
            seeds = {f: split.fresh_seeds(a.generated) for f in a.families.split(",")}
            out.write(json.dumps({"generated_seeds": seeds}) + "\n")
            for fam, ss in seeds.items():
                for sd in ss:
                    V, F = corpus.generate(fam, sd)
                    run(f"{fam} {sd}", np.asarray(V, np.float64), np.asarray(F, np.int64), out, sd % 100000)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
