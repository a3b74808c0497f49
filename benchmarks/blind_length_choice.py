"""Experiment: the blind reader's two known failures on freshly marked copies: a wrong key-free word-length
choice, and a reading that breaks when the margin is raised (the embed's self-check refuses or raises the margin
on these today, so neither is silent).

Run: nice -n 10 python benchmarks/blind_length_choice.py [--families organic,cad,scan,thin,open] [--per-family 2]
     [--phrases 3] [--seed S] [--vertices 0] [--bytes 4,7,9,26] [--scales 1] [--meshes cow_libigl.off,...]
     [--out benchmarks/results/blind-attacks/length_choice.jsonl]

Each shape (generated from seeds the master seed draws, or a report-only data mesh of ``--meshes``) x text payloads
of ``--bytes`` bytes x pass phrases is marked as ``pmwm.embed`` marks it before its self-check (the calibrated
margin times each of ``--scales``: ``bench_blind_attacks.mark_unchecked``), written as float32, and read: the
length the reader chooses (``blind.bin_statistics``, no pass phrase), each length's excess energy on the unmarked
and on the marked mesh (``radial.excess_energy`` in the own frame, in standard deviations), how far the marked
mesh's own frame moved from the unmarked one's (centre, lo, hi in bin widths of the true length), the verdict, and
the verdict with the length forced to the true one. One JSON line per copy.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import RESULTS, load  # noqa: E402
from bench_blind_attacks import mark_unchecked  # noqa: E402

from pmwm.features import vertex_areas  # noqa: E402
from pmwm.schemes import blind  # noqa: E402
from pmwm.schemes.blind import radial, word  # noqa: E402
from pmwm_bench import corpus, split  # noqa: E402

LENGTHS = [L + word.CHECK_BITS for L in word.PAYLOAD_BITS]


def energies(V: np.ndarray, F: np.ndarray) -> list[float]:
    """The excess energy (standard deviations) of the own frame's bins at every word length the reader reads."""
    fr, a = radial.frame_of_areas(V, vertex_areas(V, F), 1)
    return [round(radial.excess_energy(s, sh, a.sum()), 1) for s, sh in radial.statistics_in(V, a, fr, LENGTHS)]


def frame_moved(V: np.ndarray, M: np.ndarray, F: np.ndarray, n_bins: int) -> list[float]:
    """How far the marked mesh's own frame lies from the unmarked one's: centre, lo, hi, in bin widths."""
    f0, f1 = radial.frame_of(V, F, n_bins)[0], radial.frame_of(M, F, n_bins)[0]
    w = f0.width
    return [
        round(float(np.linalg.norm(f1.centre - f0.centre) / w), 3),
        round((f1.lo - f0.lo) / w, 3),
        round((f1.hi - f0.hi) / w, 3),
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="organic,cad,scan,thin,open")
    ap.add_argument("--per-family", type=int, default=2)
    ap.add_argument("--phrases", type=int, default=3)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--vertices", type=int, default=0, help="vertices aimed at (0: the seed's, 3,000-28,000)")
    ap.add_argument("--bytes", default="4,7,9,26")
    ap.add_argument("--scales", default="1", help="multiples of the calibrated margin")
    ap.add_argument("--meshes", default="", help="report-only data meshes instead of generated shapes")
    ap.add_argument("--out", default=str(RESULTS / "blind-attacks" / "length_choice.jsonl"))
    a = ap.parse_args(argv)
    seed = split.fresh_seeds(1)[0] if a.seed is None else a.seed
    rng = np.random.default_rng(seed)
    names = [m for m in a.meshes.split(",") if m]
    if [m for m in names if m not in split.REPORT_ONLY]:
        raise SystemExit("--meshes: report-only data meshes only")
    shapes = names or [(f, int(rng.integers(2**62))) for f in a.families.split(",") for _ in range(a.per_family)]
    print(f"master seed {seed}; shapes {shapes}", flush=True)
    with open(a.out, "w", encoding="utf-8") as fh:
        head = {"run": " ".join(sys.argv), "seed": seed, "shapes": shapes, "vertices": a.vertices}
        fh.write(json.dumps(head) + "\n")
        for shape in shapes:
            if isinstance(shape, str):
                name, (V, F) = shape, load(shape)
            else:
                name, (V, F) = f"{shape[0]}:{shape[1]}", corpus.generate(*shape, a.vertices or None)
            unmarked = energies(V, F)
            for k in range(a.phrases):
                phrase = f"length {rng.integers(2**40):x}"
                secret = word.derive_secret(phrase)
                for n in [int(b) for b in a.bytes.split(",")]:
                    text = "".join(rng.choice(list("ABCDEFGHJKLMNPQRSTUVWXYZ"), n))
                    n_word = len(word.payload_of(text, None, 32, None)[0]) + word.CHECK_BITS
                    for scale in [float(x) for x in a.scales.split(",")]:
                        M, alpha = mark_unchecked(V, F, phrase, text, scale)
                        stats = blind.bin_statistics(M, F)
                        v = blind.decide(stats, secret)
                        forced = blind.decide(dataclasses.replace(stats, n_word=n_word), secret)
                        row = {
                            "shape": name,
                            "vertices": len(V),
                            "phrase": phrase,
                            "bytes": n,
                            "scale": scale,
                            "margin": alpha,
                            "true": n_word,
                            "chosen": stats.n_word,
                            "frames": list(stats.frame_names),
                            "mesh": stats.mesh,
                            "energy_unmarked": unmarked,
                            "energy_marked": energies(M, F),
                            "frame_moved": frame_moved(V, M, F, n_word),
                            "read": bool(v.marked and v.payload == text),
                            "forced_read": bool(forced.marked and forced.payload == text),
                        }
                        fh.write(json.dumps(row) + "\n")
                        fh.flush()
                        print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
