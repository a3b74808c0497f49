"""The blind scheme: distortion, BER per benchmark attack, the whole payload after the
target attacks, progressive-mesh levels, false positives and speed; section ``blind`` of the report.

Run: python benchmarks/bench_blind.py [--keys 10] [--models bunny,dragon,venus-head,igea] [--fp 10000]
     [--quick] [--no-write]

Benchmark protocol: 64 bits in total per embedding (32 random payload bits + 32 check bits), one pass
phrase per key ("pmwm-bench:<seed>"), the attacks and their seeds of ``pmwm_bench.protocols``. BER is
over the 64-bit word as read at that length (hard decisions, before the Chase search); the BER of the
word returned is over the word the reader gives the user: when the verdict is marked, the word it decoded
(its payload and check bits: 0 errors when the whole payload is read), else the hard decisions of the
reader's guess (the verdict's "guess", chosen without the pass phrase), as the BER counts them (the anchors'
papers report the bits their extractors return, with no code to correct them). "whole"
counts the copies whose verdict is marked (p < 1e-6) with the exact payload.

False positives: every mesh of the data folder and procedurally made shapes (ellipsoids with keyed
bumps, tori), unmarked, read with random secrets. The statistics do not depend on the secret, so
each mesh is measured once and decided for every secret (``pmwm.schemes.blind.decide``); a secret
stands for the pass phrase it is derived from (scrypt maps phrases to secrets), and a few real
phrases go through scrypt too.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, commit, data_dirs, load, machine, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm import attacks, metrics  # noqa: E402
from pmwm.schemes import blind  # noqa: E402
from pmwm.validate import parse_bits  # noqa: E402
from pmwm_bench.protocols import attack_seed, benchmark_settings  # noqa: E402

PAYLOAD_BITS = 32
N_WORD = PAYLOAD_BITS + blind.word.CHECK_BITS


def crop_posed(V, F, seed=None):
    """A 30 % plane crop of a copy in a random pose."""
    Vs, Fs = attacks.similarity(V, F, seed=seed)
    return attacks.crop_plane(Vs, Fs, fraction=0.3, seed=seed)


WHOLE = [
    ("similarity", lambda V, F, seed: attacks.similarity(V, F, seed=seed)),
    ("reordering", lambda V, F, seed: attacks.reorder(V, F, seed=seed)),
    *[
        (f"re-export {e[1:].upper()}", (lambda e: lambda V, F, seed: attacks.reexport(V, F, e))(e))
        for e in (".obj", ".ply", ".stl", ".glb")
    ],
    ("quantization 8 bits", lambda V, F, seed: attacks.quantize(V, F, bits=8)),
    ("simplification 50 %", lambda V, F, seed: attacks.simplify(V, F, ratio=0.5, seed=seed)),
    ("subdivision midpoint", lambda V, F, seed: attacks.subdivide(V, F, "midpoint")),
    ("subdivision loop", lambda V, F, seed: attacks.subdivide(V, F, "loop")),
    ("subdivision sqrt3", lambda V, F, seed: attacks.subdivide(V, F, "sqrt3")),
    ("plane crop 10 %", lambda V, F, seed: attacks.crop_plane(V, F, fraction=0.1, seed=seed)),
    ("crop 30 % in a random pose", lambda V, F, seed: crop_posed(V, F, seed=seed)),
    # rows are added at the end: a row's attack seed follows its index (attack_seed(seed, "whole", j))
    ("subdivision Catmull-Clark", lambda V, F, seed: attacks.subdivide(V, F, "catmull-clark")),
]


def true_word(secret: str, payload: np.ndarray) -> np.ndarray:
    return blind.word.word_of(secret, "bits", payload)


@dataclass
class Reading:
    """What the reader made of one suspect: ``ber``, the BER of the 64-bit word read (hard decisions) in
    the frame whose reading the verdict kept (own, refined, crop or a neighbour of it, denoised) when
    marked, else the reader's guess (``blind._guess``: the own frame's, or for a copy on a coarse grid, the
    copy as it is or smoothed, whichever shows the most mark energy); ``ber_returned``, the BER of the word
    the reader returns (the decoded word when marked, else those hard decisions); ``whole``, the whole
    payload recovered with p < 1e-6; ``whole_own``, the same from the suspect's own frame alone (the reader
    before the refinement), None when not asked for."""

    ber: float
    ber_returned: float
    whole: bool
    whole_own: Optional[bool] = None


def read_one(V, F, secret: str, payload: np.ndarray, own_too: bool = False) -> Reading:
    """The reading of a suspect (``Reading``); ``own_too``: its own frame's verdict too."""
    try:
        stats = blind.bin_statistics(V, F)
    except pmwm.PmwmError:
        return Reading(0.5, 0.5, False, False if own_too else None)
    v = blind.decide(stats, secret)
    # the BER of the reading the verdict kept when it is marked; otherwise of the reader's guess, chosen
    # without the check bits (an unmarked verdict's own word is whichever frame's candidate happened to match
    # them best: no measure), or of the suspect's own frame when the guess has another length
    fi = v.detail.frame_index if v.marked else 0
    got, _ = blind.word_read(stats.words[N_WORD][fi], secret, N_WORD)
    if not v.marked:
        guess, _ = blind.guess_word(stats, secret)
        got = guess if len(guess) == N_WORD else got
    want = true_word(secret, payload)
    ber = float(np.mean(got != want))
    # the word the verdict returns: its decoded word (after the Chase search) when marked at this length
    decoded = parse_bits(v.detail.word) if v.marked else got
    returned = decoded if len(decoded) == N_WORD else got
    bits = "".join(map(str, payload.tolist()))
    own = None
    if own_too:
        v0 = blind.decide(stats.own_frame(), secret)
        own = bool(v0.marked and v0.bits == bits)
    return Reading(ber, float(np.mean(returned != want)), bool(v.marked and v.bits == bits), own)


