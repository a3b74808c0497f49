"""Markdown of the reports: the robustness section (both protocols) and the equal-distortion section.

The robustness section's layout (headings, tables, column names) is what the report's robustness
fragments hold and the lead re-generates; change it only on purpose. Sections are rendered one heading level below the
report file's title.
"""

from __future__ import annotations

import math
import os
import platform
from datetime import datetime, timezone
from typing import Callable, Optional, Sequence

import numpy as np

from pmwm import metrics as M

from .methods import DISPLAY, STRENGTH_MEANING
from .published import CHO_PUBLISHED, PAPER_TABLE1, PAPER_TABLES, paper_value
from .records import BenchResults, Cell, Distortion, SweepResults, cell, mean_std, select


def fmt(mean: float, std: float, digits: int = 2) -> str:
    """ "mean ± std" with ``digits`` decimals ("inf" / "n/a" for a non-finite mean)."""
    if not math.isfinite(mean):
        return "inf" if mean > 0 else "n/a"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


def fmt_cell(c: Optional[Cell], what: str) -> str:
    """A table cell: correlation (``what`` "corr") or BER, "~" when at chance, the unreadable count."""
    if c is None:
        return "n/a"
    s = fmt(c.corr_mean, c.corr_std) if what == "corr" else fmt(c.ber_mean, c.ber_std)
    if c.chance:
        s += " ~"
    if c.failed:
        s += f" ({c.failed}/{c.n} unreadable)"
    return s


def table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """The lines of a markdown table."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(str(x) for x in r) + " |" for r in rows]
    return lines


def bound_cell(res: BenchResults, model: str, method: str, amp_sigma: Callable[[Distortion], float]) -> str:
    """Mean matched-filter bound of a method's paper-protocol embeddings at noise sigma ``amp_sigma(d)``."""
    ds = select(res.distortions, protocol="paper", model=model, method=method)
    if not ds:
        return "–"
    vals = [M.matched_filter_bound(d.energy_per_bit, amp_sigma(d)) for d in ds]
    return f"{np.mean(vals):.2f}"


def distortion_table(
    res: BenchResults,
    protocol: str,
    models: Sequence[str],
    methods: Sequence[str],
    extra: dict[str, Callable[[list], str]],
) -> list[str]:
    """One row per model and method with the embedding distortion of ``protocol``'s marked meshes (mean
    ± std over the keys): MRMS, Hausdorff, vertex RMSE, VSNR, then the ``extra`` columns (header ->
    cell from that row's distortion records)."""
    base = {
        "MRMS (% diag)": lambda ds: fmt(*mean_std([d.mrms_percent for d in ds]), 4),
        "Hausdorff (% diag)": lambda ds: fmt(*mean_std([d.hausdorff_percent for d in ds]), 3),
        "vertex RMSE (% diag)": lambda ds: fmt(*mean_std([d.rmse_percent for d in ds]), 4),
        "VSNR (dB)": lambda ds: fmt(*mean_std([d.vsnr for d in ds]), 1),
    }
    columns = {**base, **extra}
    rows = []
    for model in models:
        for method in methods:
            ds = select(res.distortions, protocol=protocol, model=model, method=method)
            if ds:
                rows.append([model, method, *(cell(ds) for cell in columns.values())])
    return table(["Model", "Method", *columns], rows)


