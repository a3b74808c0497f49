"""What an informed attacker (pmwm's code, no pass phrase) does to the blind scheme's mark; section
``blind-attacks`` of the report.

Run: nice -n 10 python benchmarks/bench_blind_attacks.py [--meshes horse_cyberware.ply,...]
     [--families organic,cad,scan] [--seed S] [--strengths 0.1,0.2,0.3,0.4,0.5,1]
     [--out benchmarks/results/blind-attacks/runs.jsonl] [--also MORE.jsonl ...]
     python benchmarks/bench_blind_attacks.py --markdown-only [--also ...]   (the fragment and plot from the rows)

Meshes: report-only meshes of ``pmwm_bench.split`` (the reader was never tuned on them) and one shape per
family of ``pmwm_bench.corpus`` from a seed drawn fresh. One master seed (fresh unless ``--seed``) draws every
mesh's owner pass phrase, owner payload (8 bytes of text), pirate pass phrases and payloads, and noise seeds.
The owner marks with default settings; then, on the marked copy:

- strip (key-free): the attacker computes what the blind reader computes before it uses the pass phrase
  (``blind.bin_statistics``: the bins at every word length and the length whose bins show the most mark energy),
  takes the bins of that length in the copy's own frame and moves every bin mean of r back towards 1/2 by a
  fraction t (the strength: 1 flattens, above 1 overshoots), with the scheme's own edge-preserving push
  r + beta sin^2(pi r) and its move partly along the surface (``radial.moved_to_radius``); also the library's
  embedder itself (``radial.embed_signs``) asked for the opposite signs with margin 0;
- baselines at the same distortion: Gaussian white noise and one uniform Laplacian step, each scaled so that its
  MRMS equals that of the strip at each strength (to show the strip is targeted, not merely strong);
- overmarking: the copy marked again with another pass phrase, payload 4 or 9 bytes of text, at the default
  (calibrated) margin and at twice that margin.

Every attacked copy is verified with the owner's pass phrase (marked, p-value, payload confirmed), an overmarked
one with the pirate's too. Distortion: MRMS surface distance (``pmwm.metrics.displaced_surface_distance``, 20,000
samples, % of the bounding-box diagonal), the attack's from the marked copy, the marking's from the original; the
table gives the attack's as a multiple of the marking's. One JSON line per attacked copy (``--out``).

Unlike the other scripts, this one uses the blind scheme's internals (``radial``, ``word``, the embedder's margin
calibration): the attacker it plays has the code.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import zlib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import RESULTS, command, load, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm import attacks, metrics  # noqa: E402
from pmwm.errors import PmwmError  # noqa: E402
from pmwm.features import vertex_normals  # noqa: E402
from pmwm.schemes import blind  # noqa: E402
from pmwm.schemes.blind import radial, selfcheck, word  # noqa: E402
from pmwm_bench import corpus, split  # noqa: E402
from pmwm_bench.report import commit, machine  # noqa: E402

NAME = "blind-attacks"
RAW = RESULTS / NAME
MESHES = ("horse_cyberware.ply", "armadillo_libigl.obj", "rocker_arm.obj", "fandisk.obj")
FAMILIES = ("organic", "cad", "scan")
STRENGTHS = (0.1, 0.2, 0.3, 0.4, 0.5, 1.0)
BASELINE_MULTIPLES = (2.0, 3.0)  # noise and Laplacian alone at these multiples of the marking's MRMS
PIRATE_BYTES = (4, 9)
PIRATE_SCALES = (1.0, 2.0)
SAMPLES = 20000
ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"
MACHINE = "this 2-core AMD EPYC, shared"


def mrms(V0: np.ndarray, V1: np.ndarray, F: np.ndarray) -> float:
    """MRMS (% of the bbox diagonal) between a mesh and a displaced copy of it (the same faces)."""
    return float(metrics.displaced_surface_distance(V0, V1, F, SAMPLES, seed=1)[0])


def text(rng: np.random.Generator, n: int) -> str:
    return "".join(rng.choice(list(ALPHABET), n))


# --------------------------------------------------------------------------- the key-free strip


def estimate(V: np.ndarray, F: np.ndarray) -> tuple[int, str]:
    """What the blind reader decides before it uses the pass phrase: the word length (bins) its energy shows,
    and the mesh it read ("suspect" or a coarser one)."""
    stats = blind.bin_statistics(V, F)
    return stats.n_word * blind.BINS_PER_BIT, stats.mesh


def flatten(V: np.ndarray, F: np.ndarray, n_bins: int, t: float) -> np.ndarray:
    """Every bin mean of r (``n_bins`` bins in the copy's own frame) moved from m to m - t (m - 1/2) by the push
    r + beta sin^2(pi r) (the bin mean is linear in beta; |beta| < 1/pi keeps the push monotone), each vertex
    moved to its new radius partly along the surface as the embedder moves it; (n, 3) float64."""
    fr, a = radial.frame_of(V, F, n_bins)
    bv = radial.bin_vertices(V, fr)
    inside = bv.bin >= 0
    bi = np.where(inside, bv.bin, 0)
    means = radial.BinMeans(bv.bin, a, n_bins)
    lift = np.sin(np.pi * bv.r) ** 2
    m, s = means(bv.r), means(lift)
    with np.errstate(invalid="ignore", divide="ignore"):
        beta = np.where(s > 0, -t * (m - 0.5) / s, 0.0)
    beta = np.clip(np.nan_to_num(beta), -radial.BETA_MAX, radial.BETA_MAX)
    r_new = np.where(inside, bv.r + beta[bi] * lift, bv.r)
    rho_new = fr.lo + fr.width * (bi + r_new)
    moved = radial.moved_to_radius(V, fr.centre, bv, rho_new, vertex_normals(V, F))
    return np.where(inside[:, None], moved, V)


def embedder_margin0(V: np.ndarray, F: np.ndarray, n_bins: int) -> np.ndarray:
    """The library's embedder asked for the opposite of every bin's sign as read, with margin 0."""
    fr, a = radial.frame_of(V, F, n_bins)
    stat, _ = radial.statistics_in(V, a, fr, [n_bins])[0]
    signs = -np.sign(np.nan_to_num(stat)).astype(np.int64)
    return radial.embed_signs(V, F, signs, 0.0)


# --------------------------------------------------------------------------- another pass phrase


def mark_unchecked(V: np.ndarray, F: np.ndarray, phrase: str, text: str, scale: float = 1.0):
    """The marking ``pmwm.embed`` makes before its self-check (an attacker with the code can skip the check): the
    word of ``text`` under ``phrase`` at the calibrated margin times ``scale`` (at most ``selfcheck.MAX_MARGIN``);
    (vertices (n, 3) float32-exact, margin)."""
    secret = word.derive_secret(phrase)
    payload, kind = word.payload_of(text, None, word.PAYLOAD_BITS[0], None)
    w = word.word_of(secret, kind, payload)
    n_bins = len(w) * blind.BINS_PER_BIT
    bit_of_bin, scramble = word.layout(secret, len(w), n_bins)
    signs = np.where((w ^ scramble)[bit_of_bin] == 1, 1, -1)
    host = radial.Host.of(V, F, n_bins)
    marked = radial.embed_signs(V, F, signs, blind.DEFAULT_ALPHA, host=host)
    alpha, marked = blind._calibrated(V, F, signs, blind.DEFAULT_ALPHA, marked, host)
    if scale != 1.0:
        alpha = min(scale * alpha, selfcheck.MAX_MARGIN)
        marked = radial.embed_signs(V, F, signs, alpha, host=host)
    return marked.astype(np.float32).astype(np.float64), float(alpha)


# --------------------------------------------------------------------------- key-free baselines


def noise_at(V: np.ndarray, F: np.ndarray, target: float, seed: int) -> tuple[np.ndarray, float]:
    """Gaussian white noise (per coordinate) scaled so that its MRMS is ``target``: (vertices, MRMS)."""
    rng = np.random.default_rng(seed)
    z = rng.standard_normal(V.shape) * metrics.bbox_diagonal(V) * 1e-4
    k = 1.0
    for _ in range(3):  # the MRMS is about linear in the amplitude
        got = mrms(V, V + k * z, F)
        if not got > 0 or abs(got / target - 1) < 0.02:
            break
        k *= target / got
    out = V + k * z
    return out, mrms(V, out, F)


def laplacian_at(V: np.ndarray, F: np.ndarray, target: float) -> tuple[np.ndarray, float, float]:
    """One uniform Laplacian step whose lambda (at most 1) gives the MRMS ``target``: (vertices, MRMS, lambda)."""
    lam = 0.05
    for _ in range(5):  # about linear in lambda for small steps
        out = attacks.smooth_laplacian(V, F, lam=lam, iterations=1)[0]
        got = mrms(V, out, F)
        if not got > 0 or abs(got / target - 1) < 0.02 or (lam >= 1.0 and got < target):
            break
        lam = float(min(1.0, lam * target / got))
    out = attacks.smooth_laplacian(V, F, lam=lam, iterations=1)[0]
    return out, mrms(V, out, F), lam


# --------------------------------------------------------------------------- reading


def read(V, F, phrase: str, payload: str) -> dict:
    """The verdict of the phrase on a copy: marked, p-value, and whether it confirms ``payload``."""
    t0 = time.perf_counter()
    try:
        v = pmwm.verify(V, F, passphrase=phrase)
    except PmwmError as exc:
        return {"marked": False, "p": 1.0, "payload_ok": False, "error": str(exc)[:200]}
    return {
        "marked": bool(v.marked),
        "p": float(v.p_value),
        "payload_ok": bool(v.marked and v.payload == payload),
        "payload_read": v.payload if v.marked else None,
        "verify_s": round(time.perf_counter() - t0, 2),
    }


def run_mesh(name: str, V: np.ndarray, F: np.ndarray, rng: np.random.Generator, strengths, emit) -> None:
    owner_phrase, owner_payload = f"owner {text(rng, 12)}", text(rng, 8)
    noise_seed = int(rng.integers(2**40))
    pirates = [(n, s, f"pirate {text(rng, 12)}", text(rng, n)) for n in PIRATE_BYTES for s in PIRATE_SCALES]
    base = {"mesh": name, "vertices": len(V), "owner_phrase": owner_phrase, "owner_payload": owner_payload}
    try:
        res = pmwm.embed(
            V, F, pmwm.EmbedOptions(scheme="blind", passphrase=owner_phrase, payload=owner_payload, progressive=False)
        )
    except PmwmError as exc:
        emit({**base, "attack": "embed", "refused": str(exc)[:200]})
        return
    M = res.vertices
    mark = mrms(V, M, F)
    base["mark_mrms"] = mark
    emit({**base, "attack": "none", "owner": read(M, F, owner_phrase, owner_payload)})
    n_bins, mesh_read = estimate(M, F)
    true_bins = 8 * len(owner_payload.encode()) + blind.word.CHECK_BITS
    base |= {"strip_bins": n_bins, "true_bins": true_bins, "estimate_mesh": mesh_read}
    print(
        f"{name}: {len(V)} vertices, marking MRMS {mark:.4f} %, estimated length {n_bins} (true {true_bins})",
        flush=True,
    )
    strips = [(f"strip t={t:g}", t, flatten(M, F, n_bins, t)) for t in strengths]
    strips.append(("embedder margin 0", None, embedder_margin0(M, F, n_bins)))
    for label, t, A in strips:
        d = mrms(M, A, F)
        emit(
            {
                **base,
                "attack": "strip",
                "variant": label,
                "t": t,
                "mrms": d,
                "multiple": d / mark,
                "owner": read(A, F, owner_phrase, owner_payload),
            }
        )
        An, dn = noise_at(M, F, d, noise_seed)
        emit(
            {
                **base,
                "attack": "noise",
                "variant": label,
                "t": t,
                "mrms": dn,
                "multiple": dn / mark,
                "owner": read(An, F, owner_phrase, owner_payload),
            }
        )
        Al, dl, lam = laplacian_at(M, F, d)
        emit(
            {
                **base,
                "attack": "laplacian",
                "variant": label,
                "t": t,
                "lambda": lam,
                "mrms": dl,
                "multiple": dl / mark,
                "owner": read(Al, F, owner_phrase, owner_payload),
            }
        )
    for k in BASELINE_MULTIPLES:  # the key-free baselines at the distortion the goal allows an attacker
        An, dn = noise_at(M, F, k * mark, noise_seed)
        emit(
            {
                **base,
                "attack": "noise",
                "variant": f"{k:g}x the marking",
                "t": None,
                "mrms": dn,
                "multiple": dn / mark,
                "owner": read(An, F, owner_phrase, owner_payload),
            }
        )
        Al, dl, lam = laplacian_at(M, F, k * mark)
        emit(
            {
                **base,
                "attack": "laplacian",
                "variant": f"{k:g}x the marking",
                "t": None,
                "lambda": lam,
                "mrms": dl,
                "multiple": dl / mark,
                "owner": read(Al, F, owner_phrase, owner_payload),
            }
        )
    for n_bytes, scale, phrase, payload in pirates:
        row = {**base, "attack": "overmark", "pirate_bytes": n_bytes, "scale": scale, "pirate_payload": payload}
        P, margin = mark_unchecked(M, F, phrase, payload, scale)
        try:  # the library's own embed (its self-check may refuse: the attacker then keeps the unchecked marking)
            opts = dict(scheme="blind", passphrase=phrase, payload=payload, progressive=False)
            got = pmwm.embed(M, F, pmwm.EmbedOptions(**opts, strength=None if scale == 1.0 else margin))
            P, margin = got.vertices, float(got.strength)
        except PmwmError as exc:
            row["refused"] = str(exc)[:200]
        d = mrms(M, P, F)
        emit(
            {
                **row,
                "margin": margin,
                "mrms": d,
                "multiple": d / mark,
                "owner": read(P, F, owner_phrase, owner_payload),
                "pirate": read(P, F, phrase, payload),
            }
        )


# --------------------------------------------------------------------------- the fragment


def fragment(rows: list[dict], heads: list[dict], files: list[str]) -> str:
    meshes = sorted({r["mesh"] for r in rows if "mark_mrms" in r})
    refused = sorted({r["mesh"] for r in rows if r.get("attack") == "embed"})
    marks = [r["mark_mrms"] for r in rows if r.get("attack") == "none"]
    own = [r for r in rows if r.get("attack") == "none"]
    est = {(r["mesh"], r["owner_phrase"]): (r["strip_bins"], r["true_bins"]) for r in rows if "strip_bins" in r}
    lines = [
        "## What an informed attacker does to the blind mark (no pass phrase)",
        "",
        f"Command: {len(heads)} run(s) on {MACHINE}, "
        + "; ".join(
            f"`{h['command']}` at commit {h['commit']}, {h['started']}, master seed {h['seed']}, corpus seeds "
            + ", ".join(f"{f} {s}" for f, s in h["corpus"].items())
            for h in heads
        )
        + ". Master seeds drawn fresh from os.urandom; every pass phrase, payload and noise seed of a run follows "
        "from its seed. Raw rows: " + ", ".join(f"`{f}`" for f in files) + ".",
        "",
        f"Copies: {len(own)}, marked by their owners on {', '.join(meshes)} (report-only data meshes and generated "
        "shapes, none tuned on)"
        + (
            f"; the owner's embed refused (its self-check, one line, nothing written) on {', '.join(refused)}"
            if refused
            else ""
        )
        + f". Owner: default settings, an 8-byte text payload; marking MRMS median {np.median(marks):.4f} % of the "
        f"bounding-box diagonal (range {min(marks):.4f}-{max(marks):.4f}); the untouched marked copy read with its "
        f"payload {sum(r['owner']['payload_ok'] for r in own)} of {len(own)}. The key-free length estimate "
        f"(the reader's energy) found the owner's word length on {sum(a == b for a, b in est.values())} of {len(est)}.",
        "",
        "Strip: every bin mean of r at the estimated length, in the copy's own frame, moved back towards 1/2 by a "
        "fraction t with the scheme's own push (t = 1 flattens); *embedder margin 0*: `radial.embed_signs` asked "
        "for the opposite signs with margin 0. Noise (Gaussian) and one Laplacian step are scaled to the same "
        "MRMS as the strip of the same row. Attack MRMS as a multiple of the marking's (median over meshes, range); "
        "cells: copies whose owner's verify still says marked with the owner's payload (p < 1e-6).",
        "",
        "| strip | attack MRMS / marking MRMS | owner reads after strip | after noise | after Laplacian |",
        "|---|---|---|---|---|",
    ]
    variants = list(dict.fromkeys(r["variant"] for r in rows if r.get("attack") == "strip"))
    for v in variants:
        cells = []
        for kind in ("strip", "noise", "laplacian"):
            got = [r for r in rows if r.get("attack") == kind and r["variant"] == v]
            cells.append(f"{sum(r['owner']['payload_ok'] for r in got)} of {len(got)}")
        mult = [r["multiple"] for r in rows if r.get("attack") == "strip" and r["variant"] == v]
        lines.append(f"| {v} | {np.median(mult):.2f} ({min(mult):.2f}-{max(mult):.2f}) | " + " | ".join(cells) + " |")
    for k in BASELINE_MULTIPLES:
        v = f"{k:g}x the marking"
        cells = []
        for kind in ("noise", "laplacian"):
            got = [r for r in rows if r.get("attack") == kind and r["variant"] == v]
            cells.append(f"{sum(r['owner']['payload_ok'] for r in got)} of {len(got)}")
        if any(c != "0 of 0" for c in cells):
            lines.append(f"| no strip: noise and Laplacian alone | {k:.2f} | - | " + " | ".join(cells) + " |")
    lam = [r["lambda"] for r in rows if r.get("attack") == "laplacian"]
    off = [r for r in rows if r.get("attack") in ("noise", "laplacian") and abs(r["mrms"] / target(rows, r) - 1) > 0.05]
    lines += [
        "",
        f"The Laplacian step's lambda ranged {min(lam):.3f}-{max(lam):.3f} (at most 1)"
        + (
            f"; {len(off)} baseline copies missed their MRMS by more than 5 % ("
            + ", ".join(f"{r['mesh']} {r['attack']} {r['variant']}: {r['multiple']:.2f}" for r in off)
            + ")"
            if off
            else "; every baseline copy within 5 % of its MRMS"
        )
        + ".",
        "",
        "Overmarking: the owner's marked copy marked again by a pirate with another pass phrase, at the default "
        "(calibrated) margin or twice it, by `pmwm.embed`; where its self-check refused (its own mark did not read "
        "back), marked as `pmwm.embed` marks before that check (an attacker with the code skips it). Cells: copies.",
        "",
        "| pirate payload, margin | pirate's pmwm.embed refused | pirate MRMS / marking MRMS | "
        "owner reads its payload | owner marked, other payload | pirate reads its payload |",
        "|---|---|---|---|---|---|",
    ]
    for nb in PIRATE_BYTES:
        for sc in PIRATE_SCALES:
            got = [r for r in rows if r.get("attack") == "overmark" and r["pirate_bytes"] == nb and r["scale"] == sc]
            done = got
            mult = [r["multiple"] for r in done]
            n = len(done)
            lines.append(
                f"| {nb} bytes, {sc:g}x | {sum('refused' in r for r in got)} of {n} | "
                + (f"{np.median(mult):.2f} ({min(mult):.2f}-{max(mult):.2f})" if mult else "-")
                + f" | {sum(r['owner']['payload_ok'] for r in done)} of {n}"
                + f" | {sum(r['owner']['marked'] and not r['owner']['payload_ok'] for r in done)} of {n}"
                + f" | {sum(r['pirate']['payload_ok'] for r in done)} of {n} |"
            )
    lines += ["", "The curve: ![curve](blind-attacks/curve.png)"]
    return "\n".join(lines) + "\n"


def target(rows: list[dict], r: dict) -> float:
    """The MRMS a baseline row aimed at: the strip's of its row, or a multiple of the marking's."""
    if r["variant"].endswith("x the marking"):
        return float(r["variant"].split("x")[0]) * r["mark_mrms"]
    return next(
        s["mrms"]
        for s in rows
        if s.get("attack") == "strip"
        and s["mesh"] == r["mesh"]
        and s["owner_phrase"] == r["owner_phrase"]
        and s["variant"] == r["variant"]
    )


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    style = {
        "strip": ("o-", "strip (key-free, targeted)"),
        "noise": ("s--", "Gaussian noise"),
        "laplacian": ("^:", "one Laplacian step"),
    }
    for kind, (fmt, label) in style.items():
        pts = [r for r in rows if r.get("attack") == kind and (r.get("t") is not None or kind != "strip")]
        groups = sorted(
            {r["variant"] for r in pts}, key=lambda v: np.median([r["multiple"] for r in pts if r["variant"] == v])
        )
        x = [np.median([r["multiple"] for r in pts if r["variant"] == v]) for v in groups]
        y = [np.mean([r["owner"]["payload_ok"] for r in pts if r["variant"] == v]) for v in groups]
        ax.plot(x, y, fmt, label=label)
        for r in pts:
            ax.plot(
                r["multiple"],
                r["owner"]["payload_ok"] + np.random.default_rng(zlib.crc32(r["mesh"].encode())).uniform(-0.03, 0.03),
                fmt[0],
                alpha=0.25,
                color=ax.lines[-1].get_color(),
                ms=3,
            )
    ax.axvline(3.0, color="grey", lw=0.8)
    ax.text(2.95, 0.45, "3x: the goal", fontsize=8, color="grey", ha="right")
    ax.set_xlabel("attack MRMS / marking MRMS (from the marked copy)")
    ax.set_ylabel("share of copies: owner reads its payload")
    ax.set_ylim(-0.08, 1.08)
    ax.set_title("Blind scheme: the owner's read against the attacker's distortion", fontsize=10)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(0.35, 0.7))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_outputs(paths: list[Path]) -> None:
    """The fragment and the plot from the JSON lines of one or more runs (each file starts with its run's row)."""
    lines = [json.loads(ln) for p in paths for ln in p.read_text().splitlines() if ln.strip()]
    heads = [r for r in lines if r.get("attack") == "run"]
    rows = [r for r in lines if r.get("attack") != "run"]
    RAW.mkdir(parents=True, exist_ok=True)
    plot(rows, RAW / "curve.png")
    write_section(NAME, fragment(rows, heads, [os.path.relpath(p, RESULTS.parents[1]) for p in paths]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default=",".join(MESHES), help="report-only data meshes ('' for none)")
    ap.add_argument("--families", default=",".join(FAMILIES), help="corpus families, one fresh shape each")
    ap.add_argument("--seed", type=int, default=None, help="the master seed (default: drawn fresh)")
    ap.add_argument("--strengths", default=",".join(map(str, STRENGTHS)))
    ap.add_argument("--out", default=str(RAW / "runs.jsonl"))
    ap.add_argument("--markdown-only", action="store_true")
    ap.add_argument("--also", nargs="*", default=[], help="more runs' JSON lines for the fragment and the plot")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.markdown_only:
        write_outputs([out, *map(Path, a.also)])
        return 0
    names = [m for m in a.meshes.split(",") if m]
    bad = [m for m in names if m not in split.REPORT_ONLY]
    if bad:
        raise SystemExit(f"not report-only meshes (tuning meshes are not reported on): {', '.join(bad)}")
    seed = split.fresh_seeds(1)[0] if a.seed is None else a.seed
    rng = np.random.default_rng(seed)
    fams = [f for f in a.families.split(",") if f]
    corpus_seeds = {f: int(rng.integers(2**62)) for f in fams}
    print(f"master seed {seed}; corpus seeds {corpus_seeds}", flush=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    fh = open(out, "w", encoding="utf-8")

    def emit(row: dict) -> None:
        fh.write(json.dumps(row) + "\n")
        fh.flush()
        os.fsync(fh.fileno())

    emit(
        {
            "attack": "run",
            "command": command(),
            "commit": commit(),
            "machine": machine(),
            "seed": seed,
            "corpus": corpus_seeds,
            "started": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        }
    )
    strengths = [float(x) for x in a.strengths.split(",")]
    items = [(m, *load(m)) for m in names] + [(f"{f}:{s}", *corpus.generate(f, s)) for f, s in corpus_seeds.items()]
    for name, V, F in items:
        run_mesh(name, np.asarray(V, np.float64), np.asarray(F, np.int64), rng, strengths, emit)
    fh.close()
    write_outputs([out, *map(Path, a.also)])
    return 0


if __name__ == "__main__":
    sys.exit(main())
