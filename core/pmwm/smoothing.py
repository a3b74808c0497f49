"""Uniform Laplacian smoothing and its inverse: the neighbour mean, steps forward and back.

One step moves every vertex a share ``lam`` of the way to the mean of its neighbours, all at once:
V <- V + lam (M V - V), M the neighbour-mean operator (``mean_operator``). Interior vertices average
their 1-ring; boundary vertices (on an edge with one face) average their neighbours along boundary
edges only, so an open border is smoothed as a curve (MeshLab's "1D boundary smoothing" default);
isolated vertices stay. This is the benchmark's smoothing attack (``attacks.smooth_laplacian``,
lam 0.1); Blender's Smooth modifier takes the same steps with lam = factor / 2, its repeat the step
count, boundary vertices averaging all their neighbours (measured in Blender 4.2: equal to 1e-7 of the
diagonal).

``unsmoothing_steps`` runs the same steps backwards, V <- V - lam (M V - V): a step of heat flow
back. Smoothing damps each of the mesh's frequencies by a factor (1 + lam mu) per step (mu in [-2, 0],
an eigenvalue of M - I) and mixes none of them, so steps back give the detail back: each is the forward
step's inverse to first order (it leaves (lam mu)^2 per step), so about as many steps back as were
taken forward, or a few more, restore most of it; what smoothing damped to nothing they amplify from
nothing (noise stays noise). A reader that does not know how many steps were taken tries several and
keeps the one that shows what it looks for (the blind scheme: ``pmwm.schemes.blind.frames``;
docs/decisions/080-blind-reader-frames.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import islice
from typing import Iterator, Optional

import numpy as np

from .adjacency import edge_face_counts, numpy_sparse, stable_order

__all__ = ["neighbour_pairs", "mean_operator", "cotangent_step", "NeighbourMean", "unsmoothing_steps", "smoothed"]


def neighbour_pairs(
    faces: np.ndarray, n: int, edge_counts: Optional[tuple[np.ndarray, np.ndarray]] = None
) -> tuple[np.ndarray, np.ndarray]:
    """Whom each vertex averages: pairs (owner, neighbour), each (p,) int64, for the n vertices of the
    faces (m, 3): an interior vertex's 1-ring, a boundary vertex's neighbours along boundary edges (an
    edge of one face); each pair once, a vertex never its own neighbour (a degenerate face's repeated
    corner). The edges from ``adjacency.edge_face_counts`` (``edge_counts``: its answer, when the caller
    has it)."""
    edges, count = edge_face_counts(faces, n) if edge_counts is None else edge_counts
    lo, hi = edges[:, 0], edges[:, 1]
    one_face = count == 1
    boundary = np.zeros(n, bool)
    boundary[edges[one_face].ravel()] = True
    owner, nbr = np.concatenate([lo, hi]), np.concatenate([hi, lo])
    interior = ~boundary[owner]
    bl, bh = lo[one_face], hi[one_face]
    return np.concatenate([owner[interior], bl, bh]), np.concatenate([nbr[interior], bh, bl])


def mean_operator(faces: np.ndarray, n: int, edge_counts: Optional[tuple[np.ndarray, np.ndarray]] = None):
    """The neighbour-mean operator M, (n, n), for products ``M @ X``, X (n, k): row i averages vertex i's
    neighbours (``neighbour_pairs``, and its ``edge_counts``); a vertex with none keeps itself (M V = V
    there: it never moves). A scipy.sparse CSR matrix, or, for a small mesh
    (``adjacency.numpy_sparse``), a ``NeighbourMean`` that gives its products bit for bit."""
    owner, nbr = neighbour_pairs(faces, n, edge_counts)
    count = np.bincount(owner, minlength=n).astype(np.float64)
    alone = np.flatnonzero(count == 0)
    rows = np.concatenate([owner, alone])
    cols = np.concatenate([nbr, alone])
    weight = np.concatenate([1.0 / count[owner], np.ones(len(alone))])
    if numpy_sparse(n):
        order = stable_order(rows * n + cols)[0]  # CSR's order (each pair is there once)
        return NeighbourMean(rows[order], cols[order], weight[order], n)
    from scipy.sparse import coo_matrix

    return coo_matrix((weight, (rows, cols)), shape=(n, n)).tocsr()


def cotangent_step(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The vertices (n, 3) float64 after one step of MeshLab's Laplacian smoothing with cotangent weights
    (pymeshlab's ``apply_coord_laplacian_smoothing``, its default): V_i <- (V_i + sum_j w_ij V_j) /
    (1 + sum_j w_ij), w_ij = cot(alpha_ij) + cot(beta_ij) of the angles facing edge ij, unnormalised and
    unclipped, computed on V itself (equal to MeshLab's to 1e-9 of the diagonal on closed surfaces; MeshLab
    smooths border vertices along the border instead). A vertex whose weights sum to -1/2 or less (a fan of
    obtuse angles) keeps its place."""
    V = np.asarray(vertices, np.float64)
    F = np.asarray(faces, np.int64)
    n = len(V)
    rows, cols, weights = [], [], []
    for i in range(3):  # (the three corners of every face: the angle at a faces edge bc)
        a, b, c = F[:, i], F[:, (i + 1) % 3], F[:, (i + 2) % 3]
        e1, e2 = V[b] - V[a], V[c] - V[a]
        cross = np.linalg.norm(np.cross(e1, e2), axis=1)
        cot = np.clip(np.einsum("ij,ij->i", e1, e2) / np.maximum(cross, 1e-300), -1e3, 1e3)
        rows += [b, c]
        cols += [c, b]
        weights += [cot, cot]
    r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(weights)
    total = 1.0 + np.bincount(r, weights=w, minlength=n)
    summed = np.stack([np.bincount(r, weights=w * V[c, k], minlength=n) for k in range(3)], axis=1)
    keep = total <= 0.5
    return np.where(keep[:, None], V, (V + summed) / np.where(keep, 1.0, total)[:, None])