def render_markdown(res: BenchResults, p_set: dict, b_set: dict) -> str:
    """The robustness section of a ``run_bench`` run (``p_set`` / ``b_set``: the settings it ran)."""
    st = res.settings
    methods = st["methods"]
    lines = [
        "# Robustness: both protocols, pmwm against Cho et al. 2007",
        "",
        f"Command: `{st.get('command', 'pmwm_bench.run_bench')}`"
        + (f", commit {st['commit']}" if st.get("commit") else "")
        + f". Generated on {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC "
        f"({platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"numpy {np.__version__}); {st['keys']} keys per model{' (quick mode)' if st['quick'] else ''}, "
        f"seeds {st['seed']}..{st['seed'] + st['keys'] - 1}, {st.get('seconds', 0)} s. "
        f"Methods: {', '.join(methods)}. Raw per-trial results and plots: the folder "
        f"`{st.get('raw', '<report name>-' + st.get('section', 'robustness'))}/` "
        "beside this file (`trials.json`, `correlation_*.png`).",
        "",
        "Cells are mean ± std over the keys. **~** marks a cell not distinguishable from chance: pooling all keys' "
        "bits, the number of correct bits is not significant against Binomial(bits, 1/2) at p < 0.01. "
        "Cho = Cho, Prost, Jung 2007 (IEEE TSP), methods I and II, alpha = 0.05, strength step 0.001. "
        f"pmwm = our default (robust) scheme at strength {st.get('strength', 2.0):g}; pmwm-paper = our "
        "implementation of the paper's scheme at strength 2 (its mu ± 2 sigma).",
        "",
        "## Models",
        "",
    ]
    rows = []
    for name, info in res.models.items():
        counts = "not found" if info.get("missing") else f"{info['vertices']:,} / {info['faces']:,}"
        rows.append([name, counts, info.get("paper_model") or "–", info["note"]])
    lines += table(["Model", "V / F", "Paper model", "Note"], rows)
    present = [m for m, i in res.models.items() if not i.get("missing")]

    # ---------------- paper protocol
    lines += [
        "",
        "## Paper protocol (50-bit payloads)",
        "",
        "Uniform noise in ±A·Rmax per coordinate (Rmax = max vertex norm about the vertex mean); "
        "Laplacian smoothing, uniform weights, lambda = 0.03; cropping = a connected geodesic patch of "
        "the given share of vertices removed. Correlation = eq. 6 (Pearson; for a constant sequence "
        "1 − 2·BER).",
        "",
    ]
    t1 = select(res.distortions, protocol="table1")
    if t1:
        lines += [
            "### Table 1: VSNR (dB) of the marked mesh with M carriers",
            "",
            "M = number of carriers (= bits; the paper collapses one edge per carrier). Full-resolution "
            "marked mesh vs the original; centred VSNR (signal about the vertex mean) and uncentred "
            "(about the origin). The paper's 104–137 dB cannot come from its own mu ± 2 sigma rule with "
            "the usual VSNR definition (DESIGN section 6); we report what we measure.",
            "",
        ]
        rows = []
        for model in present:
            pm = res.models[model]["paper_model"]
            for method in methods:
                if not select(t1, model=model, method=method):
                    continue
                row = [model + (" (Venus stand-in)" if pm == "venus" else ""), method]
                for j, m_bits in enumerate((50, 80, 120)):
                    ds = select(t1, model=model, method=method, n_bits=m_bits)
                    c = mean_std([d.vsnr for d in ds])
                    u = mean_std([d.vsnr_uncentred for d in ds])
                    paper = f"{PAPER_TABLE1[pm][j]:.2f}" if pm in PAPER_TABLE1 else "–"
                    row += [fmt(*c, 1), fmt(*u, 1), paper]
                rows.append(row)
        hdr = ["Model", "Method"]
        for m_bits in (50, 80, 120):
            hdr += [f"M={m_bits} centred", f"M={m_bits} uncentred", f"M={m_bits} paper"]
        lines += table(hdr, rows)

    lines += ["", "### Distortion of the 50-bit marked meshes", ""]
    lines += distortion_table(
        res,
        "paper",
        present,
        methods,
        {
            "E/N": lambda ds: f"{np.mean([d.energy_per_bit for d in ds]):.3g}",
            "embed (s)": lambda ds: f"{np.mean([d.embed_seconds for d in ds]):.2f}",
        },
    )
    lines += ["", f"MRMS / Hausdorff from {st['surface_samples']} area-uniform samples per surface, both directions."]

    titles = {
        "noise": "Table 2: additive uniform noise (correlation)",
        "smoothing": "Table 3: Laplacian smoothing, lambda = 0.03 (correlation)",
        "cropping": "Table 4: cropping (correlation)",
    }
    paper_tables = PAPER_TABLES
    for group, items in p_set.items():
        for model in present:
            pm = res.models[model]["paper_model"]
            stand_in = " — Venus stand-in, the paper's column is its Venus" if pm == "venus" else ""
            lines += ["", f"### {titles[group]} — {model}{stand_in}", ""]
            hdr = ["Setting"]
            for method in methods:
                hdr.append(method)
                if group == "noise":
                    hdr.append(f"bound {method}")
            hdr += ["paper: proposed"] + (["paper: Cho"] if group != "cropping" else [])
            rows = []
            for label, value, _, _ in items:
                row = [label]
                for method in methods:
                    row.append(
                        fmt_cell(
                            cell(
                                select(
                                    res.trials, protocol="paper", model=model, method=method, group=group, label=label
                                )
                            ),
                            "corr",
                        )
                    )
                    if group == "noise":
                        row.append(bound_cell(res, model, method, lambda d, a=value: a * d.r_max / math.sqrt(3.0)))
                row.append(paper_value(paper_tables[group], value, pm, 0))
                if group != "cropping":
                    row.append(paper_value(paper_tables[group], value, pm, 1))
                rows.append(row)
            lines += table(hdr, rows)
            if group == "noise":
                lines += [
                    "",
                    "bound = matched-filter limit 1 − 2·Q(√(E/N)/σ) at the method's own embedding "
                    'energy E/N (table above), σ = A·Rmax/√3 (DESIGN section 6, "The limit").',
                ]

    # ---------------- benchmark protocol
    lines += [
        "",
        "## Benchmark protocol (Wang, Lavoué, Denis, Baskurt 2010; 64-bit payloads, BER)",
        "",
        "Noise ±A·d̄ per coordinate (d̄ = mean vertex norm); smoothing lambda = 0.1; quantization per "
        "axis over the bounding box; similarity = translation ±5·d̄, random rotation, scale in "
        "[0.1, 10] (log-uniform); reordering of vertices, faces and face corners; cropping by a random "
        "plane; simplification by fast-simplification (quadric); one subdivision step. MSDM is not "
        "implemented.",
        "",
        "### Distortion of the 64-bit marked meshes",
        "",
    ]
    lines += distortion_table(
        res, "benchmark", present, methods, {"PSNR (dB)": lambda ds: fmt(*mean_std([d.psnr for d in ds]), 1)}
    )
    lines += [
        "",
        f"MRMS / Hausdorff from {st['surface_samples']} area-uniform samples per surface, both directions. "
        "Published anchor: Cho et al. on the benchmark's Venus at MRMS 0.008 % (perceptual protocol).",
    ]
    for model in present:
        pm = res.models[model]["paper_model"]
        lines += ["", f"### BER — {model}" + (" (Venus stand-in)" if pm == "venus" else ""), ""]
        hdr = ["Attack", "Setting"] + list(methods) + ["bound " + m for m in methods] + ["Cho 2007 published (Venus)"]
        rows = []
        for group, items in b_set.items():
            for label, value, _, _ in items:
                row = [group, label]
                for method in methods:
                    row.append(
                        fmt_cell(
                            cell(
                                select(
                                    res.trials,
                                    protocol="benchmark",
                                    model=model,
                                    method=method,
                                    group=group,
                                    label=label,
                                )
                            ),
                            "ber",
                        )
                    )
                for method in methods:
                    if group == "noise":
                        ds = select(res.distortions, protocol="benchmark", model=model, method=method)
                        vals = [
                            (1 - M.matched_filter_bound(d.energy_per_bit, value * d.d_bar / math.sqrt(3))) / 2
                            for d in ds
                        ]
                        row.append(f"{np.mean(vals):.2f}" if vals else "–")
                    else:
                        row.append("–")
                pub = CHO_PUBLISHED.get((group, value))
                row.append("–" if pub is None else f"{pub:g}")
                rows.append(row)
        lines += table(hdr, rows)
    lines += [
        "",
        "bound (noise rows) = lowest BER any detector can reach, Q(√(E/N)/σ), σ = A·d̄/√3, at the "
        "method's own embedding energy.",
    ]
    # a section of the report: one heading level below the file's title
    lines = ["#" + ln if ln.startswith("#") else ln for ln in lines]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------
