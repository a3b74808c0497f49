"""PNG plots of the reports, drawn with matplotlib when it is importable (the bench extra).

matplotlib is imported lazily, inside the functions, with the non-interactive Agg backend: the
reports and their tests run without it (no plots are written then).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import numpy as np

from .published import PAPER_MODELS, PAPER_TABLES, paper_value
from .records import BenchResults, SweepResults, cell, select


def pyplot() -> Optional[Any]:
    """matplotlib.pyplot on the Agg backend, or None when matplotlib is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def _finish(plt: Any, fig: Any, axes: Any, title: str, title_kw: dict, path: Path) -> Path:
    """Legend on the first panel, the title, and the figure written to ``path`` (PNG, 110 dpi) and closed."""
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title, **title_kw)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_plots(res: BenchResults, p_set: dict, b_set: dict, folder: Path, stem: str) -> list[Path]:
    """One PNG per model and protocol when matplotlib is importable; [] otherwise."""
    plt = pyplot()
    if plt is None:
        return []
    written = []
    methods = res.settings["methods"]
    for model, info in res.models.items():
        if info.get("missing"):
            continue
        for protocol, sets, what in (("paper", p_set, "corr"), ("benchmark", b_set, "ber")):
            groups = [g for g, items in sets.items() if len(items) > 1]
            if not groups:
                continue
            fig, axes = plt.subplots(1, len(groups), figsize=(4 * len(groups), 3.4), squeeze=False)
            for ax, group in zip(axes[0], groups):
                items = sets[group]
                x = np.arange(len(items))
                for method in methods:
                    cells = [
                        cell(
                            select(res.trials, protocol=protocol, model=model, method=method, group=group, label=label)
                        )
                        for label, *_ in items
                    ]
                    if any(c is None for c in cells):
                        continue
                    mean = [c.corr_mean if what == "corr" else c.ber_mean for c in cells]
                    std = [c.corr_std if what == "corr" else c.ber_std for c in cells]
                    ax.errorbar(x, mean, yerr=std, marker="o", capsize=3, label=method)
                pm = info.get("paper_model")
                if protocol == "paper" and pm in PAPER_MODELS and group in PAPER_TABLES:
                    table = PAPER_TABLES[group]
                    rows = [("paper: proposed", 0, "--")] + ([("paper: Cho", 1, ":")] if group != "cropping" else [])
                    for name, which, style in rows:
                        vals = [paper_value(table, value, pm, which) for _, value, *_ in items]
                        if "–" not in vals:
                            ax.plot(
                                x, [float(v) for v in vals], style, color="gray" if which == 0 else "black", label=name
                            )
                ax.set_xticks(x, [label for label, *_ in items], rotation=30, fontsize=8)
                ax.set_title(group)
                ax.set_ylabel("correlation" if what == "corr" else "BER")
                ax.grid(alpha=0.3)
            written.append(
                _finish(plt, fig, axes, f"{model}: {protocol} protocol", {}, folder / f"{stem}_{model}_{protocol}.png")
            )
    return written


def write_sweep_plots(res: SweepResults, folder: Path) -> list[Path]:
    """One PNG per attack, ``ber_vs_mrms_<attack>.png``: BER against MRMS (log axis), one panel per
    model, one line per method through its strengths, error bars = std over the keys (both axes), the
    MRMS overlap of all methods shaded. [] when matplotlib is not importable."""
    plt = pyplot()
    if plt is None:
        return []
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    st = res.settings
    models = [m for m, info in res.models.items() if not info.get("missing")]
    if not models:
        return []
    written = []
    markers = "osD^v<>p"
    for attack in st["attacks"]:
        fig, axes = plt.subplots(1, len(models), figsize=(max(6.5, 5 * len(models)), 4.0), squeeze=False)
        for ax, model in zip(axes[0], models):
            xs = [p.mrms_mean for p in res.points if (p.model, p.attack) == (model, attack)]
            x_lo, x_hi = (min(xs), max(xs)) if xs else (0.001, 0.1)
            for i, method in enumerate(st["methods"]):
                pts = sorted(
                    (p for p in res.points if (p.model, p.method, p.attack) == (model, method, attack)),
                    key=lambda p: p.mrms_mean,
                )
                if not pts:
                    continue
                x = np.array([p.mrms_mean for p in pts])
                ax.errorbar(
                    x,
                    [p.ber_mean for p in pts],
                    yerr=[p.ber_std for p in pts],
                    xerr=[p.mrms_std for p in pts],
                    marker=markers[i % len(markers)],
                    capsize=3,
                    label=method,
                )
                for p in pts:  # the strength beside each point
                    ax.annotate(
                        f"{p.strength:g}",
                        (p.mrms_mean, p.ber_mean),
                        textcoords="offset points",
                        xytext=(3, 3),
                        fontsize=6,
                        alpha=0.7,
                    )
            comp = next((c for c in res.comparisons if (c.model, c.attack) == (model, attack)), None)
            if comp is not None and comp.overlap is not None:
                ax.axvspan(*comp.overlap, color="gray", alpha=0.12, label="MRMS overlap")
            ax.set_xscale("log")
            ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))  # 0.01, not 1e-2
            ax.xaxis.set_minor_formatter(NullFormatter())  # unlabelled minor ticks: no overlap
            ax.set_xticks([t for t in (0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2) if 0.5 * x_lo <= t <= 2.0 * x_hi])
            ax.set_xlabel("MRMS (% of bbox diagonal)")
            ax.set_ylabel("BER")
            ax.set_ylim(-0.02, 0.6)
            ax.set_title(model)
            ax.grid(alpha=0.3, which="both")
        title = (
            f"{st['attack_settings'][attack]['label']}: BER against embedding distortion "
            f"({st['keys']} key{'s' if st['keys'] != 1 else ''})"
        )
        written.append(_finish(plt, fig, axes, title, {"fontsize": 10}, folder / f"ber_vs_mrms_{attack}.png"))
    return written
