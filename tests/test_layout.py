"""The library's layout: no import cycle inside pmwm or inside pmwm_bench, the shared types below every
scheme, and neither the evaluation nor Blender imported by any library module."""

from __future__ import annotations

import ast
from pathlib import Path

import pmwm
import pmwm_bench

PKG = Path(pmwm.__file__).parent
BENCH = Path(pmwm_bench.__file__).parent


def module_name(path: Path, root: Path = PKG) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(root: Path = PKG) -> dict[str, Path]:
    return {module_name(p, root): p for p in sorted(root.rglob("*.py"))}


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Every module (of ``known``, or outside pmwm by its top name) that ``path`` imports anywhere
    in its body, functions included."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([node.module] if node.module else []))
            for a in node.names:
                sub = f"{base}.{a.name}"
                out.add(sub if sub in known else base)
    return out


def graph(root: Path = PKG) -> dict[str, set[str]]:
    """Module -> the modules it imports, for the package at ``root`` (pmwm by default); imports under
    ``if TYPE_CHECKING`` and inside functions count too: a circle closed lazily is still a circle."""
    mods = modules(root)
    known = set(mods)
    return {m: imports(m, p, known) for m, p in mods.items()}


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    found, state, stack = [], {}, []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(g.get(m, ())):
            if n not in g:
                continue
            if state.get(n) == 1:
                found.append(stack[stack.index(n) :] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(g):
        if m not in state:
            visit(m)
    return found


def test_the_graph_sees_relative_and_nested_imports():
    g = graph()
    assert "pmwm.base" in g["pmwm.schemes.paper"] and "pmwm.schemes.robust.read" in g["pmwm.schemes.robust.embed"]
    assert "pmwm.api" in g["pmwm"] and "pmwm.schemes" in g["pmwm.api"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c", "a"]]  # the detector works


def test_no_import_cycle_inside_pmwm():
    assert cycles(graph()) == []


def test_no_import_cycle_inside_pmwm_bench():
    g = graph(BENCH)
    assert "pmwm_bench.records" in g["pmwm_bench.sweep"] and "pmwm_bench.plots" in g["pmwm_bench.runner"]
    assert cycles(g) == []


def test_shared_layers_import_no_scheme_and_no_entry_point():
    g = graph()
    above = (
        "pmwm.schemes",
        "pmwm.api",
        "pmwm.cli",
        "pmwm.__main__",
        "pmwm.fingerprint",  # fingerprinting sits on the robust scheme
        "pmwm.scene",
    )  # scenes sit on the entry points (pmwm.api), object by object
    below = [m for m in g if not m.startswith(above) and m != "pmwm"]
    assert "pmwm.base" in below and "pmwm.key" in below
    for m in below:
        bad = {n for n in g[m] if n.startswith(above)}
        assert not bad, f"{m} imports {bad}"
    for m in g:  # a scheme never imports another scheme
        if m.startswith("pmwm.schemes."):
            own = ".".join(m.split(".")[:3])
            others = {n for n in g[m] if n.startswith("pmwm.schemes.") and not n.startswith(own)}
            assert not others, f"{m} imports {others}"


def test_no_library_module_imports_the_evaluation_or_blender():
    for m, deps in graph().items():
        assert not {d for d in deps if d.split(".")[0] in ("pmwm_bench", "bpy", "matplotlib")}, m


def test_atomic_writing_and_keys_do_not_pull_in_trimesh():
    g = graph()
    for m in ("pmwm.atomic", "pmwm.key", "pmwm.progressive.fileformat"):
        assert "trimesh" not in g[m] and "pmwm.meshio" not in g[m], m


def test_dask_is_imported_by_the_catalogue_only():
    """The Blender extension bundles pmwm without dask: importing pmwm, its command line and
    pmwm.fingerprint (all but its catalogue module) must not import dask or distributed."""
    import os
    import subprocess
    import sys

    for m, deps in graph().items():
        if m != "pmwm.fingerprint.catalogue":
            assert not {d for d in deps if d.split(".")[0] in ("dask", "distributed")}, m
    code = (
        "import sys, pmwm, pmwm.cli, pmwm.fingerprint, pmwm.fingerprint.trace, pmwm.fingerprint.asset; "
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')); "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True, env={**os.environ, "PYTHONPATH": str(PKG.parent)})


def test_front_ends_reach_the_schemes_through_the_registry_only():
    """``pmwm.api``, the command line, the wording, the report and the add-on use ``pmwm.schemes`` (the
    registry: ``SCHEMES``, ``get_scheme``, each scheme's ``keying``) and never a scheme's own module."""
    g = graph()
    for m in ("pmwm.api", "pmwm.cli", "pmwm.wording", "pmwm.verify_report"):
        inside = {n for n in g[m] if n.startswith("pmwm.schemes.")}
        assert not inside, f"{m} imports {inside}"
    addon = PKG.parent.parent / "blender_pmwm"
    assert addon.is_dir(), addon
    for path in sorted(addon.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            assert not any(n.startswith("pmwm.schemes.") for n in names), f"{path.name} imports {names}"
