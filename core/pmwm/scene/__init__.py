"""Scenes: files of several objects (glTF/GLB, OBJ with ``o``/``g`` objects) marked as one asset.

``read_asset(path)`` gives the file's objects and a writer that puts marked positions back into the
file with everything else it held kept (``gltf``: buffers patched in place; ``obj``: only ``v``/``vn``
lines rewritten), or None for a file of one mesh (``pmwm.read_mesh`` reads it, as before).
``embed_objects`` marks every object with one master secret, ``verify_objects`` reads objects against
object keys with the union bound paid (``asset``). ``read_objects`` gives the objects of any mesh file
(a file of one mesh: one object named by the file). See docs/scenes.md.
"""

from __future__ import annotations

import os
from typing import Union

import numpy as np

from ..errors import MeshError
from .asset import (
    SCENE_KEY_FORMAT,
    AssetMarking,
    SceneDetail,
    SceneKey,
    embed_objects,
    read_keys,
    union_bound,
    verify_objects,
    write_keys,
)
from .canonical import SceneObject
from .gltf import GltfScene, read_gltf
from .obj import ObjScene, read_obj_scene

Asset = Union[GltfScene, ObjScene]
SCENE_EXTENSIONS = (".glb", ".gltf", ".obj")

__all__ = [
    "Asset",
    "SCENE_EXTENSIONS",
    "SceneObject",
    "read_asset",
    "read_objects",
    "write_asset",
    "SCENE_KEY_FORMAT",
    "AssetMarking",
    "SceneDetail",
    "SceneKey",
    "embed_objects",
    "verify_objects",
    "union_bound",
    "read_keys",
    "write_keys",
]


def read_asset(path) -> "Asset | None":
    """The objects of a glTF/GLB file (any number of meshes) or of an OBJ file of several objects, with
    their writer; None for any other file (one mesh: ``pmwm.read_mesh``). MeshError naming the problem
    when the file is refused."""
    p = os.fspath(path)
    ext = os.path.splitext(p)[1].lower()
    if ext not in SCENE_EXTENSIONS or not os.path.isfile(p):
        return None  # (a missing file: read_mesh says so)
    return read_gltf(p) if ext in (".glb", ".gltf") else read_obj_scene(p)


def read_objects(path) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, vertices (n, 3) float64, faces (m, 3) int64) of every object of a mesh file: a scene's
    objects, or the one mesh of any other file, named by the file."""
    asset = read_asset(path)
    if asset is not None:
        return [(o.name, o.vertices, o.faces) for o in asset.objects]
    from ..meshio import read_mesh

    src = read_mesh(path)
    return [(os.path.basename(os.fspath(path)), src.vertices, src.faces)]


def write_asset(path, asset: Asset, marked: list[np.ndarray], *, force: bool = False) -> list[str]:
    """Write the asset with its objects at ``marked`` (canonical positions, one (n_i, 3) array per
    object), read it back and check every object holds exactly the positions meant (as float32 for
    glTF); returns the files written. On any failure nothing written is left (MeshError)."""
    p = os.fspath(path)
    written = asset.write(p, marked, force=force)
    try:
        again = read_asset(p)
        ok = again is not None and len(again.objects) == len(marked)
        cast = np.float32 if isinstance(asset, GltfScene) else np.float64
        for obj, new in zip(again.objects if ok else [], marked):
            ok = ok and np.array_equal(obj.vertices, np.asarray(new, np.float64).astype(cast).astype(np.float64))
        if not ok:
            raise MeshError(f"{p} did not read back with the marked positions; nothing was kept")
    except BaseException:
        for w in written:
            try:
                os.remove(w)
            except OSError:
                pass
        raise
    return written
