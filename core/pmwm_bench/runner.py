"""The robustness benchmark run end to end: both protocols, every method, mean +- std over keys.

``run_bench(models, keys=10, quick=False, out="BENCHMARKS.md")`` embeds random payloads with every
method (pmwm's robust and paper schemes, Cho et al. 2007 methods I and II, all through
``pmwm.embed`` / ``pmwm.verify``), attacks the marked meshes with both protocols and reports mean
+- std over the keys:

- Paper protocol, 50-bit payloads: Table 1 (VSNR at M = 50/80/120 carriers; pmwm's schemes only),
  Tables 2-4 (correlation, eq. 6, under uniform noise, Laplacian smoothing lambda 0.03 and
  cropping), with the paper's published numbers beside ours and, for noise, the matched-filter
  bound of each method at the distortion it was measured with.
- Benchmark protocol (Wang, Lavoue, Denis, Baskurt 2010), 64-bit payloads: BER under noise,
  smoothing (lambda 0.1), quantization, similarity, reordering, plane cropping, simplification and
  subdivision, with the embedding distortion as MRMS / Hausdorff (% of the bbox diagonal) and VSNR.
  MSDM is not implemented.

Reading of "M refinements" (Table 1): the paper performs as many carrier collapses as bits, so M is
the number of carriers; we embed an M-bit payload and measure the full-resolution marked mesh
against the original (centred and uncentred VSNR).

Each key k uses seed ``seed + k`` for the payload, the embedding and (mixed with the setting) the
attack, so all methods face the same attack realisations.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

import numpy as np

import pmwm
from pmwm import attacks as A
from pmwm import metrics as M
from pmwm.validate import parse_bits

from .markdown import render_markdown
from .methods import SchemeMethod, default_methods
from .models import DEFAULT_MODELS, load, resolve
from .plots import write_plots
from .protocols import Setting, attack_seed, benchmark_settings, paper_settings
from .records import BenchResults, Distortion, Trial
from .report import commit, raw_folder, raw_folder_path, write_section

Progress = Optional[Callable[[str], None]]


def _norms(v: np.ndarray) -> np.ndarray:
    """(n,) distances of the vertices (n, 3) to their mean."""
    return np.linalg.norm(v - v.mean(axis=0), axis=1)


def measure_distortion(
    protocol: str,
    model: str,
    method: str,
    key: int,
    bits: np.ndarray,
    V: np.ndarray,
    F: np.ndarray,
    marked: np.ndarray,
    seconds: float,
    samples: int,
    seed: Optional[int],
) -> Distortion:
    """The distortion of ``marked`` (n, 3) against the original (V (n, 3), F (m, 3)); MRMS and Hausdorff
    from ``samples`` surface samples each way (0: skipped, left NaN)."""
    diag = M.bbox_diagonal(V)
    norms = _norms(marked)
    d = Distortion(
        protocol=protocol,
        model=model,
        method=method,
        key=key,
        n_bits=len(bits),
        vsnr=M.vsnr(V, marked),
        vsnr_uncentred=M.vsnr(V, marked, centred=False),
        psnr=M.psnr(V, marked),
        rmse_percent=100.0 * M.vertex_rmse(V, marked) / diag,
        energy_per_bit=M.energy_per_bit(V, marked, len(bits)),
        r_max=float(norms.max()),
        d_bar=float(norms.mean()),
        embed_seconds=seconds,
    )
    if samples:
        d.mrms_percent, d.hausdorff_percent = M.surface_distance(V, F, marked, F, samples, seed=seed)
    return d


def read_attacked(
    method: SchemeMethod, va: np.ndarray, fa: np.ndarray, key: Any, n_bits: int
) -> tuple[Optional[np.ndarray], str]:
    """(bits read (n_bits,), "") from an attacked copy, or (None, the reason) when the method cannot
    read it at all (a ``pmwm.PmwmError``, or a payload of another length)."""
    try:
        got = parse_bits(method.extract(va, fa, key), erasures=True)  # an erasure (NaN) never matches
        if len(got) != n_bits:
            raise pmwm.PmwmError(f"extracted {len(got)} bits, expected {n_bits}")
    except pmwm.PmwmError as exc:
        return None, str(exc)
    return got, ""


def run_attacks(
    protocol: str,
    model: str,
    method: SchemeMethod,
    key_idx: int,
    key_seed: int,
    bits: np.ndarray,
    marked: np.ndarray,
    F: np.ndarray,
    mkey: Any,
    settings: dict[str, list[Setting]],
    out: list[Trial],
) -> None:
    """Attack ``marked`` with every setting, read it back, append one ``Trial`` each to ``out``."""
    for group, items in settings.items():
        for i, (label, _value, name, params) in enumerate(items):
            va, fa = A.ATTACKS[name](marked, F, seed=attack_seed(key_seed, group, i), **params)
            got, failed = read_attacked(method, va, fa, mkey, len(bits))
            if got is None:  # unreadable: counted as chance
                trial = Trial(
                    protocol, model, method.name, group, label, key_idx, len(bits), len(bits) // 2, 0.5, 0.0, failed
                )
            else:
                trial = Trial(
                    protocol,
                    model,
                    method.name,
                    group,
                    label,
                    key_idx,
                    len(bits),
                    int(np.sum(got == bits)),
                    M.ber(bits, got),
                    M.correlation(bits, got),
                )
            out.append(trial)


def run_bench(
    models: Optional[Sequence[str]] = None,
    keys: int = 10,
    quick: bool = False,
    out: Optional[str] = "BENCHMARKS.md",
    progress: Progress = print,
    *,
    methods: Optional[Sequence[SchemeMethod]] = None,
    data_dir: Optional[str] = None,
    seed: int = 0,
    plots: bool = True,
    surface_samples: Optional[int] = None,
    command: Optional[str] = None,
    section: str = "robustness",
) -> BenchResults:
    """Run both protocols and write the markdown report (and raw JSON, PNG plots) to ``out``.

    models:  catalogue names (``pmwm_bench.models.CATALOGUE``) or mesh paths; default the paper's
             three models and the Igea, ``quick``: bunny only. Named models are looked up in
             ``data_dir`` or $PMWM_BENCH_DATA (the bunny falls back to the copy shipped with pmwm);
             missing ones are skipped with a note.
    keys:    payloads/seeds per model (``quick``: at most 3).
    methods: ``SchemeMethod``s (or objects with ``name``, ``scheme``, ``strength``,
             ``embed(v, f, bits, seed) -> (marked, key)`` and ``extract(v, f, key) -> bits``);
             default pmwm, pmwm-paper, Cho I, Cho II.
    out:     markdown path (its section ``section`` is rewritten; a file named ``<section>.md`` is the section
             alone, as in benchmarks/results/), None to skip writing.
    """
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    if quick:
        keys = min(keys, 3)
        models = models or ("bunny",)
    models = list(models or DEFAULT_MODELS)
    methods = list(methods) if methods is not None else default_methods()
    samples = surface_samples or (5000 if quick else 20000)
    p_set, b_set = paper_settings(quick), benchmark_settings(quick)
    robust = [m for m in methods if getattr(m, "scheme", None) == "robust"]
    res = BenchResults(
        settings={
            "command": command or "pmwm_bench.run_bench(...)",
            "section": section,
            "commit": commit(),
            "keys": keys,
            "quick": quick,
            "seed": seed,
            "surface_samples": samples,
            "methods": [m.name for m in methods],
            "strength": robust[0].effective_strength if robust else 2.0,
        }
    )
    ours = [m for m in methods if getattr(m, "is_pmwm", False)]

    for name in models:
        found = resolve(name, data_dir)
        label = found.label
        if found.path is None:
            say(f"[bench] {name}: mesh not found (set data_dir or PMWM_BENCH_DATA); skipped")
            res.models[label] = {"note": found.note, "missing": True, "paper_model": found.paper_model}
            continue
        V, F = load(found.path)
        res.models[label] = {
            "note": found.note,
            "path": str(found.path),
            "vertices": len(V),
            "faces": len(F),
            "paper_model": found.paper_model,
        }
        say(f"[bench] {label}: {len(V)} vertices, {len(F)} faces, {keys} keys")
        for k in range(keys):
            key_seed = seed + k
            rng = np.random.default_rng(key_seed)
            bits = {n: rng.integers(0, 2, n) for n in (50, 64, 80, 120)}
            # Table 1: VSNR with M carriers (pmwm's schemes); M = 50 is reused for the paper protocol
            marked50 = {}
            for scheme in ours:
                for m_bits in (50, 80, 120):
                    t0 = time.perf_counter()
                    mv, mkey = scheme.embed(V, F, bits[m_bits], seed=key_seed)
                    d = measure_distortion(
                        "table1", label, scheme.name, k, bits[m_bits], V, F, mv, time.perf_counter() - t0, 0, None
                    )
                    res.distortions.append(d)
                    if m_bits == 50:
                        marked50[scheme.name] = (mv, mkey, d.embed_seconds)
            for method in methods:
                # paper protocol, 50 bits
                if method.name in marked50:
                    mv, mkey, secs = marked50[method.name]
                else:
                    t0 = time.perf_counter()
                    mv, mkey = method.embed(V, F, bits[50], seed=key_seed)
                    secs = time.perf_counter() - t0
                res.distortions.append(
                    measure_distortion("paper", label, method.name, k, bits[50], V, F, mv, secs, samples, key_seed)
                )
                run_attacks("paper", label, method, k, key_seed, bits[50], mv, F, mkey, p_set, res.trials)
                # benchmark protocol, 64 bits
                t0 = time.perf_counter()
                mv, mkey = method.embed(V, F, bits[64], seed=key_seed)
                secs = time.perf_counter() - t0
                res.distortions.append(
                    measure_distortion("benchmark", label, method.name, k, bits[64], V, F, mv, secs, samples, key_seed)
                )
                run_attacks("benchmark", label, method, k, key_seed, bits[64], mv, F, mkey, b_set, res.trials)
            say(f"[bench] {label}: key {k + 1}/{keys} done ({time.perf_counter() - t_start:.0f} s)")

    res.settings["seconds"] = round(time.perf_counter() - t_start, 1)
    if out:
        res.settings["raw"] = raw_folder_path(out, section).name
    res.markdown = render_markdown(res, p_set, b_set)
    if out:
        # the report is the ``section`` of ``out`` (other benchmarks keep theirs);
        # raw trials and plots go to ``<out stem>-<section>/`` beside it
        out_path = Path(out)
        write_section(out_path, section, res.markdown)
        raw_dir = raw_folder(out_path, section)
        raw = {
            "settings": res.settings,
            "models": res.models,
            "trials": [asdict(t) for t in res.trials],
            "distortions": [asdict(d) for d in res.distortions],
        }
        (raw_dir / "trials.json").write_text(json.dumps(raw, indent=0, default=float) + "\n", encoding="utf-8")
        if plots:
            written = write_plots(res, p_set, b_set, raw_dir, "correlation")
            if written:
                say(f"[bench] plots: {', '.join(p.name for p in written)}")
        say(f"[bench] wrote {out_path} ({res.settings['seconds']} s)")
    return res


__all__ = ["measure_distortion", "read_attacked", "run_attacks", "run_bench"]
