"""Nearest-point, radius and point-to-surface queries: the one place spatial search is done.

Every scheme, the registration and the metrics ask their spatial questions here. The engine is
scipy's KD-tree (``scipy.spatial.cKDTree``), built unbalanced and without compacting nodes (faster to
build, as fast to query on surface samples) and queried on one thread (``workers=1``: the library
never takes more than the caller's thread). Distances are computed from coordinate differences, so
far-off coordinates keep their digits.

``PointIndex`` is the reusable form: a tree built ONCE over a reference set and queried many times
(the registration queries the key's samples some hundred times per suspect); ``MovingNearest`` answers
the same queries for points that move a little between calls (an ICP) without searching again the
points whose nearest cannot have changed. ``nearest``,
``pairs_within``, ``min_spacing`` and ``surface_distances`` (exact point-to-triangle-surface
distances, for the metrics) are the one-shot functions. Each answers exactly what a brute-force scan
answers (tests/test_spatial.py).
"""

from __future__ import annotations

import contextlib
import itertools
import sys
import threading

import numpy as np

from .adjacency import unique_values

__all__ = ["PointIndex", "MovingNearest", "nearest", "pairs_within", "min_spacing", "surface_distances",
           "closest_point_on_triangles"]


def _load_engine() -> None:
    try:
        from scipy.spatial import cKDTree  # noqa: F401
    except Exception:  # (the query that needs it raises the error)
        pass


@contextlib.contextmanager
def loading_engine():
    """Load the KD-tree engine (scipy.spatial: about 0.2 s of imports) in a thread while the caller does
    other work before its first query; the thread is joined on exit. A query that comes first waits
    for the import to finish (Python's import lock), so the results are the same either way."""
    if "scipy.spatial" in sys.modules:
        yield
        return
    loader = threading.Thread(target=_load_engine, name="pmwm-load-kdtree", daemon=True)
    loader.start()
    try:
        yield
    finally:
        loader.join()