# the equal-distortion sweep


def _mrms_range(r: tuple[float, float]) -> str:
    return f"{r[0]:.4f}–{r[1]:.4f} %"


def verdict_line(label: str, comparisons: Sequence) -> str:
    """The one line saying, per model, which method has the lowest BER at equal MRMS under one attack
    (computed by ``sweep.compare_at_equal_mrms``; ``comparisons``: its ``EqualMrms`` per model)."""
    parts = []
    for c in comparisons:
        chance = f"; at chance at every strength: {', '.join(c.at_chance)}" if c.at_chance else ""
        if c.ranges and set(c.at_chance) >= set(c.ranges):
            parts.append(f"{c.model}: none: every method reads at chance at every strength")
            continue
        if c.overlap is None:
            ranges = ", ".join(f"{m} {_mrms_range(r)}" for m, r in c.ranges.items())
            parts.append(f"{c.model}: no overlap of the methods' MRMS ranges ({ranges})")
            continue
        bers = ", ".join(f"{m} {c.mean_ber[m]:.3f}" for m in c.ranking)
        if len(c.tied) > 1:
            names = [f"**{m}**" for m in c.tied]
            parts.append(
                f"{c.model}: tie between {', '.join(names[:-1])} and {names[-1]} "
                f"(over MRMS {_mrms_range(c.overlap)}, mean BER {bers}{chance})"
            )
        else:
            parts.append(
                f"{c.model}: **{c.winner}** (over MRMS {_mrms_range(c.overlap)}, mean BER {bers}; "
                f"lowest on {100 * c.lowest_share:.0f} % of the overlap{chance})"
            )
    decided = [
        c for c in comparisons if c.overlap is not None and len(c.tied) == 1 and not set(c.at_chance) >= set(c.ranges)
    ]
    winners = {c.winner for c in decided}
    lead = ""
    if len(comparisons) > 1 and len(decided) == len(comparisons) and len(winners) == 1:
        lead = f"**{winners.pop()}** on every model. "
    return f"- **{label}**: {lead}" + "; ".join(parts) + "."


