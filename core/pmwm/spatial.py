"""Nearest-point and radius queries between point sets: the one place spatial search is done.

Every scheme, the registration and the metrics ask their spatial questions here. The engine is
scipy's KD-tree (``scipy.spatial.cKDTree``), built unbalanced and without compacting nodes (faster to
build, as fast to query on surface samples) and queried on one thread (``workers=1``: the library
never takes more than the caller's thread). Distances are computed from coordinate differences, so
far-off coordinates keep their digits.

``PointIndex`` is the reusable form: a tree built ONCE over a reference set and queried many times
(the registration queries the key's samples some hundred times per suspect). ``nearest``,
``pairs_within`` and ``min_spacing`` are the one-shot functions.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["PointIndex", "nearest", "pairs_within", "min_spacing"]


def _tree(P: np.ndarray) -> cKDTree:
    # leaves of 32 points: 5-10 % faster than 16 for the registration's queries, as fast elsewhere
    return cKDTree(P, leafsize=32, balanced_tree=False, compact_nodes=False)


class PointIndex:
    """A KD-tree over the points T (n, 3) float64, built once, for many nearest-point and radius
    queries against the same set."""

    def __init__(self, T: np.ndarray):
        self.points = np.ascontiguousarray(T, dtype=np.float64).reshape(-1, 3)
        self._tree = _tree(self.points) if len(self.points) else None

    def __len__(self) -> int:
        return len(self.points)

    def nearest(self, Q: np.ndarray, bound: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """Nearest point of T to each query Q (m, 3): index into T (m,) int64 and squared distance
        (m,) float64; -1 and inf where T is empty or no point of T is within ``bound`` (a bound
        close to the distances asked about makes the search much faster). Q may have any leading
        shape (..., 3); so do the results."""
        Q = np.asarray(Q, dtype=np.float64)
        lead = Q.shape[:-1]
        if self._tree is None:
            return np.full(lead, -1, np.int64), np.full(lead, np.inf)
        d, j = self._tree.query(Q.reshape(-1, 3), k=1, distance_upper_bound=bound, workers=1)
        j = np.where(j < len(self.points), j, -1).astype(np.int64)
        return j.reshape(lead), (d * d).reshape(lead)

    def within(self, Q: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every pair (query i, point j of T) closer than ``radius`` (scalar or (m,) per query).

        Q : (m, 3) float64. Returns (i, j, distance): (k,) int64, (k,) int64, (k,) float64, ordered
        by i then j."""
        Q = np.asarray(Q, dtype=np.float64).reshape(-1, 3)
        rad = np.broadcast_to(np.asarray(radius, np.float64), (len(Q),))
        if self._tree is None or not np.any(rad > 0):
            return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)
        # queries grouped by radius, each group searched at its largest radius in one call (no Python
        # loop over queries; a few large radii do not widen the search of all the others), then
        # each query's own radius (strictly closer)
        found = []
        for q in _radius_groups(rad):
            pairs = _tree(Q[q]).sparse_distance_matrix(self._tree, float(rad[q].max()), output_type="ndarray")
            found.append((q[pairs["i"]], pairs["j"].astype(np.int64), pairs["v"]))
        i, j, d = (np.concatenate(x) for x in zip(*found))
        keep = d < rad[i]
        i, j, d = i[keep], j[keep], d[keep]
        order = np.lexsort((j, i))
        return i[order], j[order], d[order]


def nearest(T: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point of T to each query.

    T : (n, 3) float64 targets; Q : (m, 3) float64 queries.
    Returns the index into T (m,) int64 (-1 when T is empty) and the squared distance (m,) float64.
    To query the same T many times, build a ``PointIndex`` once.
    """
    return PointIndex(T).nearest(Q)


def pairs_within(P: np.ndarray, Q: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of points closer than ``radius``.

    P : (n, 3), Q : (m, 3) float64; radius : scalar or (n,) per point of P.
    Returns (i, j, distance): (k,) int64, (k,) int64, (k,) float64, ordered by i then j.
    The tree is built over the smaller set (over P in groups of radii within a factor of 2).
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    Q = np.asarray(Q, dtype=np.float64).reshape(-1, 3)
    if len(P) <= len(Q) or not len(Q):
        return PointIndex(Q).within(P, radius)
    rad = np.broadcast_to(np.asarray(radius, np.float64), (len(P),))
    found = [(np.empty(0, np.int64), np.empty(0, np.int64))]
    for p in _radius_groups(rad):
        hits = _tree(P[p]).query_ball_point(Q, float(rad[p].max()), workers=1)
        counts = np.fromiter(map(len, hits), np.int64, count=len(hits))
        found.append((p[np.fromiter(itertools.chain.from_iterable(hits), np.int64, count=int(counts.sum()))],
                      np.repeat(np.arange(len(Q), dtype=np.int64), counts)))
    i, j = (np.concatenate(x) for x in zip(*found))
    d = np.sqrt(((P[i] - Q[j]) ** 2).sum(axis=1))
    keep = d < rad[i]
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order], d[keep][order]


def _radius_groups(rad: np.ndarray) -> list[np.ndarray]:
    """Indices of the positive radii in groups within a factor of 2 of each other (each group is
    searched at its largest radius, so that a few large radii do not widen every search)."""
    group = np.ceil(np.log2(np.maximum(rad, 1e-300) / max(float(rad.max()), 1e-300))).clip(-64, 0)
    return [np.flatnonzero((group == g) & (rad > 0)) for g in np.unique(group[rad > 0])]


def min_spacing(P: np.ndarray) -> float:
    """Smallest distance between two distinct points of P (n, 3); inf for fewer than two."""
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    if len(P) < 2:
        return float("inf")
    d, _ = _tree(P).query(P, k=2, workers=1)
    return float(d[:, 1].min())