def _tree(P: np.ndarray, leafsize: int = 32) -> "cKDTree":
    from scipy.spatial import cKDTree  # scipy loads (0.2 s) when a query first runs, not on import

    # leaves of 32 points: 5-10 % faster than 16 for the registration's queries, as fast elsewhere
    return cKDTree(P, leafsize=leafsize, balanced_tree=False, compact_nodes=False)


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

    def nearest_rows(self, Q: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``nearest`` for each row of queries Q (b, m, 3) within its own bound (b,): index (b, m)
        int64 and squared distance (b, m) float64 (-1 and inf beyond the row's bound)."""
        Q = np.asarray(Q, dtype=np.float64)
        if self._tree is None or Q.shape[0] == 0:
            return np.full(Q.shape[:2], -1, np.int64), np.full(Q.shape[:2], np.inf)
        d, j = np.empty(Q.shape[:2]), np.empty(Q.shape[:2], np.intp)
        for b in range(len(Q)):
            d[b], j[b] = self._tree.query(Q[b], k=1, distance_upper_bound=bound[b], workers=1)
        return np.where(j < len(self.points), j, -1).astype(np.int64), d * d

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


class MovingNearest:
    """Nearest points of a ``PointIndex`` for rows of query points that move a little between
    calls (an ICP: the same m source points under each start's pose, (rows, m, 3)).

    Each call answers what ``index.nearest(Q[r], bound[r])`` answers for each row r, but a point is
    searched again only when its answer can have changed. After a search from place x0 the point
    knows its nearest point j at distance d0 (or none within the bound: d0 = the bound) and a lower
    bound L on the distance from x0 to every other point of T (the second nearest, else the bound).
    From a new place x, |x - x0| = delta away, every point is at least d0 - delta away and every
    other point at least L - delta, so j is still the unique nearest when |x - T[j]| < L - delta
    (its distance is then computed as the tree computes it, the same bits), and there is none within
    the bound when d0 - delta exceeds it. Only the other points are searched, one tree query per row
    (this pays when most points keep their nearest: converging poses; a query for two neighbours
    costs more than one).
    """

    def __init__(self, index: PointIndex, rows: int, m: int):
        self.index = index
        self._x0 = np.zeros((rows, m, 3))  # each point's place at its last search
        self._j0 = np.full((rows, m), -1, np.int64)  # its nearest then (-1: none within the bound)
        self._d0 = np.full((rows, m), -np.inf)  # the nearest's distance then (else the bound)
        self._l0 = np.full((rows, m), -np.inf)  # lower bound on the distance to every other point
        self._big = float(np.abs(index.points).max()) if len(index) else 0.0

    def nearest(self, rows: np.ndarray, Q: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``rows`` (r,) (of the rows given at construction) at places Q (r, m, 3), each
        searched within its ``bound`` (r,) (inf: no bound): the nearest point's index (r, m) int64
        and squared distance (r, m) float64 (-1 and inf where none is within the bound), exactly
        as ``PointIndex.nearest`` answers."""
        index, T = self.index, self.index.points
        Q = np.asarray(Q, np.float64)
        bound = np.asarray(bound, np.float64)
        if index._tree is None:
            return np.full(Q.shape[:2], -1, np.int64), np.full(Q.shape[:2], np.inf)
        x0, j0, d0, l0 = (np.take(a, rows, axis=0) for a in (self._x0, self._j0, self._d0, self._l0))
        # rounding of the distances below: far below 1e-9 of the coordinates' size
        tol = 1e-9 * (self._big + float(np.abs(Q).max(initial=0.0)))
        delta = np.sqrt(_sq3(Q - x0))
        s = _sq3(Q - np.take(T, np.maximum(j0, 0), axis=0))  # as the tree sums it: the same bits
        dj = np.sqrt(s)
        ub = bound[:, None]
        unique = (j0 >= 0) & (dj < l0 - delta - tol)  # j0 is still the nearest
        found = unique & (dj < ub - tol)
        gone = (unique & (dj > ub + tol)) | (d0 - delta > ub + tol)  # none within the bound
        j = np.where(found, j0, -1)
        d2 = np.where(found, dj * dj, np.inf)
        todo = ~(found | gone)
        n = len(T)
        for r in np.flatnonzero(todo.any(axis=1)):
            i = np.flatnonzero(todo[r])
            Qi = np.take(Q[r], i, axis=0)
            d, jq = index._tree.query(Qi, k=2, distance_upper_bound=bound[r], workers=1)
            first = np.where(jq[:, 0] < n, jq[:, 0], -1)
            tie = np.isfinite(d[:, 0]) & (d[:, 0] == d[:, 1])
            if tie.any():  # two nearest at one distance: the one a single-neighbour search picks
                first[tie] = index.nearest(Qi[tie], bound[r])[0]
            row = rows[r]
            self._x0[row, i], self._j0[row, i] = Qi, first
            self._d0[row, i] = np.where(first >= 0, d[:, 0], bound[r])
            self._l0[row, i] = np.where(np.isfinite(d[:, 1]), d[:, 1], bound[r])
            j[r, i], d2[r, i] = first, d[:, 0] * d[:, 0]
        return j, d2


def _sq3(d: np.ndarray) -> np.ndarray:
    """Squared length of each vector d (..., 3), summed in the KD-tree's order (same bits)."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return (x * x + y * y) + z * z


def nearest(T: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point of T to each query.

    T : (n, 3) float64 targets; Q : (m, 3) float64 queries.
    Returns the index into T (m,) int64 (-1 when T is empty) and the squared distance (m,) float64.
    To query the same T many times, build a ``PointIndex`` once.
    """
    return PointIndex(T).nearest(Q)


def pairs_within(P: np.ndarray, Q: np.ndarray, radius, by_j: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of points closer than ``radius``.

    P : (n, 3), Q : (m, 3) float64; radius : scalar or (n,) per point of P.
    Returns (i, j, distance): (k,) int64, (k,) int64, (k,) float64, ordered by i then j (by j then
    i with ``by_j``). The tree is built over the smaller set (over P in groups of radii within a
    factor of 2).
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    Q = np.asarray(Q, dtype=np.float64).reshape(-1, 3)
    if len(P) <= len(Q) or not len(Q):
        i, j, d = PointIndex(Q).within(P, radius)
        if by_j:
            order = np.lexsort((i, j))
            i, j, d = i[order], j[order], d[order]
        return i, j, d
    rad = np.broadcast_to(np.asarray(radius, np.float64), (len(P),))
    found = [(np.empty(0, np.int64), np.empty(0, np.int64))]
    for p in _radius_groups(rad):
        # a tree over many points (faces) for a few balls (sites): large leaves build and search faster
        hits = _tree(P[p], leafsize=256).query_ball_point(Q, float(rad[p].max()), workers=1,
                                                          return_sorted=False)  # (sorted below)
        counts = np.fromiter(map(len, hits), np.int64, count=len(hits))
        found.append((np.take(p, np.fromiter(itertools.chain.from_iterable(hits), np.int64,
                                             count=int(counts.sum()))),
                      np.repeat(np.arange(len(Q), dtype=np.int64), counts)))
    i, j = (np.concatenate(x) for x in zip(*found))
    d = np.sqrt(_sq3(np.take(P, i, axis=0) - np.take(Q, j, axis=0)))  # (np.take: as P[i], faster)
    keep = d < np.take(rad, i)
    i, j, d = i[keep], j[keep], d[keep]
    order = np.lexsort((i, j) if by_j else (j, i))
    return i[order], j[order], d[order]


def _radius_groups(rad: np.ndarray) -> list[np.ndarray]:
    """Indices of the positive radii in groups within a factor of 2 of each other (each group is
    searched at its largest radius, so that a few large radii do not widen every search)."""
    group = np.ceil(np.log2(np.maximum(rad, 1e-300) / max(float(rad.max()), 1e-300))).clip(-64, 0)
    return [np.flatnonzero((group == g) & (rad > 0)) for g in unique_values(group[rad > 0])]


def min_spacing(P: np.ndarray) -> float:
    """Smallest distance between two distinct points of P (n, 3); inf for fewer than two."""
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    if len(P) < 2:
        return float("inf")
    d, _ = _tree(P).query(P, k=2, workers=1)
    return float(d[:, 1].min())


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point of triangle (a[i], b[i], c[i]) to p[i], vectorised (Ericson 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v_in = np.where(denom != 0, vb / denom, 0.0)
        w_in = np.where(denom != 0, vc / denom, 0.0)
        out = a + v_in[:, None] * ab + w_in[:, None] * ac  # face region
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        t_ac = d2 / (d2 - d6)
        t_ab = d1 / (d1 - d3)
    # apply the regions from the last test to the first, so the first matching test wins
    conds = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), lambda: b + t_bc[:, None] * (c - b)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), lambda: a + t_ac[:, None] * ac),
        ((d6 >= 0) & (d5 <= d6), lambda: c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), lambda: a + t_ab[:, None] * ab),
        ((d3 >= 0) & (d4 <= d3), lambda: b),
        ((d1 <= 0) & (d2 <= 0), lambda: a),
    ]
    for cond, value in conds:
        if cond.any():
            out = np.where(cond[:, None], value(), out)
    return out


def surface_distances(points: np.ndarray, tri: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Exact distance from each point (m, 3) to the surface of the triangles tri (t, 3, 3): (m,).

    A triangle whose centre is farther than (a point's distance to some triangle + the triangle's
    radius about its centre) cannot be the nearest: an upper bound from the triangles of the 4
    nearest centres, then every triangle within reach (KD-trees over the centres, in groups of radii
    within a factor of 2) gets the exact closest-point test.
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cen = (a + b + c) / 3.0
    rad = np.sqrt(np.maximum(np.maximum(_sq(a - cen), _sq(b - cen)), _sq(c - cen)))
    everything = _tree(cen)
    groups = [(g, _tree(cen[g]), float(rad[g].max())) for g in _radius_groups(np.maximum(rad, 1e-300))]
    k = min(4, len(tri))
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk]
        _, near = everything.query(p, k=k, workers=1)
        near = near.reshape(len(p), k)
        q = np.repeat(np.arange(len(p)), k)
        f = near.ravel()
        upper = np.full(len(p), np.inf)
        np.minimum.at(upper, q, _to_triangles(p[q], a[f], b[f], c[f]))
        qs, fs = [], []
        for g, tree, r in groups:
            hits = tree.query_ball_point(p, upper + r, workers=1)
            n = np.fromiter(map(len, hits), np.int64, count=len(hits))
            qs.append(np.repeat(np.arange(len(p)), n))
            fs.append(g[np.fromiter(itertools.chain.from_iterable(hits), np.int64, count=int(n.sum()))])
        q, f = np.concatenate(qs), np.concatenate(fs)
        keep = np.sqrt(_sq(p[q] - cen[f])) <= (upper[q] + rad[f]) * (1 + 1e-9) + 1e-300
        q, f = q[keep], f[keep]
        best = upper.copy()
        np.minimum.at(best, q, _to_triangles(p[q], a[f], b[f], c[f]))
        out[s:s + chunk] = best
    return out


def _to_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from p[i] to triangle (a[i], b[i], c[i]), (k,)."""
    return np.linalg.norm(closest_point_on_triangles(p, a, b, c) - p, axis=1)


def _sq(d: np.ndarray) -> np.ndarray:
    """Squared length of each row of d (n, 3)."""
    return np.einsum("ij,ij->i", d, d)
