"""Fixtures for the Blender add-on tests: headless bpy (4.2 LTS or 5.2 LTS), the add-on loaded from blender_pmwm/.

A process imports bpy once; every test starts from an empty scene (read_homefile(use_empty=True)).
The add-on is registered from the source folder as the package ``blender_pmwm`` (no sys.path edit);
test_install.py checks the built zip separately, in subprocesses.
"""

from __future__ import annotations

import hashlib
import importlib.util
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _load_addon():
    """Import blender_pmwm/ as a package from its folder (once per process)."""
    name = "blender_pmwm"
    if name not in sys.modules:
        folder = ROOT / "blender_pmwm"
        spec = importlib.util.spec_from_file_location(
            name, folder / "__init__.py", submodule_search_locations=[str(folder)]
        )
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope="session")
def addon():
    module = _load_addon()
    module.register()
    yield module
    module.unregister()


@pytest.fixture
def key_prefs(addon, tmp_path):
    """The add-on's preferences, as when the extension is enabled (here it is registered from its
    folder, so Blender has no entry for it yet), with the key folder in tmp_path."""
    addons = bpy.context.preferences.addons
    entry = addons.get("blender_pmwm")
    if entry is None:
        entry = addons.new()
        entry.module = "blender_pmwm"
    entry.preferences.key_folder = str(tmp_path / "key-folder")
    yield entry.preferences
    addons.remove(entry)


@pytest.fixture
def scene(addon):
    """An empty scene with the add-on registered."""
    bpy.ops.wm.read_homefile(use_empty=True)
    return bpy.context.scene


# ----------------------------------------------------------------------------- building objects


def new_object(name: str, V: np.ndarray, F: np.ndarray):
    """A mesh object from triangle arrays (the add-on's ``meshdata.set_geometry``), linked, selected and
    active."""
    mesh = bpy.data.meshes.new(name)
    _load_addon().meshdata.set_geometry(mesh, V, F)
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(ob)
    activate(ob)
    return ob


def activate(ob) -> None:
    for other in bpy.context.view_layer.objects:
        other.select_set(False)
    ob.select_set(True)
    bpy.context.view_layer.objects.active = ob


def suzanne(levels: int = 2):
    """Suzanne (quads and triangles) with a Subdivision modifier applied: ~7.9k vertices at level 2."""
    bpy.ops.mesh.primitive_monkey_add()
    ob = bpy.context.active_object
    if levels:
        mod = ob.modifiers.new("Subdivision", "SUBSURF")
        mod.levels = levels
        bpy.ops.object.modifier_apply(modifier=mod.name)
    return ob


_BUNNY_CACHE: dict = {}


def bunny():
    """The benchmark bunny (34,835 vertices), the sample shipped in the package, as a mesh object."""
    import pmwm

    if "src" not in _BUNNY_CACHE:
        _BUNNY_CACHE["src"] = pmwm.read_mesh(str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
    src = _BUNNY_CACHE["src"]
    return new_object("bunny", src.vertices, src.faces)


# ----------------------------------------------------------------------------- reading state


def positions(ob) -> np.ndarray:
    co = np.empty(len(ob.data.vertices) * 3, np.float32)
    ob.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def polygons(ob) -> tuple[np.ndarray, np.ndarray]:
    """(loop vertex indices, polygon sizes): the user's topology."""
    me = ob.data
    loops = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", loops)
    sizes = np.empty(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_total", sizes)
    return loops, sizes


def _props(group) -> tuple:
    return tuple(
        (p.identifier, str(getattr(group, p.identifier)))
        for p in group.bl_rna.properties
        if p.identifier not in {"rna_type", "name"}
    )


def snapshot(folder: Path | None = None) -> tuple:
    """Everything an operator might change: objects, meshes, modes, selection, options, files."""
    objects = []
    for ob in sorted(bpy.data.objects, key=lambda o: o.name):
        # ob.pmwm_lod first: Blender 4.2 creates an object's property group when it is first read
        # (then ob.keys() lists it), 4.3 and later keep it out of ob.keys()
        lod = _props(ob.pmwm_lod)
        entry = [
            ob.name,
            ob.type,
            ob.mode,
            ob.select_get(),
            tuple(map(tuple, ob.matrix_world)),
            tuple(g.name for g in ob.vertex_groups),
            tuple(ob.keys()),
            lod,
        ]
        if ob.type == "MESH":
            loops, sizes = polygons(ob)
            digest = hashlib.sha256(positions(ob).tobytes() + loops.tobytes() + sizes.tobytes()).hexdigest()
            entry += [
                ob.data.name,
                len(ob.data.vertices),
                digest,
                tuple(ob.data.keys()),
                tuple(a.name for a in ob.data.attributes),
            ]
        objects.append(tuple(entry))
    active = bpy.context.view_layer.objects.active
    files = ()
    if folder is not None:
        files = tuple(
            sorted((p.name, hashlib.sha256(p.read_bytes()).hexdigest()) for p in Path(folder).iterdir() if p.is_file())
        )
    return (
        tuple(objects),
        len(bpy.data.meshes),
        active.name if active else None,
        _props(bpy.context.scene.pmwm),
        files,
    )


def cli_verify(path: Path, key: Path) -> tuple[int, dict | None]:
    """Run ``pmwm verify FILE --key KEY --json``; (exit code, parsed JSON or None)."""
    import json

    proc = subprocess.run(
        [sys.executable, "-m", "pmwm", "verify", str(path), "--key", str(key), "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    try:
        data = json.loads(proc.stdout)
    except ValueError:
        data = None
    return proc.returncode, data


@pytest.fixture
def bl():
    """Helper functions for the tests (a fixture, so test modules need no imports from here)."""
    return SimpleNamespace(
        new_object=new_object,
        activate=activate,
        suzanne=suzanne,
        bunny=bunny,
        positions=positions,
        polygons=polygons,
        snapshot=snapshot,
        cli_verify=cli_verify,
        root=ROOT,
    )
