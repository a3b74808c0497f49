"""Nearest-point, radius and point-to-surface queries: the one place spatial search is done.

Every scheme, the registration and the metrics ask their spatial questions here. Two KD-trees answer
them, each where it is the better one:

- Nearest points (``PointIndex``, ``MovingNearest``, ``nearest``, ``min_spacing``) and the pairs within a
  radius (``pairs_within``): pykdtree's KD-tree when it is installed (a dependency of the pip package),
  else scipy's. Both answer exactly (the same neighbours, distances and pairs; where two points lie at
  exactly the same distance, either may be named). Why pykdtree: it imports in about a millisecond where
  ``scipy.spatial`` takes 0.25-0.4 s with numpy 2 (scipy's array-API layer imports most of numpy's
  submodules), most of what ``pmwm verify`` would spend beyond reading its files
  (docs/decisions/083-numpy-fast-paths.md). The radius queries ask it for the neighbours within the
  radius, more of them until a point has fewer than it asked for. Its queries run on OpenMP threads
  (``OMP_NUM_THREADS``). The Blender extension does not bundle it: its macOS wheels carry their own
  OpenMP runtime, and Blender loads one already (two LLVM OpenMP runtimes in one process abort it), so
  inside Blender scipy answers, whose import is paid once per session.
- Point-to-surface distances (``surface_distances``, for the metrics): scipy's KD-tree.

scipy's tree is built unbalanced and without compacting nodes (faster to build, as fast to query on
surface samples) and queried on one thread (``workers=1``). Distances are computed from coordinate
differences, so far-off coordinates keep their digits.

``PointIndex`` is the reusable form: a tree built ONCE over a reference set and queried many times
(the registration queries the key's samples some hundred times per suspect); ``MovingNearest`` answers
the same queries for points that move a little between calls (an ICP) without searching again the
points whose nearest cannot have changed. ``nearest``,
``pairs_within``, ``min_spacing`` and ``surface_distances`` (exact point-to-triangle-surface
distances, for the metrics) are the one-shot functions. Each answers exactly what a brute-force scan
answers, with either engine (tests/test_spatial.py).
"""

from __future__ import annotations

import contextlib
import itertools
import os
import sys
import threading
from typing import TYPE_CHECKING

import numpy as np

from .adjacency import unique_values
from .features import row_norms, squared_norms

if TYPE_CHECKING:  # annotations only: scipy is imported at the first query that needs it
    from scipy.spatial import cKDTree

__all__ = [
    "PointIndex",
    "MovingNearest",
    "nearest",
    "pairs_within",
    "min_spacing",
    "surface_distances",
    "closest_point_on_triangles",
]


def _load_engine() -> None:
    try:
        from scipy.spatial import cKDTree  # noqa: F401
    except Exception:  # (the query that needs it raises the error)
        pass


@contextlib.contextmanager
def loading_engine():
    """Load scipy's KD-tree (scipy.spatial: 0.25-0.4 s of imports) in a thread while the caller does
    other work before its first query that needs it; the thread is joined on exit. A query that comes
    first waits for the import to finish (Python's import lock), so the results are the same either way.
    Nothing to load when pykdtree answers (it imports in a millisecond)."""
    if "scipy.spatial" in sys.modules or engine() == "pykdtree":
        yield
        return
    loader = threading.Thread(target=_load_engine, name="pmwm-load-kdtree", daemon=True)
    loader.start()
    try:
        yield
    finally:
        loader.join()


def _tree(P: np.ndarray, leafsize: int = 32) -> "cKDTree":
    from scipy.spatial import cKDTree  # scipy loads (0.25-0.4 s) when a query first runs, not on import

    # leaves of 32 points: 5-10 % faster than 16 for the registration's queries, as fast elsewhere
    return cKDTree(P, leafsize=leafsize, balanced_tree=False, compact_nodes=False)


def _pykdtree():
    """pykdtree's KDTree class, or None where it is not installed (inside Blender: module docstring).

    Its OpenMP threads wait for work passively (``OMP_WAIT_POLICY``, unless the caller set it): the
    registration asks hundreds of small queries, and threads that spin between them on a busy machine
    cost 5-20 times the queries' own time (docs/decisions/116-verify-speed-of-symmetric-parts.md)."""
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # read once, when pykdtree's OpenMP runtime loads
    try:
        from pykdtree.kdtree import KDTree
    except ImportError:
        return None
    return KDTree


ENGINES = ("pykdtree", "scipy")
_engine: list = []  # the engine of the nearest-point and radius queries, chosen at the first query


def engine() -> str:
    """The KD-tree that answers nearest-point and radius queries: "pykdtree" when installed, else "scipy"."""
    if not _engine:
        _engine.append("pykdtree" if _pykdtree() is not None else "scipy")
    return _engine[0]


