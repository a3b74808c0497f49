"""The library apart from its evaluation.

The Blender extension carries the pmwm wheel: it must hold the library only, with no module of
pmwm_bench, no file of the evaluation (runner, markdown, plots, published tables, the sweep) and no
``pmwm.commands`` entry point. And no module of pmwm imports pmwm_bench: ``pmwm bench`` reaches it
through the entry point only. The extension is built as build_addon.py builds it (a pip wheel of the
library and the trimesh wheel); Blender's validator runs when bpy is installed, and the build runs
without it otherwise (the contents checked here do not depend on it).
"""

from __future__ import annotations

import ast
import io
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = ROOT / "core" / "pmwm"
EVALUATION = ROOT / "core" / "pmwm_bench"
#: file names of the evaluation, wherever they would appear in the wheel
EVAL_FILES = {"bench.py", "runner.py", "markdown.py", "plots.py", "published.py", "sweep.py", "report.py"}
#: text that only the evaluation holds (published tables, the runner, the report sections, plots)
EVAL_MARKERS = ("PAPER_TABLE1", "CHO_PUBLISHED", "def run_bench", "def run_sweep", "<!-- bench:", "matplotlib")


@pytest.fixture(scope="module")
def bundled_wheel(extension_zip) -> zipfile.ZipFile:
    """The pmwm wheel inside the extension zip (tests/blender runs Blender's validator on that zip)."""
    with zipfile.ZipFile(extension_zip) as zf:
        wheels = [n for n in zf.namelist() if n.startswith("wheels/pmwm-")]
        assert len(wheels) == 1, zf.namelist()
        data = zf.read(wheels[0])
    return zipfile.ZipFile(io.BytesIO(data))


def _imported_modules(tree: ast.AST) -> list[str]:
    """Absolute module names a module imports: import statements and importlib.import_module("...")."""
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module)
        elif (
            isinstance(node, ast.Call)
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
            and getattr(node.func, "attr", getattr(node.func, "id", "")) in ("import_module", "__import__")
        ):
            names.append(node.args[0].value)
    return names


@pytest.mark.slow
def test_bundled_pmwm_wheel_holds_the_library_only(bundled_wheel):
    names = bundled_wheel.namelist()
    assert "pmwm/__init__.py" in names and "pmwm/data/bunny.off" in names  # the library is whole
    packages = {n.split("/")[0] for n in names}
    assert not any(p.startswith("pmwm_bench") for p in packages), packages
    assert packages <= {"pmwm"} | {p for p in packages if p.endswith((".dist-info", ".data"))}, packages
    evaluation = [n for n in names if n.rsplit("/", 1)[-1] in EVAL_FILES]
    assert not evaluation, evaluation
    for name in names:
        if name.endswith(".py"):
            text = bundled_wheel.read(name).decode("utf-8")
            assert not [m for m in EVAL_MARKERS if m in text], (name, [m for m in EVAL_MARKERS if m in text])
            assert not [m for m in _imported_modules(ast.parse(text)) if m.startswith("pmwm_bench")], name
    entry_points = next(
        (bundled_wheel.read(n).decode() for n in names if n.endswith(".dist-info/entry_points.txt")), ""
    )
    assert "pmwm.commands" not in entry_points and "pmwm_bench" not in entry_points
    metadata = next(bundled_wheel.read(n).decode() for n in names if n.endswith(".dist-info/METADATA"))
    assert "Provides-Extra: bench" not in metadata


def test_the_evaluation_files_exist_where_the_wheel_check_looks_for_them():
    # the wheel check above names these files: they must be the evaluation's, and live outside pmwm
    assert {p.name for p in EVALUATION.glob("*.py")} >= EVAL_FILES - {"bench.py"}
    assert not [p for p in LIBRARY.rglob("*.py") if p.name in EVAL_FILES], "evaluation code inside core/pmwm"


def test_no_pmwm_module_imports_the_evaluation():
    offenders = []
    for path in sorted(LIBRARY.rglob("*.py")):
        for name in _imported_modules(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if name == "pmwm_bench" or name.startswith("pmwm_bench."):
                offenders.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not offenders, offenders


def test_importing_pmwm_loads_neither_the_evaluation_nor_matplotlib():
    code = (
        "import sys, pmwm, pmwm.cli, pmwm.attacks, pmwm.metrics; "
        "bad = sorted(m for m in sys.modules if m.startswith(('pmwm_bench', 'matplotlib'))); "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
