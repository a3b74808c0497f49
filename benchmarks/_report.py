"""Shared helper of the benchmark scripts: the report file, the meshes, the command line that ran.

The provenance every section states (``commit``, ``machine``) and the section writer live in
``pmwm_bench.report``; the model catalogue in ``pmwm_bench.models``. The scripts look meshes up in
$PMWM_TEST_DATA (or $PMWM_BENCH_DATA), else in ../shared/data beside the checkout.
"""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path

import numpy as np

from pmwm_bench import models, report
from pmwm_bench.report import commit, machine  # noqa: F401  (re-exported for the scripts)

ROOT = Path(__file__).resolve().parents[1]
REPORT = ROOT / "BENCHMARKS.md"


def data_dirs() -> list[Path]:
    """Where the scripts look for meshes, before $PMWM_BENCH_DATA: $PMWM_TEST_DATA, ../shared/data."""
    dirs = [Path(os.environ["PMWM_TEST_DATA"])] if os.environ.get("PMWM_TEST_DATA") else []
    return dirs + [ROOT.parent / "shared" / "data"]


def mesh_path(name: str) -> Path:
    """The file of catalogue model (or file name, or path) ``name``; FileNotFoundError if absent."""
    return models.model_path(name, data_dirs())


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3), faces (m, 3)) of catalogue model (or file name, or path) ``name``."""
    return models.load(mesh_path(name))


def write_section(name: str, body: str) -> None:
    """Replace (or append) the section ``name`` of BENCHMARKS.md with ``body``, and print it."""
    report.write_section(REPORT, name, body)
    print(body)


def command() -> str:
    """The command line that ran the script, relative to the checkout."""
    return "python " + shlex.join([os.path.relpath(sys.argv[0], ROOT), *sys.argv[1:]])
