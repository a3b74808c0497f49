"""Re-render the equal-distortion plots from a sweep's raw results, measuring nothing.

Run: python benchmarks/replot_sweep.py benchmarks/results/equal-distortion
Reads ``sweep.json`` in that folder and writes its ``ber_vs_mrms_<attack>.png`` again with the current
plotting code (``pmwm_bench.plots.write_sweep_plots``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from pmwm_bench.plots import write_sweep_plots
from pmwm_bench.records import EqualMrms, SweepPoint, SweepResults


def main(folder: Path) -> list[Path]:
    raw = json.loads((folder / "sweep.json").read_text())
    comparisons = [
        EqualMrms(**{**c, "overlap": tuple(c["overlap"]) if c["overlap"] else None}) for c in raw["comparisons"]
    ]
    res = SweepResults(
        settings=raw["settings"],
        models=raw["models"],
        points=[SweepPoint(**p) for p in raw["points"]],
        comparisons=comparisons,
    )
    return write_sweep_plots(res, folder)


if __name__ == "__main__":
    for path in main(Path(sys.argv[1])):
        print(path)
