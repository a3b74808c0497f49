"""Which data meshes a reader may be tuned on, and fresh seeds for the generated shapes.

A claim about robustness holds only where nobody tuned for it: the blind reader's frames and
thresholds were chosen on the four meshes of TUNING; every other mesh of the data folder (its
README.md lists them) is REPORT_ONLY, to be measured and never tuned on. The generated shapes
(``pmwm_bench.corpus``) are drawn from seeds that nobody chose: ``fresh_seeds`` reads them from the
operating system at each run and ``draw_corpus`` records them beside the results, so that any copy
a benchmark reports can be generated again.
"""

from __future__ import annotations

import datetime
import json
import os
from collections.abc import Iterable
from pathlib import Path

from .corpus import FAMILIES

__all__ = ["REPORT_ONLY", "SAME_SUBJECT", "TUNING", "draw_corpus", "fresh_seeds", "read_seeds"]

#: file names (in the data folder) the blind reader was tuned on
TUNING: tuple[str, ...] = (
    "bunny_wm_benchmark.off",
    "dragon_wm_benchmark.off",
    "venus_head_jigsaw.ply",
    "igea_cyberware.ply",
)

#: every other mesh of the data folder: reported on, never tuned on
REPORT_ONLY: tuple[str, ...] = (
    "armadillo_libigl.obj",
    "horse_cyberware.ply",
    "cow.obj",  # one pinched vertex: a scheme may refuse it, and that refusal is a result
    "cow_libigl.off",
    "fandisk.obj",
    "rocker_arm.obj",
    "camelhead.off",  # open, one boundary loop
    "bunny_stanford_holes.ply",  # open (5 holes), 1,113 unreferenced vertices
)

#: report-only meshes of a subject that a tuning mesh shows too (other triangulation), for tables to flag
SAME_SUBJECT: dict[str, str] = {"bunny_stanford_holes.ply": "bunny_wm_benchmark.off"}


def fresh_seeds(count: int) -> list[int]:
    """``count`` seeds from the operating system's entropy (``os.urandom``), each below 2^63."""
    return [int.from_bytes(os.urandom(8), "little") >> 1 for _ in range(int(count))]


def draw_corpus(per_family: int, families: Iterable[str] | None = None,
                record: os.PathLike | None = None) -> dict[str, list[int]]:
    """Fresh seeds for ``per_family`` shapes of each family (all of ``corpus.FAMILIES`` by default):
    family -> seeds. With ``record``, also written there as JSON (the seeds, when, and their source),
    refusing to overwrite an existing file (a record is evidence)."""
    chosen = list(FAMILIES) if families is None else list(families)
    unknown = [f for f in chosen if f not in FAMILIES]
    if unknown:
        raise ValueError(f"unknown families {unknown}; choose among {', '.join(FAMILIES)}")
    seeds = {f: fresh_seeds(per_family) for f in chosen}
    if record is not None:
        text = json.dumps({"source": "os.urandom", "drawn_at": datetime.datetime.now(datetime.UTC)
                           .isoformat(timespec="seconds"), "seeds": seeds}, indent=1)
        with open(Path(record), "x", encoding="utf-8") as fh:
            fh.write(text + "\n")
    return seeds


def read_seeds(record: os.PathLike) -> dict[str, list[int]]:
    """The family -> seeds of a record that ``draw_corpus`` wrote, to generate the same shapes again."""
    return {k: [int(s) for s in v] for k, v in json.loads(Path(record).read_text(encoding="utf-8"))["seeds"].items()}
