"""Experiment: how often the blind reader's key-free word-length choice is wrong on a freshly marked copy, and
whether the copy reads at the right length (the embed's self-check refuses or raises the margin on these today).

Run: nice -n 10 python benchmarks/blind_length_choice.py [--families organic,cad,scan,thin,open] [--per-family 2]
     [--phrases 3] [--seed S] [--vertices 0] [--out benchmarks/results/blind-attacks/length_choice.jsonl]

Each generated shape (fresh seeds from the master seed) x text payloads of 4, 7, 9 and 26 bytes x pass phrases
is marked as ``pmwm.embed`` marks it before its self-check (the calibrated margin, ``radial.embed_signs``), written
as float32, and read: the length the reader chooses (``blind.bin_statistics``, no pass phrase), each length's
excess energy, the verdict, and the verdict with the length forced to the true one. One JSON line per copy.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import RESULTS  # noqa: E402
from bench_blind_attacks import mark_unchecked  # noqa: E402

from pmwm.schemes import blind  # noqa: E402
from pmwm.schemes.blind import word  # noqa: E402
from pmwm_bench import corpus, split  # noqa: E402

BYTES = (4, 7, 9, 26)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="organic,cad,scan,thin,open")
    ap.add_argument("--per-family", type=int, default=2)
    ap.add_argument("--phrases", type=int, default=3)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--vertices", type=int, default=0, help="vertices aimed at (0: the seed's, 3,000-28,000)")
    ap.add_argument("--out", default=str(RESULTS / "blind-attacks" / "length_choice.jsonl"))
    a = ap.parse_args(argv)
    seed = split.fresh_seeds(1)[0] if a.seed is None else a.seed
    rng = np.random.default_rng(seed)
    shapes = [(f, int(rng.integers(2**62))) for f in a.families.split(",") for _ in range(a.per_family)]
    print(f"master seed {seed}; shapes {shapes}", flush=True)
    with open(a.out, "w", encoding="utf-8") as fh:
        head = {"run": " ".join(sys.argv), "seed": seed, "shapes": shapes, "vertices": a.vertices}
        fh.write(json.dumps(head) + "\n")
        for fam, s in shapes:
            V, F = corpus.generate(fam, s, a.vertices or None)
            for k in range(a.phrases):
                phrase = f"length {rng.integers(2**40):x}"
                for n in BYTES:
                    text = "".join(rng.choice(list("ABCDEFGHJKLMNPQRSTUVWXYZ"), n))
                    M, alpha = mark_unchecked(V, F, phrase, text)
                    secret = word.derive_secret(phrase)
                    n_word = len(word.payload_of(text, None, 32, None)[0]) + word.CHECK_BITS
                    stats = blind.bin_statistics(M, F)
                    v = blind.decide(stats, secret)
                    forced = blind.decide(dataclasses.replace(stats, n_word=n_word), secret)
                    row = {
                        "shape": f"{fam}:{s}", "vertices": len(V), "phrase": phrase, "bytes": n, "margin": alpha,
                        "true": n_word, "chosen": stats.n_word, "frames": list(stats.frame_names),
                        "mesh": stats.mesh, "read": bool(v.marked and v.payload == text),
                        "forced_read": bool(forced.marked and forced.payload == text),
                    }
                    fh.write(json.dumps(row) + "\n")
                    fh.flush()
                    print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