def marked(V: np.ndarray, F: np.ndarray, seed: int):
    """The benchmark's blind-marked copy for key ``seed`` (its payload and pass phrase follow from it):
    (EmbedResult, payload (PAYLOAD_BITS,) uint8)."""
    payload = np.random.default_rng(seed).integers(0, 2, PAYLOAD_BITS).astype(np.uint8)
    res = pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind", bits=payload, seed=seed, passphrase=phrase_of(seed)))
    return res, payload


def phrase_of(seed: int) -> str:
    """The pass phrase of key ``seed``."""
    return f"pmwm-bench:{seed}"


def secret_of(seed: int) -> str:
    """The secret the pass phrase of key ``seed`` derives (``word.derive_secret``)."""
    return blind.word.derive_secret(phrase_of(seed))


def pm_first_level(pm, secret: str, payload: np.ndarray) -> tuple[int, int]:
    """(vertices of the coarsest level from which every finer level reads the whole payload, or -1;
    vertices of the full mesh)."""
    levels = [0, *pm.level_records.tolist()]
    first = -1
    for k in reversed(levels):
        V, F = pm.decode(records=k)
        if not read_one(V, F, secret, payload).whole:
            break
        first = pm.n_base_vertices + k
    return first, pm.n_vertices


def procedural(n: int, seed: int):
    """Ellipsoids with keyed bumps (and a few tori): unmarked shapes of many proportions."""
    rng = np.random.default_rng(seed)
    import trimesh

    if n % 5 == 4:
        m = trimesh.creation.torus(
            major_radius=1.0, minor_radius=rng.uniform(0.2, 0.5), major_sections=64, minor_sections=32
        )
        V = np.asarray(m.vertices) * rng.uniform(0.5, 2.0, 3)
        return V, np.asarray(m.faces)
    m = trimesh.creation.icosphere(subdivisions=int(rng.integers(4, 6)))
    V = np.asarray(m.vertices)
    bumps = rng.normal(size=(8, 3))
    bumps /= np.linalg.norm(bumps, axis=1)[:, None]
    h = (rng.uniform(-0.15, 0.15, 8)[None] * np.exp(-8 * (1 - V @ bumps.T))).sum(1)
    V = V * (1 + h)[:, None] * rng.uniform(0.4, 1.6, 3)
    return V, np.asarray(m.faces)


EQUAL_GRID = {"blind": (0.03, 0.05, 0.07, 0.1), "cho1": (0.01, 0.025, 0.05, 0.09), "cho2": (0.03, 0.05, 0.1, 0.18)}
EQUAL_ATTACKS = [
    ("noise 0.3 %", "noise_benchmark", {"amplitude": 0.003}),
    ("noise 0.5 %", "noise_benchmark", {"amplitude": 0.005}),
    ("smoothing 5 it.", "smooth_laplacian", {"lam": 0.1, "iterations": 5}),
    ("smoothing 10 it.", "smooth_laplacian", {"lam": 0.1, "iterations": 10}),
    ("quantization 8 bits", "quantize", {"bits": 8}),
    ("quantization 7 bits", "quantize", {"bits": 7}),
    ("simplification 50 %", "simplify", {"ratio": 0.5}),
    ("subdivision loop", "subdivide", {"scheme": "loop"}),
]


