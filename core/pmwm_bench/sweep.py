"""Equal-distortion curves: every method at several strengths, BER against embedding MRMS.

A table at each method's default strength cannot say which method is more robust for the same
distortion (Cho II spends 0.012 % MRMS on the bunny, pmwm 0.019 %, pmwm-paper 0.022 %). The sweep
embeds each method at a grid of strengths chosen so that the four MRMS ranges overlap (about
0.005 % to 0.06 % of the bbox diagonal on the bunny and the dragon), measures the MRMS of every
marked mesh and its BER after five attacks, and compares the methods inside the MRMS range they all
cover (``compare_at_equal_mrms``).

Seeding: key k uses seed ``seed + k`` for its 64-bit payload (the same for every method and
strength), for the embedding, for the MRMS samples and (mixed with the attack's name) for the
attack, so every method at every strength faces the same attack realisations.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from pmwm import attacks as A
from pmwm import metrics as M

from .markdown import render_sweep
from .methods import DISPLAY, SWEEP_SCHEMES, SchemeMethod, scheme_of
from .models import load, resolve
from .plots import write_sweep_plots
from .protocols import attack_seed
from .runner import read_attacked
from .records import EqualMrms, SweepEmbedding, SweepPoint, SweepResults, SweepTrial
from .report import commit, machine, raw_folder, raw_folder_path, write_section

Progress = Optional[Callable[[str], None]]

N_BITS = 64
SECTION = "equal-distortion"
DEFAULT_SWEEP_MODELS: tuple[str, ...] = ("bunny", "dragon")


@dataclass(frozen=True)
class SweepAttack:
    """One attack of the sweep: ``key`` names its plot and JSON rows, ``label`` its table."""

    key: str
    label: str
    attack: str  # name in pmwm.attacks.ATTACKS
    params: Mapping[str, object]
    description: str


SWEEP_ATTACKS: tuple[SweepAttack, ...] = (
    SweepAttack(
        "noise",
        "noise 0.3 %",
        "noise_benchmark",
        {"amplitude": 0.003},
        "uniform noise in ±0.003·d̄ per coordinate (d̄ = mean vertex norm; benchmark protocol)",
    ),
    SweepAttack(
        "smoothing",
        "smoothing 30 it.",
        "smooth_laplacian",
        {"lam": 0.1, "iterations": 30},
        "30 iterations of Laplacian smoothing, lambda = 0.1",
    ),
    SweepAttack(
        "quantization",
        "quantization 8 bits",
        "quantize",
        {"bits": 8},
        "coordinates quantized to 8 bits per axis over the bounding box",
    ),
    SweepAttack(
        "cropping",
        "plane crop 50 %",
        "crop_plane",
        {"fraction": 0.5},
        "the 50 % of the vertices beyond a plane of random direction removed",
    ),
    SweepAttack(
        "simplification",
        "simplification 50 %",
        "simplify",
        {"ratio": 0.5},
        "quadric simplification (fast-simplification) removing 50 % of the faces",
    ),
)
#: attacks run only when named (``--attacks``): the paper protocol's heavy noise, where the paper
#: scheme, reading a same-order copy by index, is strongest
EXTRA_ATTACKS: tuple[SweepAttack, ...] = (
    SweepAttack(
        "paper-noise-0.03",
        "paper noise A = 0.03",
        "noise_paper",
        {"amplitude": 0.03},
        "uniform noise in ±0.03·Rmax per coordinate (Rmax = max vertex norm; paper protocol)",
    ),
    SweepAttack(
        "paper-noise-0.05",
        "paper noise A = 0.05",
        "noise_paper",
        {"amplitude": 0.05},
        "uniform noise in ±0.05·Rmax per coordinate (Rmax = max vertex norm; paper protocol)",
    ),
)
#: the attacks of ``--quick`` (both fast to read for every scheme)
QUICK_ATTACKS: tuple[str, ...] = ("noise", "quantization")

#: scheme -> strengths. Tuned on the bunny and the dragon (one key each, MRMS % of the bbox diagonal):
#: robust 0.5 -> 0.0047 / 0.0036, 2 -> 0.019, 6 -> 0.060 / 0.046; paper 0.5 -> 0.0040 / 0.0048,
#: 2 -> 0.027, 3.5 -> ~0.06 / 0.086; Cho I alpha 0.015 -> 0.0063 / 0.0090, 0.05 -> 0.018,
#: 0.16 -> ~0.058 / 0.058; Cho II alpha 0.03 -> 0.0057 / 0.0059, 0.05 -> 0.0091, 0.3 -> 0.056 / 0.057.
#: blind margin 0.02 -> 0.0043 (bunny), 0.04 -> 0.0074, 0.07 -> 0.013, 0.12 -> 0.021, 0.2 -> 0.039, 0.3 -> 0.069.
#: Each grid holds the scheme's default strength, so the sweep meets the robustness tables.
DEFAULT_GRID: dict[str, tuple[float, ...]] = {
    "robust": (0.5, 1.0, 2.0, 3.5, 6.0),
    "paper": (0.5, 0.8, 1.3, 2.0, 3.5),
    "cho1": (0.01, 0.025, 0.05, 0.09, 0.16),
    "cho2": (0.03, 0.05, 0.1, 0.18, 0.3),
    "blind": (0.02, 0.04, 0.07, 0.12, 0.25),
}
#: two strengths per scheme, for tests and smoke runs
QUICK_GRID: dict[str, tuple[float, ...]] = {
    "robust": (1.0, 3.5),
    "paper": (0.8, 2.0),
    "cho1": (0.025, 0.09),
    "cho2": (0.05, 0.18),
    "blind": (0.04, 0.12),
}


# ----------------------------------------------------------------------------------------------
# the comparison at equal MRMS


def compare_at_equal_mrms(
    curves: Mapping[str, tuple[np.ndarray, np.ndarray]],
    tolerance: float = 0.0,
    n_grid: int = 64,
    attack: str = "",
    model: str = "",
) -> EqualMrms:
    """Which method has the lowest BER at equal MRMS.

    curves: method -> (MRMS (S,), BER (S,)), one point per strength (means over the keys).
    Each curve is interpolated linearly in log MRMS (``np.interp`` on its points sorted by MRMS) at
    ``n_grid`` log-spaced MRMS values spanning the overlap of all curves' MRMS ranges, and averaged
    there. Nothing is extrapolated: outside its own range a method has no value, hence the overlap.
    """
    ranges = {m: (float(np.min(x)), float(np.max(x))) for m, (x, _y) in curves.items()}
    out = EqualMrms(attack, model, None, ranges, tolerance=tolerance)
    if not curves:
        return out
    lo = max(r[0] for r in ranges.values())
    hi = min(r[1] for r in ranges.values())
    if not (lo < hi and lo > 0):
        return out
    grid = np.log(np.geomspace(lo, hi, n_grid))  # (G,)
    names = list(curves)
    ber = np.empty((len(names), n_grid))  # (methods, G)
    for i, m in enumerate(names):
        x, y = (np.asarray(a, dtype=float) for a in curves[m])
        order = np.argsort(x, kind="stable")
        ber[i] = np.interp(grid, np.log(x[order]), y[order])
    mean = ber.mean(axis=1)
    order = np.argsort(mean, kind="stable")
    best = int(order[0])
    lowest = ber[best] <= ber.min(axis=0) + tolerance  # (G,)
    out.overlap = (float(lo), float(hi))
    out.mean_ber = {m: float(v) for m, v in zip(names, mean)}
    out.ranking = [names[i] for i in order]
    out.winner = names[best]
    out.tied = [names[i] for i in order if mean[i] - mean[best] <= tolerance]
    out.lowest_share = float(lowest.mean())
    return out


def aggregate(res: SweepResults) -> list[SweepPoint]:
    """Per (model, method, strength, attack): MRMS and BER mean / std over the keys."""
    emb: dict[tuple, list[float]] = {}
    for e in res.embeddings:
        emb.setdefault((e.model, e.method, e.strength), []).append(e.mrms_percent)
    trials: dict[tuple, list[SweepTrial]] = {}
    for t in res.trials:
        trials.setdefault((t.model, t.method, t.strength, t.attack), []).append(t)
    points = []
    for (model, method, strength, attack), ts in trials.items():
        mrms = np.array(emb.get((model, method, strength), [math.nan]))
        ber = np.array([t.ber for t in ts])
        chance = M.binomial_tail(sum(t.matches for t in ts), sum(t.n_bits for t in ts)) >= 0.01
        points.append(
            SweepPoint(
                model,
                method,
                strength,
                attack,
                float(mrms.mean()),
                float(mrms.std()),
                float(ber.mean()),
                float(ber.std()),
                len(ts),
                sum(1 for t in ts if t.failed),
                bool(chance),
            )
        )
    return points


def compare(res: SweepResults) -> list[EqualMrms]:
    """``compare_at_equal_mrms`` for every attack and model of ``res`` (its ``points``)."""
    keys = res.settings.get("keys", 1)
    tolerance = 1.0 / (N_BITS * max(keys, 1))  # one bit over all keys
    out = []
    for attack in res.settings["attacks"]:
        for model, info in res.models.items():
            if info.get("missing"):
                continue
            curves, at_chance = {}, []
            for method in res.settings["methods"]:
                pts = [p for p in res.points if (p.model, p.method, p.attack) == (model, method, attack)]
                if pts:
                    curves[method] = (np.array([p.mrms_mean for p in pts]), np.array([p.ber_mean for p in pts]))
                    if all(p.chance for p in pts):
                        at_chance.append(method)
            comparison = compare_at_equal_mrms(curves, tolerance, attack=attack, model=model)
            comparison.at_chance = at_chance
            out.append(comparison)
    return out


# ----------------------------------------------------------------------------------------------
# running


def sweep_attacks(names: Optional[Sequence[str]] = None) -> list[SweepAttack]:
    """The attacks named (keys of ``SWEEP_ATTACKS`` or ``EXTRA_ATTACKS``), those of ``SWEEP_ATTACKS``
    by default."""
    if names is None:
        return list(SWEEP_ATTACKS)
    by_key = {a.key: a for a in SWEEP_ATTACKS + EXTRA_ATTACKS}
    unknown = [n for n in names if n not in by_key]
    if unknown:
        raise ValueError(f"unknown sweep attack(s) {', '.join(unknown)}; use {', '.join(by_key)}")
    return [by_key[n] for n in names]


def run_sweep(
    models: Optional[Sequence[str]] = None,
    keys: int = 5,
    quick: bool = False,
    out: Optional[str] = "BENCHMARKS.md",
    progress: Progress = print,
    *,
    schemes: Optional[Sequence[str]] = None,
    grid: Optional[Mapping[str, Sequence[float]]] = None,
    attacks: Optional[Sequence[str]] = None,
    data_dir: Optional[str] = None,
    seed: int = 0,
    plots: bool = True,
    surface_samples: Optional[int] = None,
    command: Optional[str] = None,
    section: str = SECTION,
) -> SweepResults:
    """Run the equal-distortion sweep and write its section (and raw JSON, one PNG per attack) to ``out``.

    models:  catalogue names or mesh paths; default bunny and dragon (``quick``: bunny, which falls
             back to the copy packaged with pmwm). Missing ones are skipped with a note.
    keys:    payloads / seeds per point (``quick``: 1). schemes: default all five (``SWEEP_SCHEMES``).
    grid:    scheme -> strengths, overriding ``DEFAULT_GRID`` (``quick``: ``QUICK_GRID``) per scheme.
    attacks: keys of ``SWEEP_ATTACKS`` (``quick``: ``QUICK_ATTACKS``).
    """
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    if quick:
        keys = min(keys, 1)
        models = models or ("bunny",)
        attacks = attacks or QUICK_ATTACKS
    models = list(models or DEFAULT_SWEEP_MODELS)
    schemes = [scheme_of(s) for s in (schemes or SWEEP_SCHEMES)]
    base = QUICK_GRID if quick else DEFAULT_GRID
    strengths = {s: tuple(float(x) for x in (grid or {}).get(s, base[s])) for s in schemes}
    chosen = sweep_attacks(attacks)
    samples = surface_samples or (2000 if quick else 20000)
    res = SweepResults(
        settings={
            "command": command or "pmwm_bench.run_sweep(...)",
            "section": section,
            "commit": commit(),
            "machine": machine(),
            "keys": keys,
            "quick": quick,
            "seed": seed,
            "surface_samples": samples,
            "n_bits": N_BITS,
            "methods": [DISPLAY[s] for s in schemes],
            "schemes": schemes,
            "grid": {DISPLAY[s]: list(v) for s, v in strengths.items()},
            "attacks": [a.key for a in chosen],
            "attack_settings": {
                a.key: {"label": a.label, "attack": a.attack, "params": dict(a.params), "description": a.description}
                for a in chosen
            },
        }
    )

    for name in models:
        found = resolve(name, data_dir)
        if found.path is None:
            say(f"[sweep] {name}: mesh not found (set --data or PMWM_BENCH_DATA); skipped")
            res.models[found.label] = {"note": found.note, "missing": True}
            continue
        V, F = load(found.path)
        label = found.label
        res.models[label] = {"note": found.note, "path": str(found.path), "vertices": len(V), "faces": len(F)}
        diag = M.bbox_diagonal(V)
        say(
            f"[sweep] {label}: {len(V)} vertices, {keys} keys, "
            f"{sum(len(v) for v in strengths.values())} method-strength pairs, {len(chosen)} attacks"
        )
        for k in range(keys):
            key_seed = seed + k
            bits = np.random.default_rng(key_seed).integers(0, 2, N_BITS)  # (64,) the same for all methods
            for scheme in schemes:
                for strength in strengths[scheme]:
                    method = SchemeMethod(scheme, strength)
                    t0 = time.perf_counter()
                    marked, mkey = method.embed(V, F, bits, seed=key_seed)
                    secs = time.perf_counter() - t0
                    mrms, haus = M.surface_distance(V, F, marked, F, samples, seed=key_seed)
                    res.embeddings.append(
                        SweepEmbedding(
                            label,
                            method.name,
                            scheme,
                            strength,
                            k,
                            N_BITS,
                            mrms,
                            haus,
                            100.0 * M.vertex_rmse(V, marked) / diag,
                            secs,
                        )
                    )
                    for a in chosen:
                        va, fa = A.ATTACKS[a.attack](
                            marked, F, seed=attack_seed(key_seed, "sweep:" + a.key, 0), **dict(a.params)
                        )
                        got, failed = read_attacked(method, va, fa, mkey, N_BITS)
                        if got is None:
                            res.trials.append(
                                SweepTrial(label, method.name, strength, k, a.key, N_BITS, N_BITS // 2, 0.5, failed)
                            )
                        else:
                            res.trials.append(
                                SweepTrial(
                                    label,
                                    method.name,
                                    strength,
                                    k,
                                    a.key,
                                    N_BITS,
                                    int(np.sum(got == bits)),
                                    M.ber(bits, got),
                                )
                            )
                    say(
                        f"[sweep] {label} key {k + 1}/{keys}: {method.name} at {strength:g}, MRMS {mrms:.4f} % "
                        f"({time.perf_counter() - t_start:.0f} s)"
                    )

    res.settings["seconds"] = round(time.perf_counter() - t_start, 1)
    res.points = aggregate(res)
    res.comparisons = compare(res)
    if out:
        res.settings["raw"] = raw_folder_path(out, section).name
    res.markdown = render_sweep(res)
    if out:
        out_path = Path(out)
        write_section(out_path, section, res.markdown)
        folder = raw_folder(out_path, section)
        raw = {
            "settings": res.settings,
            "models": res.models,
            "embeddings": [asdict(e) for e in res.embeddings],
            "trials": [asdict(t) for t in res.trials],
            "points": [asdict(p) for p in res.points],
            "comparisons": [asdict(c) for c in res.comparisons],
        }
        (folder / "sweep.json").write_text(json.dumps(raw, indent=0, default=float) + "\n", encoding="utf-8")
        if plots:
            written = write_sweep_plots(res, folder)
            if written:
                say(f"[sweep] plots: {', '.join(p.name for p in written)}")
        say(f"[sweep] wrote {out_path} ({res.settings['seconds']} s)")
    return res


__all__ = [
    "DEFAULT_GRID",
    "DEFAULT_SWEEP_MODELS",
    "EqualMrms",
    "QUICK_ATTACKS",
    "QUICK_GRID",
    "SECTION",
    "SWEEP_ATTACKS",
    "EXTRA_ATTACKS",
    "SweepAttack",
    "SweepEmbedding",
    "SweepPoint",
    "SweepResults",
    "SweepTrial",
    "aggregate",
    "compare",
    "compare_at_equal_mrms",
    "run_sweep",
    "sweep_attacks",
]
