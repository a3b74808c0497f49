"""``pmwm bench``: the robustness benchmark, or with ``--sweep`` the equal-distortion sweep.

pmwm's command line finds this function through the ``pmwm.commands`` entry point ``bench`` (it never
imports pmwm_bench) and hands it the arguments after ``bench``; ``python -m pmwm_bench`` runs it too.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from typing import Optional, Sequence

from .methods import ALL_SCHEMES, SWEEP_SCHEMES, SchemeMethod, scheme_of
from .models import CATALOGUE, DATA_ENV
from .runner import run_bench
from .sweep import (
    DEFAULT_GRID,
    EXTRA_ATTACKS,
    QUICK_ATTACKS,
    QUICK_GRID,
    SECTION,
    SWEEP_ATTACKS,
    run_sweep,
    sweep_attacks,
)

EPILOG = f"""\
modes:
  pmwm bench [MODEL ...]          both protocols (paper: Tables 1-4; benchmark of Wang et al. 2010),
                                  pmwm, pmwm-paper, Cho I and Cho II; section "robustness"
  pmwm bench --sweep [MODEL ...]  equal-distortion sweep: each method at several strengths, MRMS and
                                  BER after noise 0.3 %, smoothing 30 it., quantization 8 bits, a 50 %
                                  plane crop and 50 % simplification; one plot per attack, a table per
                                  attack and one line per attack naming the method with the lowest BER
                                  at equal MRMS; section "{SECTION}"

models: catalogue names, looked up in --data or ${DATA_ENV} (the bunny falls back to the copy
packaged with pmwm), or mesh paths. Default: bunny dragon venus-head igea (bench), bunny dragon
(sweep); --quick: bunny. The catalogue (pmwm_bench.models):
  {", ".join(CATALOGUE)}

sweep strengths (--grid SCHEME=a,b,... overrides one scheme):
{
    chr(10).join(
        f"  {s}: {', '.join(f'{x:g}' for x in g)}   (--quick: {', '.join(f'{x:g}' for x in QUICK_GRID[s])})"
        for s, g in DEFAULT_GRID.items()
    )
}

examples:
  pmwm bench bunny dragon venus-head --data ../shared/data --keys 10 --section robustness \\
      -o benchmarks/results/robustness.md
  pmwm bench --sweep --models bunny,dragon --data ../shared/data --keys 5 \\
      -o benchmarks/results/equal-distortion.md
  pmwm bench --sweep --quick -o /tmp/B.md
