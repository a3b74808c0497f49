"""Shared helper of the benchmark scripts: where their sections go, the meshes, the command line that ran.

Each script writes its section as a fragment ``benchmarks/results/NAME.md`` (raw data in
``benchmarks/results/NAME/``); ``python benchmarks/report.py`` assembles the report, docs/benchmarks.md,
from the fragments. The provenance every section states (``commit``, ``machine``) and the section writer
live in ``pmwm_bench.report``; the model catalogue in ``pmwm_bench.models``. The scripts look meshes up in
$PMWM_TEST_DATA, $PMWM_BENCH_DATA, then ../shared/data beside the checkout.
"""

from __future__ import annotations

import compileall
import os
import resource
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from pmwm_bench import models, report
from pmwm_bench.report import commit, machine  # noqa: F401  (re-exported for the scripts)

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"  # the fragments NAME.md and the raw folders NAME/


def data_dirs() -> list[Path]:
    """Where the scripts look for meshes: $PMWM_TEST_DATA, $PMWM_BENCH_DATA, ../shared/data, each folder
    once (``bench_blind`` reads every mesh in them for its false positives)."""
    dirs = [Path(os.environ[v]) for v in ("PMWM_TEST_DATA", models.DATA_ENV) if os.environ.get(v)]
    dirs.append(ROOT.parent / "shared" / "data")
    first: dict[Path, Path] = {}
    for d in dirs:
        first.setdefault(d.resolve(), d)
    return list(first.values())


def mesh_path(name: str) -> Path:
    """The file of catalogue model (or file name, or path) ``name``; FileNotFoundError if absent."""
    return models.model_path(name, data_dirs())


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3), faces (m, 3)) of catalogue model (or file name, or path) ``name``."""
    return models.load(mesh_path(name))


def fragment(name: str) -> Path:
    """The fragment file of section ``name``: ``benchmarks/results/NAME.md``."""
    return RESULTS / f"{name}.md"


def write_section(name: str, body: str) -> None:
    """Write the fragment of section ``name`` (``benchmarks/results/NAME.md``) with ``body``, and print it;
    ``python benchmarks/report.py`` then rebuilds the report."""
    report.write_section(fragment(name), name, body)
    print(body)


def command() -> str:
    """The command line that ran the script, relative to the checkout."""
    return "python " + shlex.join([os.path.relpath(sys.argv[0], ROOT), *sys.argv[1:]])


def byte_compiled(package: Path) -> None:
    """The package ``package`` (a directory) byte-compiled, as `pip install` leaves it: with
    PYTHONDONTWRITEBYTECODE set (as on these machines) every timed process would otherwise compile from
    source the modules it imports (about 0.2 s for `pmwm verify`), which a user's never does."""
    compileall.compile_dir(str(package), quiet=1)


def best_alternating(
    commands: list[list[str]], repeat: int, env: dict, exit_codes: tuple[int, ...] = (0,)
) -> list[tuple[float, float]]:
    """(best wall-clock time, best CPU time) of each command (a whole process, environment ``env``)
    run alternately ``repeat`` times each, their output discarded; an exit status outside ``exit_codes``
    raises. The CPU time is the child's user + system time: the embedders use a second thread, so it can
    exceed the wall-clock time."""
    wall: list[list[float]] = [[] for _ in commands]
    cpu: list[list[float]] = [[] for _ in commands]
    for _ in range(repeat):
        for i, cmd in enumerate(commands):
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL)
            wall[i].append(time.perf_counter() - t)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            if done.returncode not in exit_codes:
                raise subprocess.CalledProcessError(done.returncode, cmd)
            cpu[i].append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    return [(min(w), min(c)) for w, c in zip(wall, cpu)]