@contextlib.contextmanager
def using_engine(name: str):
    """Answer nearest-point and radius queries with the engine ``name`` (one of ``ENGINES``) inside the
    block (tests and benchmarks compare the two; the answers are the same). It sets the engine of the
    whole process, not of the calling thread: not for code that queries from several threads at once."""
    if name not in ENGINES:
        raise ValueError(f"unknown KD-tree engine {name!r}; use one of {ENGINES}")
    if name == "pykdtree" and _pykdtree() is None:
        raise ImportError("pykdtree is not installed (pip install pykdtree)")
    before = engine()
    _engine[0] = name
    try:
        yield
    finally:
        _engine[0] = before


PYKDTREE_LEAF = 16  # points per leaf of pykdtree's trees


class _KnnTree:
    """A KD-tree over P (n, 3) float64 for k-nearest queries, by the current ``engine()``.

    ``query(Q, k, bound)`` -> (distance, index) as scipy's ``cKDTree.query`` gives them: shapes (m,)
    for k = 1, (m, k) otherwise, nearest first; distance inf and index n past the neighbours within
    ``bound`` (or past the n points)."""

    def __init__(self, P: np.ndarray):
        self.n = len(P)
        self.engine = engine()
        if self.engine == "pykdtree":
            self._t = _pykdtree()(np.ascontiguousarray(P, dtype=np.float64), leafsize=PYKDTREE_LEAF)
        else:
            self._t = _tree(P)

    def query(self, Q: np.ndarray, k: int = 1, bound: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        Q = np.ascontiguousarray(Q, dtype=np.float64).reshape(-1, 3)
        if self.engine == "scipy":
            d, j = self._t.query(Q, k=k, distance_upper_bound=bound, workers=1)
            return d, j.astype(np.int64)
        kk = min(k, self.n)  # pykdtree asks k <= n; the columns beyond n stay empty, as scipy's
        if len(Q) == 0:
            d, j = np.empty((0, kk)), np.empty((0, kk), np.int64)
        else:
            d, j = self._t.query(Q, k=kk, distance_upper_bound=None if bound == np.inf else float(bound))
            j = j.astype(np.int64).reshape(len(Q), kk)
            d = np.where(j < self.n, np.asarray(d, np.float64).reshape(len(Q), kk), np.inf)
        if kk < k:
            d = np.concatenate([d, np.full((len(Q), k - kk), np.inf)], axis=1)
            j = np.concatenate([j, np.full((len(Q), k - kk), self.n, np.int64)], axis=1)
        return (d[:, 0], j[:, 0]) if k == 1 else (d, j)


class PointIndex:
    """A KD-tree over the points T (n, 3) float64, built once, for many nearest-point queries against
    the same set."""

    def __init__(self, T: np.ndarray):
        self.points = np.ascontiguousarray(T, dtype=np.float64).reshape(-1, 3)
        self._tree = _KnnTree(self.points) if len(self.points) else None

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
        d, j = self._tree.query(Q.reshape(-1, 3), 1, bound)
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
            d[b], j[b] = self._tree.query(Q[b], 1, bound[b])
        return np.where(j < len(self.points), j, -1).astype(np.int64), d * d


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
        delta = row_norms(Q - x0)
        s = squared_norms(Q - np.take(T, np.maximum(j0, 0), axis=0))  # as the tree sums it: the same bits
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
            d, jq = index._tree.query(Qi, 2, bound[r])
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


def nearest(T: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point of T to each query.

    T : (n, 3) float64 targets; Q : (m, 3) float64 queries.
    Returns the index into T (m,) int64 (-1 when T is empty) and the squared distance (m,) float64.
    To query the same T many times, build a ``PointIndex`` once.
    """
    return PointIndex(T).nearest(Q)


def pairs_within(P: np.ndarray, Q: np.ndarray, radius, by_j: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of points closer than ``radius``.

    P : (n, 3), Q : (m, 3) float64; radius : scalar or (n,) per point of P.
    Returns (i, j, distance): (k,) int64, (k,) int64, (k,) float64, ordered by i then j (by j then
    i with ``by_j``). The tree is built over the smaller set (over P in groups of radii within a
    factor of 2, each searched at its largest radius, so that a few large radii do not widen every
    search) and the other set's points ask it for their neighbours within the radius.
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    Q = np.asarray(Q, dtype=np.float64).reshape(-1, 3)
    rad = np.broadcast_to(np.asarray(radius, np.float64), (len(P),))
    found = [(np.empty(0, np.int64), np.empty(0, np.int64))]
    if len(P) and len(Q):
        if len(P) <= len(Q):
            for p in _radius_groups(rad):
                q, t = _neighbours_within(_KnnTree(P[p]), Q, float(rad[p].max()))
                found.append((np.take(p, t), q))
        else:
            tree = _KnnTree(Q)
            for p in _radius_groups(rad):
                q, t = _neighbours_within(tree, P[p], float(rad[p].max()))
                found.append((np.take(p, q), t))
    i, j = (np.concatenate(x) for x in zip(*found))
    d = row_norms(np.take(P, i, axis=0) - np.take(Q, j, axis=0))  # (np.take: as P[i], faster)
    keep = d < np.take(rad, i)
    i, j, d = i[keep], j[keep], d[keep]
    order = np.lexsort((i, j) if by_j else (j, i))
    return i[order], j[order], d[order]


FIRST_K = 4  # neighbours asked first by a radius query; a point that gets them all asks 4 times more


def _neighbours_within(tree: _KnnTree, X: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, t): every pair of a point X[x] (X (m, 3)) and a tree point t within distance ``r`` of it, and
    perhaps a few just beyond (the bound is widened by 1e-9 of itself: the caller's exact test decides).
    Each point asks for its FIRST_K nearest within the bound; those that got as many ask again for 4
    times more, until each has fewer than it asked for (or the whole tree)."""
    bound = r * (1.0 + 1e-9)
    xs, ts = [np.empty(0, np.int64)], [np.empty(0, np.int64)]
    todo = np.arange(len(X))
    k = min(FIRST_K, tree.n)
    while len(todo):
        _, j = tree.query(np.take(X, todo, axis=0), k, bound)
        j = j.reshape(len(todo), k)
        more = (j[:, -1] < tree.n) if k < tree.n else np.zeros(len(todo), bool)
        done = np.flatnonzero(~more)
        jd = np.take(j, done, axis=0)
        hit = jd < tree.n
        xs.append(np.repeat(np.take(todo, done), hit.sum(axis=1)))
        ts.append(jd[hit])
        todo = np.take(todo, np.flatnonzero(more))
        k = min(4 * k, tree.n)
    return np.concatenate(xs), np.concatenate(ts)


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
    d, _ = _KnnTree(P).query(P, 2)
    return float(d[:, 1].min())


FLAT_SINE2 = 1e-12  # closest_point_on_triangles: a triangle whose squared sine at its corner a is below this is flat


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
    # a triangle of no area (corners equal or in a line; up to rounding: the sine of its angle at a below
    # 1e-6, so that it lies within a millionth of its sides of them) is its edges, where the region tests
    # divide by zero or by rounding errors (their denominator is |ab|^2 |ac|^2 sin^2 a; measured: points
    # 0.1 off on triangles 1e-16 from a line)
    flat = ~(squared_norms(np.cross(ab, ac)) > FLAT_SINE2 * squared_norms(ab) * squared_norms(ac))
    flat |= ~np.isfinite(out).all(axis=1)
    if flat.any():
        out[flat] = _closest_point_on_edges(p[flat], a[flat], b[flat], c[flat])
    return out


def _closest_point_on_edges(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point to p[i] (k, 3) on the three edges of triangle (a[i], b[i], c[i]), each (k, 3): the
    closest point of the triangle when it has no area (the region tests divide by zero there)."""
    best, best_d = a.copy(), np.full(len(p), np.inf)
    for s, e in ((a, b), (b, c), (c, a)):
        d = e - s
        t = np.clip(np.einsum("ij,ij->i", p - s, d) / np.maximum(squared_norms(d), np.finfo(np.float64).tiny), 0.0, 1.0)
        q = s + t[:, None] * d
        dist = squared_norms(p - q)
        closer = dist < best_d
        best[closer], best_d[closer] = q[closer], dist[closer]
    return best


def surface_distances(points: np.ndarray, tri: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Exact distance from each point (m, 3) to the surface of the triangles tri (t, 3, 3): (m,).

    A triangle whose centre is farther than (a point's distance to some triangle + the triangle's
    radius about its centre) cannot be the nearest: an upper bound from the triangles of the 4
    nearest centres, then every triangle within reach (KD-trees over the centres, in groups of radii
    within a factor of 2) gets the exact closest-point test.
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cen = (a + b + c) / 3.0
    rad = np.sqrt(np.maximum(np.maximum(squared_norms(a - cen), squared_norms(b - cen)), squared_norms(c - cen)))
    everything = _tree(cen)
    groups = [(g, _tree(cen[g]), float(rad[g].max())) for g in _radius_groups(np.maximum(rad, 1e-300))]
    k = min(4, len(tri))
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = points[s : s + chunk]
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
        keep = row_norms(p[q] - cen[f]) <= (upper[q] + rad[f]) * (1 + 1e-9) + 1e-300
        q, f = q[keep], f[keep]
        best = upper.copy()
        np.minimum.at(best, q, _to_triangles(p[q], a[f], b[f], c[f]))
        out[s : s + chunk] = best
    return out


def _to_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from p[i] to triangle (a[i], b[i], c[i]), (k,)."""
    return np.linalg.norm(closest_point_on_triangles(p, a, b, c) - p, axis=1)
