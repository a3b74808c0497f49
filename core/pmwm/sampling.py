"""Area-uniform random points on a triangle surface: the one sampler of the metrics (MRMS,
Hausdorff) and of the registration (reference and suspect samples)."""

from __future__ import annotations

from typing import Optional

import numpy as np

from .errors import MeshError
from .features import face_cross, vertex_normals

__all__ = ["sample_surface", "sample_faces"]


def sample_surface(
    vertices, faces, n_samples: int, seed: Optional[int] = None, normals: bool = False
) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """``n_samples`` points uniform over the surface: a face drawn by area, a point uniform in it.

    vertices : (n, 3) float64; faces : (m, 3) int64.
    Returns points (n_samples, 3) float64 and, when ``normals``, the smooth (vertex-interpolated)
    unit normals there (n_samples, 3), else None. MeshError when there is no face of positive area.
    """
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    face, w, cross = _draw(V, F, n_samples, seed)
    P = np.einsum("ij,ijk->ik", w, V[F[face]])
    if not normals:
        return P, None
    N = np.einsum("ij,ijk->ik", w, vertex_normals(V, F, cross)[F[face]])
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    return P, N


def sample_faces(vertices, faces, n_samples: int, seed: Optional[int] = None) -> tuple[np.ndarray, np.ndarray]:
    """Where ``sample_surface`` (same seed) puts its points: the face of each (n_samples,) int64 and
    its barycentric weights (n_samples, 3) float64, so that the same points can be placed on a
    displaced copy of the mesh (same faces)."""
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    face, w, _ = _draw(V, F, n_samples, seed)
    return face, w


def _draw(
    V: np.ndarray, F: np.ndarray, n_samples: int, seed: Optional[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The area-weighted face (n_samples,), barycentric weights (n_samples, 3) and the faces' cross
    products (m, 3) (reused for the normals)."""
    if len(F) == 0:
        raise MeshError("the mesh has no faces; surface sampling needs triangles")
    cross = face_cross(V, F)
    cdf = np.cumsum(0.5 * np.linalg.norm(cross, axis=1))  # face areas, as ``face_normals`` gives them
    if not cdf[-1] > 0:
        raise MeshError("all faces are degenerate (zero area); surface sampling needs a surface")
    rng = np.random.default_rng(seed)
    face = np.minimum(np.searchsorted(cdf, rng.uniform(0.0, cdf[-1], n_samples), side="right"), len(F) - 1)
    r1, r2 = rng.uniform(size=n_samples), rng.uniform(size=n_samples)
    flip = r1 + r2 > 1.0
    r1, r2 = np.where(flip, 1.0 - r1, r1), np.where(flip, 1.0 - r2, r2)
    return face, np.stack([1.0 - r1 - r2, r1, r2], axis=1), cross
