"""Same results after the speed work: the robustness benchmark re-run and compared trial by trial.

Run: python benchmarks/bench_same_results.py [--keys 5] [--models bunny,dragon,venus-head]
     [--methods robust,paper] [--trials PATH]
(meshes from $PMWM_TEST_DATA or ../shared/data beside the checkout). Runs ``pmwm bench`` with the first
``--keys`` keys of the committed robustness run (seeds 0..keys-1; or reads a ``trials.json`` it wrote,
``--trials``) and compares every trial with the committed ``benchmarks/results/robustness/trials.json``: bits
read, failures, and each cell's mean against the committed mean +- std. Writes the "same-results"
section of the report (its fragment in benchmarks/results/).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import ROOT, command, commit, data_dirs, machine, write_section  # noqa: E402

COMMITTED = ROOT / "benchmarks" / "results" / "robustness" / "trials.json"


def _by_trial(doc: dict) -> dict:
    return {(t["protocol"], t["model"], t["method"], t["group"], t["label"], t["key"]): t for t in doc["trials"]}


def compare(old: dict, new: dict) -> dict:
    """Counts of identical and different trials, and of cells whose new mean leaves the old mean +- std."""
    old_t, new_t = _by_trial(old), _by_trial(new)
    missing = [k for k in new_t if k not in old_t]
    differ = [
        k
        for k in new_t
        if k in old_t and (old_t[k]["matches"], old_t[k]["failed"]) != (new_t[k]["matches"], new_t[k]["failed"])
    ]
    cells: dict = defaultdict(lambda: ([], []))
    for k, t in old_t.items():
        cells[k[:5]][0].append(t["ber"])
    for k, t in new_t.items():
        cells[k[:5]][1].append(t["ber"])
    compared = [(c, o, n) for c, (o, n) in cells.items() if n and o]
    outside = [c for c, o, n in compared if abs(np.mean(n) - np.mean(o)) > np.std(o) + 1e-12]
    return {
        "trials": len(new_t),
        "missing": len(missing),
        "differ": differ,
        "cells": len(compared),
        "outside": outside,
        "methods": sorted({k[2] for k in new_t}),
        "models": sorted({k[1] for k in new_t}),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keys", type=int, default=5)
    ap.add_argument("--models", default="bunny,dragon,venus-head")
    ap.add_argument("--methods", default="robust,paper")
    ap.add_argument("--trials", type=Path, help="a trials.json of such a run, instead of running one")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trials = args.trials
        if trials is None:
            data = next((d for d in data_dirs() if d.is_dir()), None)
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "pmwm_bench.cli",
                    *args.models.split(","),
                    "--data",
                    str(data),
                    "--keys",
                    str(args.keys),
                    "--methods",
                    args.methods,
                    "--section",
                    "same",
                    "-o",
                    str(Path(tmp) / "B.md"),
                    "--no-plots",
                ],
                check=True,
            )
            trials = Path(tmp) / "B-same" / "trials.json"
        result = compare(json.loads(COMMITTED.read_text()), json.loads(trials.read_text()))
    committed_at = "the robustness section's commit (7bf4a85)"
    lines = [
        "## Same results after the speed work",
        "",
        f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.",
        "",
        f"`pmwm bench` re-run on {', '.join(result['models'])}, methods {', '.join(result['methods'])}, both "
        f"protocols, the first {args.keys} keys (seeds 0..{args.keys - 1}), compared trial by trial with the "
        f"committed `benchmarks/results/robustness/trials.json` of {committed_at}, made before the KD-tree, the new "
        "progressive-mesh encoder and the faster layout and carrier search:",
        "",
        f"- trials compared: {result['trials']} ({result['missing']} without a counterpart); "
        f"the same bits read and the same failures in {result['trials'] - len(result['differ'])}, "
        f"different in {len(result['differ'])};",
        f"- cells (mean over the keys): {result['cells']}; cells whose new mean leaves the committed mean +- std: "
        f"{len(result['outside'])}.",
    ]
    if result["differ"]:
        lines += ["", "Trials that differ: " + "; ".join(" / ".join(map(str, k)) for k in result["differ"][:20])]
    write_section("same-results", "\n".join(lines))


if __name__ == "__main__":
    main()