"""


def parser() -> argparse.ArgumentParser:
    """The argument parser of ``pmwm bench`` (both modes)."""
    p = argparse.ArgumentParser(
        prog="pmwm bench",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Robustness benchmark of pmwm against Cho et al. 2007, and the "
        "equal-distortion sweep (--sweep); writes a section of a markdown "
        "report, raw JSON and plots beside it.",
        epilog=EPILOG,
    )
    p.add_argument("models", nargs="*", help="catalogue names or mesh paths (see below)")
    p.add_argument(
        "--models",
        dest="models_opt",
        action="append",
        default=[],
        metavar="A,B",
        help="models, comma-separated (added to the positional ones)",
    )
    p.add_argument("--sweep", action="store_true", help="run the equal-distortion sweep instead of the benchmark")
    p.add_argument(
        "--quick",
        action="store_true",
        help="a short run for tests: bench: bunny, <= 3 keys, a few settings; sweep: bunny, 1 key, "
        f"2 strengths per method, attacks {', '.join(QUICK_ATTACKS)}, 2,000 MRMS samples",
    )
    p.add_argument("--keys", type=int, default=None, help="keys (payloads/seeds) per model: default 10, sweep 5")
    p.add_argument("--seed", type=int, default=0, help="key k uses seed SEED + k (default 0)")
    p.add_argument("--data", help=f"folder holding the benchmark meshes (default ${DATA_ENV})")
    p.add_argument(
        "--methods",
        default=None,
        metavar="S,S",
        help=f"schemes to run, comma-separated, of {', '.join(SWEEP_SCHEMES)} (default: bench "
        f"{', '.join(ALL_SCHEMES)}; sweep all)",
    )
    p.add_argument("--cho-only", action="store_true", help="Cho I and II only (same as --methods cho1,cho2)")
    p.add_argument(
        "--strength",
        type=float,
        default=2.0,
        help="bench: strength of the default (robust) scheme; the others stay at their defaults",
    )
    p.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="SCHEME=a,b,c",
        help="sweep: the strengths of one scheme (repeatable)",
    )
    p.add_argument(
        "--attacks",
        default=None,
        metavar="A,B",
        help=f"sweep: attacks to run, of {', '.join(a.key for a in SWEEP_ATTACKS + EXTRA_ATTACKS)} "
        f"(default: {', '.join(a.key for a in SWEEP_ATTACKS)})",
    )
    p.add_argument(
        "--samples",
        type=int,
        default=None,
        help="surface samples per mesh for MRMS / Hausdorff (default 20,000; --quick: 5,000 bench, 2,000 sweep)",
    )
    p.add_argument(
        "--section",
        default=None,
        help=f"section of the report file to (re)write (default robustness, sweep: {SECTION})",
    )
    p.add_argument("--no-plots", action="store_true", help="write no PNG")
    p.add_argument(
        "-o",
        "--output",
        default="BENCHMARKS.md",
        help="markdown report (default BENCHMARKS.md): its section is rewritten, raw data go to the folder "
        "REPORT-SECTION/ beside it; a file named SECTION.md is the section alone, its raw folder "
        "SECTION/",
    )
    return p


def _split(values: Sequence[str]) -> list[str]:
    return [x.strip() for v in values for x in v.split(",") if x.strip()]


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``pmwm bench`` with ``argv`` (the arguments after ``bench``); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    p = parser()
    a = p.parse_args(argv)
    command = ("pmwm bench " + shlex.join(argv)).strip()
    models = list(a.models) + _split(a.models_opt)
    try:
        schemes = (
            [scheme_of(s) for s in _split([a.methods])]
            if a.methods
            else list(SWEEP_SCHEMES if a.sweep else ALL_SCHEMES)
        )
        if a.cho_only:
            schemes = ["cho1", "cho2"]
        grid: dict[str, list[float]] = {}
        for item in a.grid:
            name, _, values = item.partition("=")
            grid[scheme_of(name)] = [float(x) for x in _split([values])]
            if not grid[scheme_of(name)]:
                raise ValueError(f"--grid {item}: give the strengths, e.g. --grid robust=0.5,1,2,4")
    except ValueError as exc:
        p.error(str(exc))
    if a.keys is not None and a.keys < 1:
        p.error("--keys must be at least 1")
    if a.sweep:
        attacks = _split([a.attacks]) if a.attacks else None
        try:
            sweep_attacks(attacks)
        except ValueError as exc:
            p.error(str(exc))
        run_sweep(
            models or None,
            keys=a.keys or 5,
            quick=a.quick,
            out=a.output,
            data_dir=a.data,
            schemes=schemes,
            grid=grid,
            attacks=attacks,
            seed=a.seed,
            plots=not a.no_plots,
            surface_samples=a.samples,
            command=command,
            section=a.section or SECTION,
        )
        return 0
    if a.grid or a.attacks:
        p.error("--grid and --attacks belong to --sweep")
    methods = [SchemeMethod(s, a.strength if s == "robust" else None) for s in schemes]
    run_bench(
        models or None,
        keys=a.keys or 10,
        quick=a.quick,
        out=a.output,
        data_dir=a.data,
        methods=methods,
        seed=a.seed,
        plots=not a.no_plots,
        surface_samples=a.samples,
        command=command,
        section=a.section or "robustness",
    )
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
