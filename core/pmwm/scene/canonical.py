"""One object of a scene as the schemes see it, and the normals that move with its vertices.

Shared by the glTF and OBJ readers: each gives an object's own vertices and triangles, this module
welds them into the canonical mesh (``pmwm.meshio.canonical_mesh``, as for a single mesh file) and
keeps the map back, so that the marked positions are written to the file's own vertices.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..features import vertex_normals
from ..meshio import canonical_mesh

__all__ = ["SceneObject", "canonical_object", "moved_normals"]


@dataclass
class SceneObject:
    """One object of a scene: its name (unique in the scene), the canonical mesh (vertices (n, 3)
    float64, faces (m, 3) int64) and, for writing back, source_to_canonical (k,) int64 mapping the
    object's own vertices in the file (k of them) to canonical ones."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    source_to_canonical: np.ndarray
    warnings: list[str] = field(default_factory=list)

    def normals_before(self) -> np.ndarray:
        """(n, 3) unit area-weighted vertex normals of the canonical mesh as read."""
        return vertex_normals(self.vertices, self.faces)

    def normals_after(self, moved: np.ndarray) -> np.ndarray:
        """(n, 3) the same for the canonical vertices at ``moved`` (n, 3)."""
        return vertex_normals(moved, self.faces)


def canonical_object(name: str, vertices: np.ndarray, faces: np.ndarray, where: str) -> SceneObject:
    """The object of a file's own vertices (k, 3) float64 and triangles (m, 3) int64 (indices into them)."""
    warnings: list[str] = []
    V, F, inverse = canonical_mesh(np.ascontiguousarray(vertices, np.float64), faces, where, warnings)
    return SceneObject(name, V, F, inverse, [f"{name}: {w}" for w in warnings])


def moved_normals(normals: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """The file's normals (k, 3) turned with the surface: each gets the change of the vertex normal
    where it sits (``after - before``, both (k, 3) unit or zero) and is made unit again. A custom or
    hard-edge normal keeps its own direction relative to the surface; one where nothing moved is
    unchanged, bit for bit."""
    delta = after - before
    out = normals + delta
    length = np.linalg.norm(out, axis=1, keepdims=True)
    moved = delta.any(axis=1) & (length[:, 0] > 1e-12)
    return np.where(moved[:, None], out / np.maximum(length, 1e-300), normals)
