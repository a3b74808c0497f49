"""Shared fixtures and small mesh builders. The test meshes themselves come from meshes.py: the
bunny shipped with the package, and meshes generated in code, so the suite needs only the clone."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import meshes


def canonical_faces(F: np.ndarray) -> np.ndarray:
    """Faces as a sorted set of oriented triangles (each rotated to start at its smallest index)."""
    F = np.asarray(F)
    r = np.argmin(F, axis=1)
    G = np.take_along_axis(F, (r[:, None] + np.arange(3)) % 3, axis=1)
    return G[np.lexsort(G.T[::-1])]


def quad_torus_obj(nu: int = 40, nv: int = 24, R: float = 1.0, r: float = 0.35) -> str:
    """OBJ text of a torus made of quads (every face a quad)."""
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    # a little deterministic relief so that the surface is not too regular
    rr = r * (1 + 0.08 * np.sin(3 * uu) * np.cos(5 * vv))
    x = (R + rr * np.cos(vv)) * np.cos(uu)
    y = (R + rr * np.cos(vv)) * np.sin(uu)
    z = rr * np.sin(vv)
    P = np.stack([x, y, z], -1).reshape(-1, 3)
    idx = np.arange(nu * nv).reshape(nu, nv)
    a = idx
    b = np.roll(idx, -1, axis=0)
    c = np.roll(np.roll(idx, -1, axis=0), -1, axis=1)
    d = np.roll(idx, -1, axis=1)
    quads = np.stack([a, b, c, d], -1).reshape(-1, 4) + 1
    lines = [f"v {p[0]:.9g} {p[1]:.9g} {p[2]:.9g}" for p in P]
    lines += [f"f {q[0]} {q[1]} {q[2]} {q[3]}" for q in quads]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="session")
def bunny():
    return meshes.bunny()


ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def build_addon():
    """The repository's build_addon.py, imported as a module (it is a script, not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("build_addon", ROOT / "build_addon.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["build_addon"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def extension_zip(build_addon, tmp_path_factory) -> Path:
    """The Blender extension zip built by build_addon.py from this checkout for this platform and Python
    (pmwm wheel, trimesh, scipy), once per test session; not validated here (tests/blender/test_install.py
    runs Blender's validator on it)."""
    import importlib.metadata

    out = tmp_path_factory.mktemp("dist")
    (built,) = build_addon.build(
        out, importlib.metadata.version("trimesh"), check=False, which=build_addon.targets(["this"], ["this"])
    )
    return built


# --------------------------------------------------------------------------- the quick run and the whole suite
# A plain ``pytest`` runs the quick subset: the tests marked ``slow`` (registered in pyproject.toml) are
# deselected, and the run says how many and how to run them. ``pytest --all`` (what tests/run_all.py, the
# README's test command and CI, runs) runs every test; so does a marker expression of one's own (``-m slow``)
# or a test named by its node id (``tests/test_x.py::test_y``).

_SLOW_KEY = pytest.StashKey[int]()  # how many slow tests the quick run deselected
SLOW_HINT = "run them with `pytest --all` (tests/run_all.py, which CI runs, does) or `pytest -m slow`"


def pytest_addoption(parser):
    parser.addoption(
        "--all",
        action="store_true",
        dest="run_all",
        help="run the slow tests too (deselected by default); tests/run_all.py and CI pass it",
    )


def _runs_everything(config) -> bool:
    return bool(
        config.getoption("run_all") or config.getoption("markexpr") or any("::" in str(arg) for arg in config.args)
    )


def pytest_report_header(config):
    if not _runs_everything(config):
        return f"quick run: tests marked slow are deselected; {SLOW_HINT}"
    return None


def pytest_collection_modifyitems(config, items):
    if _runs_everything(config):
        return
    slow = [item for item in items if item.get_closest_marker("slow") is not None]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if item.get_closest_marker("slow") is None]
    config.stash[_SLOW_KEY] = len(slow)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    n = config.stash.get(_SLOW_KEY, 0)
    if n:
        tests = "test" if n == 1 else "tests"
        terminalreporter.write_line(f"{n} slow {tests} deselected (the quick run); {SLOW_HINT}", yellow=True)