def equal_mrms(models: list[str], keys: int) -> str:
    """Blind against Cho I and II at several strengths each: MRMS and the BER of 64 bits per attack
    (blind: the 64-bit word read; Cho: its 64 payload bits), so rows of equal MRMS can be compared."""
    from pmwm_bench.methods import SchemeMethod

    out = [
        "## Blind scheme against Cho I and II at several strengths (equal MRMS)",
        "",
        f"{keys} keys per row; 64 bits (blind: 32 payload + 32 check; the word read in the frame the verdict kept "
        "when marked, else the reader's guess, as in section blind). BER per attack, mean over the keys.",
        "",
        "| model | method | strength | MRMS % | " + " | ".join(lbl for lbl, _, _ in EQUAL_ATTACKS) + " |",
        "|---|---|---|---|" + "---|" * len(EQUAL_ATTACKS),
    ]
    for model in models:
        V, F = load(model)
        for scheme, grid in EQUAL_GRID.items():
            for strength in grid:
                mr, bers = [], {lbl: [] for lbl, _, _ in EQUAL_ATTACKS}
                for k in range(keys):
                    seed = 2000 + k
                    if scheme == "blind":
                        payload = np.random.default_rng(seed).integers(0, 2, PAYLOAD_BITS).astype(np.uint8)
                        res = pmwm.embed(
                            V,
                            F,
                            pmwm.EmbedOptions(
                                scheme="blind",
                                bits=payload,
                                seed=seed,
                                strength=strength,
                                passphrase=phrase_of(seed),
                                base_ratio=1.0,
                            ),
                        )
                        marked = res.vertices
                    else:
                        bits = np.random.default_rng(seed).integers(0, 2, 64)
                        method = SchemeMethod(scheme, strength)
                        marked, key = method.embed(V, F, bits, seed=seed)
                    mr.append(metrics.surface_distance(V, F, marked, F, 100000, seed=seed)[0])
                    for i, (lbl, name, params) in enumerate(EQUAL_ATTACKS):
                        Va, Fa = attacks.ATTACKS[name](marked, F, seed=attack_seed(seed, "equal", i), **params)
                        if scheme == "blind":
                            bers[lbl].append(read_one(Va, Fa, secret_of(seed), payload).ber)
                        else:
                            got = np.array(list(method.extract(Va, Fa, key)), dtype=int)
                            bers[lbl].append(float(np.mean(got != bits)))
                out.append(
                    f"| {model} | {scheme} | {strength:g} | {np.mean(mr):.4f} | "
                    + " | ".join(f"{np.mean(bers[lbl]):.3f}" for lbl, _, _ in EQUAL_ATTACKS)
                    + " |"
                )
                print(out[-1], file=sys.stderr, flush=True)
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keys", type=int, default=10)
    ap.add_argument("--models", default="bunny,dragon,venus-head,igea")
    ap.add_argument("--fp", type=int, default=10000, help="verifications of unmarked meshes")
    ap.add_argument("--quick", action="store_true", help="the quick attack settings")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument(
        "--equal",
        metavar="MODELS",
        help="only the equal-MRMS comparison with Cho I/II on these models (section blind-equal-mrms)",
    )
    ap.add_argument("--pm-levels", action="store_true", help="only the progressive-mesh rows (first 3 keys), printed")
    a = ap.parse_args(argv)
    if a.pm_levels:
        print(f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.")
        for model in a.models.split(","):
            V, F = load(model)
            cells = []
            for k in range(min(3, a.keys)):
                res, payload = marked(V, F, 1000 + k)
                f, n = pm_first_level(res.pm, secret_of(1000 + k), payload)
                cells.append(f"{f:,} of {n:,}" if f > 0 else f"none of {n:,}")
            print(f"| {model} | {'; '.join(cells)} ({len(res.pm.level_records)} levels) |", flush=True)
        return 0
    if a.equal:
        body = f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.\n\n" + equal_mrms(
            a.equal.split(","), a.keys
        )
        print(body) if a.no_write else write_section("blind-equal-mrms", body)
        return 0
    models = a.models.split(",")
    settings = benchmark_settings(a.quick)
    rows, whole_rows, pm_rows, dist_rows = [], [], [], []
    t_start = time.time()
    for model in models:
        V, F = load(model)
        ber: dict[tuple[str, str], list[float]] = {}
        ber_returned: dict[tuple[str, str], list[float]] = {}
        whole: dict[str, list[bool]] = {}
        whole_own: dict[str, list[bool]] = {}
        mrms, haus, levels, margins = [], [], [], []
        for k in range(a.keys):
            seed = 1000 + k
            res, payload = marked(V, F, seed)
            secret = secret_of(seed)
            margins.append(res.strength)
            m, h = metrics.surface_distance(V, F, res.vertices, F, 100000, seed=seed)
            mrms.append(m)
            haus.append(h)
            for group, items in settings.items():
                for i, (label, _, name, params) in enumerate(items):
                    Va, Fa = attacks.ATTACKS[name](res.vertices, F, seed=attack_seed(seed, group, i), **params)
                    r = read_one(Va, Fa, secret, payload, own_too=True)
                    ber.setdefault((group, label), []).append(r.ber)
                    ber_returned.setdefault((group, label), []).append(r.ber_returned)
                    whole.setdefault(f"benchmark: {group} {label}", []).append(r.whole)
                    whole_own.setdefault(f"benchmark: {group} {label}", []).append(r.whole_own)
            for j, (label, fn) in enumerate(WHOLE):
                Va, Fa = fn(res.vertices, F, attack_seed(seed, "whole", j))
                r = read_one(Va, Fa, secret, payload, own_too=True)
                whole.setdefault(label, []).append(r.whole)
                whole_own.setdefault(label, []).append(r.whole_own)
            if k < 3:
                levels.append(pm_first_level(res.pm, secret, payload))
            print(f"{model} key {k}: MRMS {m:.4f} % ({time.time() - t_start:.0f} s)", file=sys.stderr, flush=True)
        dist_rows.append(
            f"| {model} | {len(V):,} | {np.mean(margins):.3f} | {np.mean(mrms):.4f} | {np.mean(haus):.4f} |"
        )
        rows.append(
            (
                model,
                {g: float(np.mean(v)) for g, v in ber.items()},
                {g: float(np.mean(v)) for g, v in ber_returned.items()},
            )
        )
        whole_rows.append(
            (
                model,
                {g: (int(np.sum(v)), len(v), int(np.sum(whole_own[g]))) for g, v in whole.items()},
                float(np.mean(mrms)),
            )
        )
        pm_rows.append(
            f"| {model} | "
            + ", ".join((f"{f:,} of {n:,} ({100 * f / n:.0f} %)" if f > 0 else f"none of {n:,}") for f, n in levels)
            + " |"
        )

    # ---- false positives
    fp_meshes = []
    for d in data_dirs():
        if d.is_dir():
            for p in sorted(d.iterdir()):
                if p.suffix.lower() in (".off", ".obj", ".ply", ".stl", ".glb"):
                    try:
                        fp_meshes.append((p.name, *load(str(p))))
                    except Exception as exc:  # a file trimesh cannot read is skipped, and said
                        print(f"skipped {p.name}: {exc}", file=sys.stderr)
    fp_meshes += [(f"procedural {i}", *procedural(i, i)) for i in range(20)]
    stats = [(name, blind.bin_statistics(V, F)) for name, V, F in fp_meshes]
    per = max(1, a.fp // len(stats))
    rng = np.random.default_rng(2026)
    ps = []
    t0 = time.time()
    for name, st in stats:
        for j in range(per):
            secret = rng.bytes(32).hex()
            ps.append(blind.decide(st, secret).p_value)
    t_fp = time.time() - t0
    for j in range(20):  # real pass phrases through scrypt too
        name, st = stats[j % len(stats)]
        ps.append(blind.decide(st, blind.word.derive_secret(f"wrong phrase {j}")).p_value)
    ps = np.array(ps)

    # ---- speed

    speed = []
    for model in ("bunny", "igea"):
        if model not in models:
            continue
        V, F = load(model)
        t = time.perf_counter()
        r = pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind", passphrase="speed", payload="Acme"))
        t_embed = time.perf_counter() - t
        best = min(_timed(lambda: pmwm.verify(r.vertices, r.faces, passphrase="speed")) for _ in range(3))
        speed.append(f"| {model} | {len(V):,} | {t_embed:.2f} s | {best:.3f} s |")

    # ---- markdown
    groups = [(g, label) for g, items in settings.items() for (label, *_rest) in items]
    out = [
        "## Blind scheme: read with a pass phrase alone",
        "",
        f"Command: `{command()}` at commit {commit()}. Machine: {machine()}. "
        f"{a.keys} keys per model (one pass phrase and random 32-bit payload each; 64 bits embedded: "
        f"32 payload + 32 check); default strength: the bin-mean margin calibrated per mesh to MRMS "
        f"{blind.TARGET_MRMS} % (``blind.TARGET_MRMS``).",
        "",
        "Embedding distortion (% of the bounding-box diagonal, mean over the keys):",
        "",
        "| model | vertices | margin (mean) | MRMS % | Hausdorff % |",
        "|---|---|---|---|---|",
        *dist_rows,
        "",
        "BER of the 64-bit word read (hard decisions in the frame the verdict kept when marked, else the reader's "
        "guess: the suspect's own frame, or for a copy on a coarse grid the copy as it is or smoothed by 3 to 16 "
        "steps, whichever shows the most mark energy, no pass phrase involved; mean over the keys), benchmark "
        "protocol:",
        "",
        "| attack | " + " | ".join(m for m, _, _ in rows) + " |",
        "|---|" + "---|" * len(rows),
    ]
    for g, label in groups:
        out.append(f"| {g} {label} | " + " | ".join(f"{r[(g, label)]:.3f}" for _, r, _ in rows) + " |")
    out += [
        "",
        "BER of the word the reader returns (the word it decoded, payload and check bits, when the verdict "
        "is marked: 0 when the whole payload is read; else the hard decisions above; mean over the keys), "
        "benchmark protocol:",
        "",
        "| attack | " + " | ".join(m for m, _, _ in rows) + " |",
        "|---|" + "---|" * len(rows),
    ]
    for g, label in groups:
        out.append(f"| {g} {label} | " + " | ".join(f"{r[(g, label)]:.3f}" for _, _, r in rows) + " |")
    out += [
        "",
        "Whole payload read (marked, p < 1e-6, exact payload) / copies; in brackets, the same copies read "
        "in the suspect's own frame alone (the reader without the frame refinement, measured in the same run):",
        "",
        "| attack | " + " | ".join(m for m, _, _ in whole_rows) + " |",
        "|---|" + "---|" * len(whole_rows),
        "| embedding MRMS % (mean) | " + " | ".join(f"{mr:.4f}" for _, _, mr in whole_rows) + " |",
    ]
    labels = [label for label, _ in WHOLE] + [f"benchmark: {g} {label}" for g, label in groups]
    for label in labels:
        out.append(
            f"| {label} | "
            + " | ".join(f"{w[label][0]}/{w[label][1]} ({w[label][2]})" for _, w, _ in whole_rows)
            + " |"
        )
    out += [
        "",
        "Progressive mesh (first 3 keys; base ratio 0.03): the coarsest level from which every finer "
        "level reads the whole payload:",
        "",
        "| model | vertices at that level, per key |",
        "|---|---|",
        *pm_rows,
        "",
        f"False positives: {len(ps):,} verifications of unmarked meshes ({len(stats)} shapes: every mesh of "
        f"the data folder and 20 procedural ones; {per} random secrets each, then 20 real pass phrases "
        f"through scrypt); decision time {t_fp:.1f} s for the random secrets.",
        "",
        "| threshold | verdicts at or below | observed rate |",
        "|---|---|---|",
    ]
    for alpha in (1e-2, 1e-3, 1e-6):
        n = int(np.sum(ps <= alpha))
        out.append(f"| p <= {alpha:g} | {n} | {n / len(ps):.2e} |")
    out += ["", f"Smallest p-value seen: {ps.min():.3g}.", ""]
    if speed:
        out += [
            "Speed (OMP_NUM_THREADS as set; end to end from arrays: embed with the progressive mesh; "
            "verify with the pass phrase, scrypt included, best of 3):",
            "",
            "| model | vertices | embed | verify |",
            "|---|---|---|---|",
            *speed,
        ]
    body = "\n".join(out)
    if a.no_write:
        print(body)
    else:
        write_section("blind", body)
    return 0


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


if __name__ == "__main__":
    sys.exit(main())
