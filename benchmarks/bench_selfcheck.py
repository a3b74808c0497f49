"""Silent failures of the blind embed: embeds that end without an error whose own output, written as
``pmwm embed`` writes it and read back, does not verify with the pass phrase and the payload.

Run: nice -n 10 python benchmarks/bench_selfcheck.py OUT.json [--meshes all] [--lengths 4,7,9,26]
     [--phrases 3] [--corpus 2] [--label after] [--seeds SEEDS.json]

Every data mesh (``pmwm_bench.split``: TUNING and REPORT_ONLY) x text payloads of 4, 7, 9 and 26 bytes x
the pass phrases, and shapes of every family of ``pmwm_bench.corpus`` (fresh seeds, recorded in the
results; ``--seeds`` re-uses a record) x the payload lengths x the first phrase. Each embed runs as the
command line runs it (``pmwm.embed``, no progressive mesh), its output is written in the input's format
(``pmwm.write_marked``: data meshes; PLY for generated shapes), read back and verified with the phrase.
Outcomes: "read" (marked, the payload confirmed), "refused" (a PmwmError: the one line the user sees),
"silent" (the embed ended and its output does not read). The results file is rewritten after every
embed, so a run cut short keeps what it measured.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, mesh_path  # noqa: E402

import pmwm  # noqa: E402
from pmwm.errors import PmwmError  # noqa: E402
from pmwm_bench import corpus, split  # noqa: E402
from pmwm_bench.report import commit, machine  # noqa: E402

PAYLOADS = {4: "OWNR", 7: "ACME-26", 9: "ACME-2026", 26: "ACME Studio asset 2026-X01"}
PHRASES = ("correct horse battery staple", "blue-whale-7", "studio secret 2026", "k9#Lm2!vq")


def one(path: str, payload: str, phrase: str) -> dict:
    """Embed ``payload`` with ``phrase`` into the mesh file ``path`` as ``pmwm embed`` does, write, read
    back, verify: the outcome and its figures."""
    src = pmwm.read_mesh(path)
    t0 = time.perf_counter()
    try:
        res = pmwm.embed(
            src.vertices,
            src.faces,
            pmwm.EmbedOptions(scheme="blind", payload=payload, passphrase=phrase, progressive=False),
        )
    except PmwmError as exc:
        return {"outcome": "refused", "message": str(exc), "embed_s": time.perf_counter() - t0}
    embed_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory(prefix="pmwm-selfcheck-") as tmp:
        out = os.path.join(tmp, "marked" + Path(path).suffix)
        pmwm.write_marked(out, src, res.vertices)
        back = pmwm.read_mesh(out)
    v = pmwm.verify(back.vertices, back.faces, passphrase=phrase)
    ok = bool(v.marked and v.payload == payload)
    return {
        "outcome": "read" if ok else "silent",
        "embed_s": embed_s,
        "p_value": v.p_value,
        "marked": bool(v.marked),
        "payload_read": v.payload,
        "strength": float(res.strength),
        "notes": list(res.notes),
        "reader": type(v.detail).__name__,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--meshes", default="all", help="data file names, comma-separated, or 'all' or 'none'")
    ap.add_argument("--lengths", default="4,7,9,26")
    ap.add_argument("--phrases", type=int, default=3)
    ap.add_argument("--corpus", type=int, default=2, help="generated shapes per family (fresh seeds)")
    ap.add_argument("--corpus-vertices", type=int, default=0, help="vertices aimed at (0: the seed's size)")
    ap.add_argument("--seeds", help="a seed record (pmwm_bench.split.draw_corpus) to generate again")
    ap.add_argument("--label", default="")
    a = ap.parse_args(argv)
    lengths = [int(x) for x in a.lengths.split(",")]
    phrases = PHRASES[: a.phrases]
    names = (
        (list(split.TUNING) + list(split.REPORT_ONLY))
        if a.meshes == "all"
        else ([] if a.meshes == "none" else a.meshes.split(","))
    )
    seeds = split.read_seeds(a.seeds) if a.seeds else split.draw_corpus(a.corpus) if a.corpus else {}
    doc = {
        "label": a.label,
        "command": command(),
        "commit": commit(),
        "machine": machine(),
        "corpus_seeds": seeds,
        "corpus_vertices": a.corpus_vertices,
        "runs": [],
    }

    def save():
        tmp = a.out + ".tmp"
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1)
        os.replace(tmp, a.out)

    jobs = [(n, str(mesh_path(n)), L, ph) for n in names for L in lengths for ph in phrases]
    with tempfile.TemporaryDirectory(prefix="pmwm-selfcheck-corpus-") as tmp:
        for fam, ss in seeds.items():
            for s in ss:
                V, F = corpus.generate(fam, s, a.corpus_vertices or None)
                p = os.path.join(tmp, f"{fam}-{s}.ply")
                pmwm.write_mesh(p, V, F)
                jobs += [(f"{fam}:{s}", p, L, phrases[0]) for L in lengths]
        for name, path, L, ph in jobs:
            r = one(path, PAYLOADS[L], ph)
            r.update(mesh=name, payload_bytes=L, phrase=PHRASES.index(ph))
            doc["runs"].append(r)
            print(name, L, PHRASES.index(ph), r["outcome"], r.get("message", ""), flush=True)
            save()
    runs = doc["runs"]
    doc["summary"] = {o: sum(r["outcome"] == o for r in runs) for o in ("read", "refused", "silent")}
    save()
    print(doc["summary"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