@dataclass(frozen=True)
class NeighbourMean:
    """The neighbour-mean operator of ``mean_operator`` as its entries in CSR order (by row, then column):
    rows, cols (p,) int64, weights (p,) float64, over n vertices. Its product sums each row's terms in
    that order, one row at a time from zero, as scipy's CSR product does, so the two agree bit for bit."""

    rows: np.ndarray
    cols: np.ndarray
    weights: np.ndarray
    n: int

    def __matmul__(self, X: np.ndarray) -> np.ndarray:
        """M X for X (n, k) or (n,): float64 of X's shape."""
        X = np.asarray(X, dtype=np.float64)
        XT = np.ascontiguousarray(X.reshape(self.n, -1).T)  # (columns gathered from contiguous rows: faster)
        out = np.stack([np.bincount(self.rows, self.weights * x.take(self.cols), self.n) for x in XT], axis=1)
        return out.reshape(X.shape)


def unsmoothing_steps(vertices: np.ndarray, operator, lam: float) -> Iterator[np.ndarray]:
    """The vertices (n, 3) after 1, 2, 3, ... steps of smoothing undone, V <- V - lam (M V - V), with
    M = ``operator`` (``mean_operator``): an endless iterator (the caller stops it). Each step costs
    one sparse product."""
    X = np.asarray(vertices, dtype=np.float64)
    while True:
        X = (1.0 + lam) * X - lam * (operator @ X)
        yield X


def smoothed(vertices: np.ndarray, operator, lam: float, steps: int) -> np.ndarray:
    """The vertices (n, 3) after ``steps`` forward steps V <- V + lam (M V - V), M = ``operator``
    (``mean_operator``): the smoothing ``unsmoothing_steps`` takes back, the same step with lam negated;
    ``steps`` sparse products (none: the vertices as float64)."""
    X = np.asarray(vertices, dtype=np.float64)
    return next(islice(unsmoothing_steps(X, operator, -lam), steps - 1, None)) if steps > 0 else X
