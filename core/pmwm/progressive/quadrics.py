"""Quadric error metrics for the encoder: each vertex's sum of plane quadrics, and their values.

A quadric is stored as the 10 coefficients of the upper triangle of its symmetric 4x4 matrix, in the
order (xx, xy, xz, x, yy, yz, y, zz, z, 1); its value at a point p is the weighted sum of squared
distances from p to its planes. Each face contributes its plane weighted by its area; each boundary
half-edge a plane through it perpendicular to its face, weighted by 10 times its squared length, so
that collapses keep the boundary in place.
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from ..adjacency import Adjacency
from ..features import face_cross
from .records import NEXT_CORNER


def plane_rows(normals: np.ndarray, d: np.ndarray, w: np.ndarray) -> Iterator[np.ndarray]:
    """The 10 coefficient rows (k,) of the planes normals . x + d = 0 ((k, 3), (k,)) weighted by w (k,),
    one at a time (one (k,) buffer reused, so that a row is only valid until the next is made)."""
    a, b, c = (np.ascontiguousarray(x) for x in normals.T)
    wa, wb, wc = w * a, w * b, w * c
    out = np.empty(len(w))
    for x, y in ((wa, a), (wa, b), (wa, c), (wa, d), (wb, b), (wb, c), (wb, d), (wc, c), (wc, d)):
        yield np.multiply(x, y, out=out)
    np.multiply(w, d, out=out)
    out *= d
    yield out


def plane_quadric(normals: np.ndarray, d: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(10, k) coefficients of the planes normals . x + d = 0 weighted by w (``plane_rows``)."""
    return np.stack([row.copy() for row in plane_rows(normals, d, w)])


def quadric_values(Q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(k,) the values Q(p) of quadrics Q (10, k) at points p (3, k)."""
    x, y, z = p
    return (
        (Q[0] * x + 2 * (Q[1] * y + Q[2] * z + Q[3])) * x
        + (Q[4] * y + 2 * (Q[5] * z + Q[6])) * y
        + (Q[7] * z + 2 * Q[8]) * z
        + Q[9]
    )


def monomials(V: np.ndarray) -> np.ndarray:
    """(n, 10) per point of V (n, 3): the factors of a quadric's coefficients in its value, so that Q(p)
    is one dot product of two rows."""
    x, y, z = (np.ascontiguousarray(c) for c in V.T)
    M = np.empty((len(V), 10))
    for j, (s, c) in enumerate(((x, x), (x, 2 * y), (x, 2 * z), (2, x), (y, y), (y, 2 * z), (2, y), (z, z), (2, z))):
        np.multiply(s, c, out=M[:, j])
    M[:, 9] = 1.0
    return M


def vertex_quadrics(V: np.ndarray, F: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """(n, 10) each vertex's sum of its faces' quadrics and of its boundary edges' constraint planes.

    V (n, 3) float64, F (m, 3) int64; ``boundary`` (m, 3) bool marks the boundary half-edges
    F[f, j] -> F[f, j+1].
    """
    n = len(V)
    cross = face_cross(V, F)  # the same bits as np.cross, without (m, 3) gathers of the corners
    area2 = np.sqrt(np.einsum("ij,ij->i", cross, cross))
    normals = cross / np.maximum(area2, 1e-300)[:, None]
    d = -np.einsum("ij,ij->i", normals, np.take(V, F[:, 0], axis=0))
    cols = [np.ascontiguousarray(F[:, j]) for j in range(3)]
    QT = np.empty((10, n))
    # the faces' area-weighted plane quadrics, a coefficient at a time (no (10, m) array)
    for j, q in enumerate(plane_rows(normals, d, 0.5 * area2)):
        QT[j] = np.bincount(cols[0], weights=q, minlength=n)
        QT[j] += np.bincount(cols[1], weights=q, minlength=n)
        QT[j] += np.bincount(cols[2], weights=q, minlength=n)
    face_b, corner_b = np.nonzero(boundary)
    if len(face_b):
        e0, e1 = F[face_b, corner_b], F[face_b, NEXT_CORNER[corner_b]]
        edge = V[e1] - V[e0]
        side = np.cross(edge, normals[face_b])
        side_len = np.linalg.norm(side, axis=1)
        side = side / np.maximum(side_len, 1e-300)[:, None]
        d = -np.einsum("ij,ij->i", side, V[e0])
        Qb = plane_quadric(side, d, 10.0 * np.einsum("ij,ij->i", edge, edge))
        for j in range(10):
            QT[j] += np.bincount(e0, weights=Qb[j], minlength=n) + np.bincount(e1, weights=Qb[j], minlength=n)
    return np.ascontiguousarray(QT.T)


def boundary_half_edges(F: np.ndarray, adj: Adjacency) -> np.ndarray:
    """(m, 3) bool: the half-edge F[f, j] -> F[f, j+1] has no twin (looked up only between boundary
    vertices)."""
    a, b = F.ravel(), F[:, NEXT_CORNER].ravel()
    boundary = np.zeros(len(a), bool)
    both = np.flatnonzero(adj.boundary_vertex[a] & adj.boundary_vertex[b])
    if len(both):
        boundary[both] = adj.edge_face_count[adj.edge_index(a[both], b[both])] == 1
    return boundary.reshape(-1, 3)