def render_sweep(res: SweepResults) -> str:
    """The equal-distortion section: header (command, commit, machine), how the winner is called, one
    verdict line per attack, and one table per attack (method, strength, MRMS and BER per model)."""
    st = res.settings
    keys = st["keys"]
    present = [m for m, info in res.models.items() if not info.get("missing")]
    grids = "; ".join(
        f"{DISPLAY[s]} ({STRENGTH_MEANING[s]}) {', '.join(f'{x:g}' for x in st['grid'][DISPLAY[s]])}"
        for s in st["schemes"]
    )
    lines = [
        "## Equal distortion: BER against embedding MRMS, every method at several strengths",
        "",
        f"Command: `{st['command']}`, commit {st['commit']}. Machine: {st['machine']}. "
        f"{keys} key{'s' if keys != 1 else ''} per point{' (quick mode)' if st['quick'] else ''}, seeds "
        f"{st['seed']}..{st['seed'] + keys - 1}: per key one {st['n_bits']}-bit random payload and one realisation "
        "of each attack, the same for every method and strength; "
        f"{st.get('seconds', 0)} s. Raw results and plots: the folder "
        f"`{st.get('raw', '<report name>-' + st['section'])}/` beside "
        "this file (`sweep.json`, `ber_vs_mrms_<attack>.png`).",
        "",
        f"Strengths: {grids}. MRMS = embedding distortion, % of the bounding-box diagonal, from "
        f"{st['surface_samples']} area-uniform samples per surface in both directions. BER and MRMS are "
        "mean ± std over the keys; **~** marks a BER not distinguishable from chance (pooling all keys' bits, the "
        "correct bits are not significant against Binomial(bits, 1/2) at p < 0.01); a copy a method cannot "
        'read at all counts as BER 0.5 ("unreadable").',
        "",
        "Attacks: " + "; ".join(f"{a['label']}: {a['description']}" for a in st["attack_settings"].values()) + ".",
        "",
        "### Which method has the lowest BER at equal MRMS",
        "",
        "Computed per model: each method's mean BER is interpolated linearly in log MRMS between its "
        "strengths at 64 log-spaced MRMS values spanning the overlap of all methods' MRMS ranges (never "
        "extrapolated) and averaged there; the lowest average wins, and methods within one bit over all keys "
        f"(1/({st['n_bits']}·{keys}) = {1 / (st['n_bits'] * keys):.4f}) of it tie with it.",
        "",
    ]
    for attack in st["attacks"]:
        comps = [c for c in res.comparisons if c.attack == attack]
        lines.append(verdict_line(st["attack_settings"][attack]["label"], comps))
    for attack in st["attacks"]:
        a = st["attack_settings"][attack]
        lines += ["", f"### {a['label']}: BER against MRMS", ""]
        hdr = ["Method", "Strength"]
        for model in present:
            hdr += [f"{model} MRMS (% diag)", f"{model} BER"]
        rows = []
        for method in st["methods"]:
            for strength in st["grid"][method]:
                row = [method, f"{strength:g}"]
                for model in present:
                    p = next(
                        (
                            p
                            for p in res.points
                            if (p.model, p.method, p.strength, p.attack) == (model, method, strength, attack)
                        ),
                        None,
                    )
                    if p is None:
                        row += ["n/a", "n/a"]
                        continue
                    ber = (
                        fmt(p.ber_mean, p.ber_std, 3)
                        + (" ~" if p.chance else "")
                        + (f" ({p.failed}/{p.n} unreadable)" if p.failed else "")
                    )
                    row += [fmt(p.mrms_mean, p.mrms_std, 4), ber]
                rows.append(row)
        lines += table(hdr, rows)
    return "\n".join(lines) + "\n"
