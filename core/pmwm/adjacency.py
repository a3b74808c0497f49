"""Mesh adjacency in CSR arrays, built once and reused by every other module.

``build_adjacency(faces, n_vertices)`` returns the unique edges with their face
counts, vertex rings (vertex -> neighbours) and vertex-face incidence as CSR
arrays, plus per-vertex flags: boundary, non-manifold (on an edge with more than
two faces, on an edge whose two faces disagree on orientation, or a pinched
vertex whose faces form several fans) and isolated (no face).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Adjacency:
    """Connectivity of a triangle mesh; every array is plain numpy."""

    n_vertices: int
    faces: np.ndarray  # (m, 3) int64
    edges: np.ndarray  # (e, 2) int64, unique, edges[:, 0] < edges[:, 1], sorted
    edge_face_count: np.ndarray  # (e,) faces on each edge
    ring_ptr: np.ndarray  # (n + 1,) CSR offsets into ring_idx
    ring_idx: np.ndarray  # neighbours of each vertex (ascending for the lower half, then ascending)
    ring_edge: np.ndarray  # index into ``edges`` of each ring entry
    vf_ptr: np.ndarray  # (n + 1,) CSR offsets into vf_idx
    vf_idx: np.ndarray  # incident faces of each vertex, ascending
    boundary_vertex: np.ndarray  # (n,) bool: on an edge with one face
    nonmanifold_vertex: np.ndarray  # (n,) bool: see module docstring
    isolated_vertex: np.ndarray  # (n,) bool: referenced by no face

    @property
    def valence(self) -> np.ndarray:
        return np.diff(self.ring_ptr)

    def ring(self, i: int) -> np.ndarray:
        return self.ring_idx[self.ring_ptr[i] : self.ring_ptr[i + 1]]

    def vertex_faces(self, i: int) -> np.ndarray:
        return self.vf_idx[self.vf_ptr[i] : self.vf_ptr[i + 1]]

    def ring_owner(self) -> np.ndarray:
        """For each entry of ring_idx, the vertex whose ring it belongs to."""
        return segment_owner(self.ring_ptr)

    def edge_index(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Index into ``edges`` of the edges (a, b); -1 where there is no such edge."""
        a = np.asarray(a, dtype=np.int64)
        b = np.asarray(b, dtype=np.int64)
        keys = np.minimum(a, b) * self.n_vertices + np.maximum(a, b)
        ekeys = self.edges[:, 0] * self.n_vertices + self.edges[:, 1]
        pos = np.searchsorted(ekeys, keys)
        pos = np.minimum(pos, len(ekeys) - 1) if len(ekeys) else pos
        found = (ekeys[pos] == keys) if len(ekeys) else np.zeros(keys.shape, bool)
        return np.where(found, pos, -1)

    @property
    def manifold_interior(self) -> np.ndarray:
        """Vertices with a full, clean fan of faces: not boundary, non-manifold or isolated."""
        return ~(self.boundary_vertex | self.nonmanifold_vertex | self.isolated_vertex)


def segment_owner(ptr: np.ndarray) -> np.ndarray:
    """Owner index of every entry of a CSR array given its offsets."""
    return np.repeat(np.arange(len(ptr) - 1, dtype=np.int64), np.diff(ptr))


def ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenation of arange(s, s + c) for each (s, c), vectorised."""
    counts = np.asarray(counts, np.int64)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    offs = np.cumsum(counts) - counts
    return np.repeat(np.asarray(starts, np.int64) - offs, counts) + np.arange(total)


def gather_rows(ptr: np.ndarray, idx: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Concatenated CSR rows ``rows`` of (ptr, idx), without a Python loop."""
    rows = np.asarray(rows, np.int64)
    return idx[ranges(ptr[rows], ptr[rows + 1] - ptr[rows])]


def segment_reduce(ptr: np.ndarray, values: np.ndarray, ufunc: np.ufunc, empty) -> np.ndarray:
    """Apply ``ufunc.reduceat`` over CSR segments; empty segments get ``empty``."""
    n = len(ptr) - 1
    counts = np.diff(ptr)
    out_shape = (n,) + values.shape[1:]
    out = np.full(out_shape, empty, dtype=np.result_type(values, type(empty)))
    nonempty = counts > 0
    if values.shape[0] and nonempty.any():
        out[nonempty] = ufunc.reduceat(values, ptr[:-1][nonempty], axis=0)
    return out


def unique_values(values: np.ndarray) -> np.ndarray:
    """The distinct values of a numeric array (any shape, no NaN), ascending, (k,): ``np.unique``'s
    answer, from a sorted copy. Why not ``np.unique``: asked for the values alone, numpy 2.x finds them
    with a hash set (``_unique_hash``), which on this project's integer keys is many times slower than
    numpy's SIMD sort (docs/decisions/083-numpy-fast-paths.md)."""
    x = np.sort(np.asarray(values).ravel())
    if len(x) < 2:
        return x
    keep = np.empty(len(x), bool)
    keep[0] = True
    np.not_equal(x[1:], x[:-1], out=keep[1:])
    return x[keep]


def stable_order(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(order, keys[order]): the stable argsort of integer ``keys`` (k,) and the sorted keys, both
    (k,) int64: the same permutation as ``np.argsort(keys, kind="stable")`` (a stable order is
    unique), found faster.

    Non-negative keys below 2^32 (vertex, face and record ids): a least-significant-digit radix sort
    on their 16-bit halves (numpy sorts 16-bit integers stably by counting, in linear time), one pass
    when they are below 2^16. Larger non-negative keys that fit in 63 bits together with their
    position: one plain sort of ``key << s | position`` (numpy sorts plain integers with SIMD, index
    arrays not). Otherwise the stable argsort itself."""
    return _stable_order(np.asarray(keys, dtype=np.int64), False)


def _stable_order(keys: np.ndarray, own: bool) -> tuple[np.ndarray, np.ndarray]:
    """``stable_order`` of int64 keys; ``own``: keys may be overwritten (one array less)."""
    k = len(keys)
    if k == 0:
        return np.zeros(0, np.int64), keys.copy()
    low, high = int(keys.min()), int(keys.max())
    if low >= 0 and high < 1 << 32:
        order = np.argsort((keys & 0xFFFF).astype(np.uint16), kind="stable")
        if high >= 1 << 16:
            order = np.take(order, np.argsort((np.take(keys, order) >> 16).astype(np.uint16), kind="stable"))
        return order, np.take(keys, order)
    shift = max(int(k - 1).bit_length(), 1)
    if low >= 0 and high.bit_length() + shift <= 63:
        if own:
            keys <<= shift
            packed = keys
        else:
            packed = keys << shift
        packed |= np.arange(k, dtype=np.int64)
        packed.sort()
        order = packed & ((1 << shift) - 1)
        packed >>= shift
        return order, packed
    order = np.argsort(keys, kind="stable")
    return order, keys[order]


def stable_argsort(values: np.ndarray) -> np.ndarray:
    """``np.argsort(values, kind="stable")`` of a float array (k,), (k,) int64, found faster when no two
    values are equal (distances, as a rule): then there is one sorted order, and numpy's default sort
    finds it in about half the time of the stable one (134,000 float64: 7 against 13 ms). With a tie or
    a NaN (after which numpy's sorts may order the NaNs differently), the stable sort itself. (Integer
    keys: ``stable_order``, a radix sort.)"""
    x = np.asarray(values)
    order = np.argsort(x)
    if len(x) > 1:
        xs = x[order]
        if np.isnan(xs[-1]) or bool(np.any(xs[1:] == xs[:-1])):
            return np.argsort(x, kind="stable")
    return order


def component_labels(edges: np.ndarray) -> np.ndarray:
    """The connected component of each edge of a graph, edges (k, 2) int64 vertex ids: (k,) int64, the
    smallest vertex id of its component (so the components rank as scipy's ``connected_components``
    numbers them). Roots hook onto the smaller root across every edge, then every vertex jumps to its
    root, until no edge joins two roots: a few rounds for a cycle of thousands of edges (11 for 100,000),
    where passing the least label along an edge at a time takes half its length. For small graphs
    (boundary loops) without importing ``scipy.sparse.csgraph`` (0.09 s of a fresh process, 0.045 s where
    ``scipy.sparse`` is loaded already). Large graphs stay with scipy's ``connected_components``
    (``subdivision``): on the rings of a Loop-subdivided Igea, 2.9 million edges, 0.09 s against 0.89 s
    here (0.06 against 0.42 s on its Catmull-Clark copy, 0.02 against 0.17 s on a sqrt(3) bunny)."""
    E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    nodes = unique_values(E)
    e = np.searchsorted(nodes, E)
    root = np.arange(len(nodes))
    while True:
        ru, rv = root[e[:, 0]], root[e[:, 1]]
        joined = ru != rv
        if not joined.any():
            return nodes[root[e[:, 0]]]
        np.minimum.at(root, np.maximum(ru, rv)[joined], np.minimum(ru, rv)[joined])
        while True:  # every vertex to its root
            up = root[root]
            if np.array_equal(up, root):
                break
            root = up


NUMPY_SPARSE = 50_000  # vertices: up to this many, the sparse work is done in numpy (``numpy_sparse``)


def numpy_sparse(n_vertices: int) -> bool:
    """Whether the sparse work on a mesh of ``n_vertices`` (``edge_face_counts``, the neighbour mean of
    ``smoothing.mean_operator``) is done in numpy rather than by scipy.sparse: while scipy.sparse is not
    loaded, for meshes up to NUMPY_SPARSE vertices. Both give the same answer, bit for bit. Why:
    scipy.sparse's first import takes a fresh process 0.11-0.17 s (most of it scipy's array-API layer,
    which imports numpy's lazily loaded submodules), more than numpy's sorts and products lose on such a
    mesh; on a mesh of 10^5 vertices they would lose more than the import (docs/decisions/083-numpy-fast-paths.md)."""
    return n_vertices <= NUMPY_SPARSE and "scipy.sparse" not in sys.modules


def edge_face_counts(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """The undirected edges of the faces (m, 3), (e, 2) int64 with edges[:, 0] < edges[:, 1], sorted,
    and how many face sides lie on each, (e,) int64: the ``edges`` and ``edge_face_count`` of
    ``build_adjacency`` (a degenerate face's repeated corner left out), for callers that need nothing
    else: from one sparse matrix whose conversion to CSR sums the repeats (a third of
    ``build_adjacency``'s time), or, for a small mesh (``numpy_sparse``), by sorting the edges' keys."""
    n = int(n_vertices)
    a = np.asarray(faces, dtype=np.int64).ravel()
    b = np.roll(np.asarray(faces, dtype=np.int64).reshape(-1, 3), -1, axis=1).ravel()
    side = a != b
    a, b = a[side], b[side]
    if numpy_sparse(n):
        return _counted_edges(a, b, n)
    from scipy.sparse import coo_matrix

    E = coo_matrix((np.ones(len(a)), (np.minimum(a, b), np.maximum(a, b))), shape=(n, n)).tocsr()
    edges = np.stack([np.repeat(np.arange(n), np.diff(E.indptr)), E.indices.astype(np.int64)], axis=1)
    return edges, E.data.astype(np.int64)


def _counted_edges(a: np.ndarray, b: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct undirected edges of the sides a -> b (s,) int64 (a != b), (e, 2) int64 sorted, and
    how many sides lie on each, (e,) int64: by sorting their keys (``stable_order``'s radix passes)."""
    keys = stable_order(np.minimum(a, b) * n + np.maximum(a, b))[1]
    first = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]]) if len(keys) else np.zeros(0, np.int64)
    count = np.diff(np.r_[first, len(keys)]).astype(np.int64)
    k = keys[first]
    return np.stack([k // n, k % n], axis=1), count


def boundary_edges(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """The edges on exactly one face side, (b, 2) int64 with edges[:, 0] < edges[:, 1], sorted: those of
    ``edge_face_counts`` with a count of 1, without counting every edge, in numpy alone.

    A vertex whose every edge has its two half-edges, v -> w and w -> v, sends to its neighbours what it
    receives from them: the sums, over the half-edges out of it, of its neighbours' random integers y
    (below 2^32, from a fixed seed; float64 sums, exact below 2^53) equal those over the half-edges into
    it. A vertex on a boundary edge breaks that but where the unmatched integers cancel (about 2^-32), and
    an edge is missed only when both its ends are. The edges at the vertices that break it are then
    counted exactly, by sorting the keys of the faces around them. Why: a cut suspect's boundary is a
    small part of it, so this is faster than counting every edge, and a fresh process reading a large cut
    suspect does not import scipy.sparse for its cut planes (``numpy_sparse``;
    docs/decisions/083-numpy-fast-paths.md)."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = int(n_vertices)
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    y = np.random.default_rng(0).integers(1, 2**32, size=n).astype(np.float64)
    broken = np.bincount(a, y[b], n) != np.bincount(b, y[a], n)
    near = f[broken[f].any(axis=1)]
    a, b = near.ravel(), near[:, [1, 2, 0]].ravel()
    side = a != b
    E, count = _counted_edges(a[side], b[side], n)
    E = E[count == 1]
    return E[broken[E].any(axis=1)]  # (an edge with neither end broken may lack its other face here)


def twin_half_edges(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (h1, h2) of half-edges (h = 3 * face + corner, from faces[face, corner] to the next
    corner) that are the two opposite sides of an edge with exactly two faces, consistently oriented."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = int(n_vertices)
    he_from, he_to = f.ravel(), f[:, [1, 2, 0]].ravel()
    keys = np.minimum(he_from, he_to) * n + np.maximum(he_from, he_to)
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    counts = np.diff(np.r_[starts, len(sk)])
    pair = starts[counts == 2]
    h1, h2 = order[pair], order[pair + 1]
    ok = he_from[h1] == he_to[h2]  # opposite directions: consistently oriented two-face edge
    return h1[ok], h2[ok]


def flip_edges(faces: np.ndarray, h1: np.ndarray, h2: np.ndarray) -> None:
    """Flip, in place, the edges of twin half-edges h1, h2 (``twin_half_edges``; no face in two pairs):
    a -> b in face (a, b, c) and b -> a in face (b, a, d) become the faces (a, d, c) and (d, b, c), the
    quad a, d, b, c split along its other diagonal, same orientation."""
    fl = faces.reshape(-1)
    a, b = fl[h1], fl[h2]
    c = fl[h1 - h1 % 3 + (h1 % 3 + 2) % 3]
    d = fl[h2 - h2 % 3 + (h2 % 3 + 2) % 3]
    faces[h1 // 3] = np.stack([a, d, c], 1)
    faces[h2 // 3] = np.stack([d, b, c], 1)


def is_closed(faces: np.ndarray, n_vertices: int) -> bool:
    """Whether every half-edge (a, b) of the faces (m, 3) has its twin (b, a), so that no edge is on a
    boundary, without building the adjacency: the sums of x_a y_b and of x_b y_a over the half-edges
    agree (random 64-bit x, y from a fixed seed, arithmetic modulo 2^64; a boundary makes them differ
    but with probability 2^-64). Igea: 13 ms against about 50 for ``build_adjacency``. A mesh whose
    faces disagree on orientation is reported open."""
    x, y = np.random.default_rng(0).integers(1, 2**63, size=(2, n_vertices), dtype=np.uint64)
    a, b = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    return bool(np.sum(x[a] * y[b], dtype=np.uint64) == np.sum(x[b] * y[a], dtype=np.uint64))


def build_adjacency(faces: np.ndarray, n_vertices: int, detect_pinches: bool = True) -> Adjacency:
    """Build all adjacency of a triangle mesh in one vectorised pass.

    ``detect_pinches=False`` skips the fan count (pinched vertices are then not
    flagged); the progressive-mesh encoder uses it on meshes it keeps manifold.
    """
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = int(n_vertices)
    he_from = faces.ravel()
    he_to = np.roll(faces, -1, axis=1).ravel()
    fwd_he = he_from < he_to
    lo = np.minimum(he_from, he_to)
    np.maximum(he_from, he_to, out=he_to)  # hi
    lo *= n
    lo += he_to  # the edge key lo * n + hi
    del he_to
    n_he = len(lo)
    order, skeys = _stable_order(lo, True)
    del lo
    first = np.r_[True, skeys[1:] != skeys[:-1]] if len(skeys) else np.zeros(0, bool)
    starts = np.flatnonzero(first)
    counts = np.diff(np.r_[starts, len(skeys)])
    ukeys = skeys[starts]
    del skeys
    edges = np.stack([ukeys // n, ukeys % n], axis=1) if len(ukeys) else np.zeros((0, 2), np.int64)
    # forward half-edges per edge: the half-edges of one edge are consecutive in ``order``
    forward = np.add.reduceat(fwd_he[order].view(np.int8), starts, dtype=np.int64) if len(starts) else counts
    del fwd_he
    boundary_edge = counts == 1
    bad_edge = (counts > 2) | ((counts == 2) & (forward != 1))

    twin = None
    if detect_pinches:  # twin half-edge of every half-edge on a clean two-face edge, else -1
        twin = np.full(n_he, -1, dtype=np.int32 if n_he < 2**31 - 1 else np.int64)
        pair_start = starts[(counts == 2) & ~bad_edge]
        twin[order[pair_start]] = order[pair_start + 1]
        twin[order[pair_start + 1]] = order[pair_start]
    del order, first

    src = np.concatenate([edges[:, 0], edges[:, 1]])
    ring_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(src, minlength=n), out=ring_ptr[1:])
    ring_order, _ = _stable_order(src, True)
    del src
    ring_idx = np.concatenate([edges[:, 1], edges[:, 0]])[ring_order]
    ring_edge = ring_order % max(len(edges), 1)
    del ring_order
    vf_order, _ = stable_order(he_from)
    vf_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(he_from, minlength=n), out=vf_ptr[1:])
    vf_idx = vf_order // 3

    boundary = np.zeros(n, bool)
    boundary[edges[boundary_edge].ravel()] = True
    nonmanifold = np.zeros(n, bool)
    nonmanifold[edges[bad_edge].ravel()] = True
    if detect_pinches:
        nonmanifold |= _pinched(he_from, twin, vf_order, vf_ptr)
    isolated = np.diff(vf_ptr) == 0
    return Adjacency(
        n_vertices=n,
        faces=faces,
        edges=edges,
        edge_face_count=counts,
        ring_ptr=ring_ptr,
        ring_idx=ring_idx,
        ring_edge=ring_edge,
        vf_ptr=vf_ptr,
        vf_idx=vf_idx,
        boundary_vertex=boundary,
        nonmanifold_vertex=nonmanifold,
        isolated_vertex=isolated,
    )


WALK_STEPS = 64  # corners walked around one vertex before the pointer doubling takes over


def _pinched(he_from: np.ndarray, twin: np.ndarray, order: np.ndarray, ptr: np.ndarray) -> np.ndarray:
    """(n,) bool: vertices whose faces form more than one fan (``_fan_count(...) > 1``).

    Around a vertex the corners, linked by ``_corner_next``, form disjoint paths (open fans, each
    with one end, a corner without a next one) and cycles (closed fans). A vertex is one fan when it
    has at most one end and the walk from the path's first corner (or, without an end, from any
    corner) visits all its corners. All vertices walk together, one corner per step, for as many
    steps as the largest valence; beyond ``WALK_STEPS`` the pointer doubling of ``_fan_count``
    answers instead."""
    n = len(ptr) - 1
    count = np.diff(ptr)
    if len(he_from) == 0:
        return np.zeros(n, bool)
    if int(count.max()) > WALK_STEPS:
        return _fan_count(he_from, twin, order, n) > 1
    # the walk follows corners by their own numbers (half-edge c starts at corner c): no reordering
    nc = len(he_from)
    it = np.int32 if nc < 2**31 - 1 else np.int64
    fwd = _corner_next(twin, it)
    end = np.flatnonzero(fwd == np.arange(nc, dtype=it))  # the ends
    ends = np.bincount(he_from[end], minlength=n)
    # the walk's first corner: without an end, any (the cycle's length is the same from all of them),
    # here the vertex's first in vertex order; with one, the corner no other corner of the vertex
    # leads to (looked for among those vertices' corners only)
    walk = np.flatnonzero((ends <= 1) & (count > 0))
    head = np.zeros(n, it)
    head[walk] = order[ptr[walk]]
    open_fan = np.flatnonzero(ends == 1)
    if len(open_fan):
        corners = order[ranges(ptr[open_fan], count[open_fan])]
        nxt = fwd[corners]
        has_pred = np.zeros(nc, bool)
        has_pred[nxt[nxt != corners]] = True
        first = corners[~has_pred[corners]]
        head[he_from[first]] = first
    # a vertex of c corners is one fan when its walk takes c - 1 steps without stopping (at an end,
    # or back at its first corner). The vertices in decreasing order of corners: those still walking
    # at a step are a prefix.
    by_count, steps = _stable_order(WALK_STEPS - count[walk], True)
    walk = walk[by_count]
    steps -= WALK_STEPS  # -count[walk], non-decreasing
    start = head[walk]
    cur = start.copy()
    stopped = np.zeros(len(walk), bool)
    for k in range(1, -int(steps[0]) if len(walk) else 0):  # at most WALK_STEPS steps
        m = int(np.searchsorted(steps, -k))  # the vertices of more than k corners
        nxt = fwd[cur[:m]]
        stopped[:m] |= (nxt == cur[:m]) | (nxt == start[:m])
        cur[:m] = nxt
    pinched = ends > 1
    pinched[walk] = stopped
    return pinched


def _corner_next(twin: np.ndarray, it) -> np.ndarray:
    """(3 m,) ``it``: the corner that follows each corner around its vertex, itself where none does.

    Corner c (the corner where half-edge c starts) is followed by the corner of the twin of the
    half-edge arriving at c (the previous half-edge of c's face)."""
    step = np.roll(twin.reshape(-1, 3), 1, axis=1).ravel()  # twin of the previous half-edge
    return np.where(step >= 0, step, np.arange(len(step), dtype=it)).astype(it, copy=False)


def _next_corner(he_from: np.ndarray, twin: np.ndarray, order: np.ndarray) -> np.ndarray:
    """In vertex order (``order``, a stable argsort of he_from): the position of the corner that
    follows each corner around its vertex, its own position where none does (int32 when it fits).

    Corner c (the corner where half-edge c starts) is followed by the corner of the twin of the
    half-edge arriving at c (the previous half-edge of c's face)."""
    nc = len(he_from)
    it = np.int32 if nc < 2**31 - 1 else np.int64
    order = order.astype(it)
    pos = np.empty(nc, it)
    pos[order] = np.arange(nc, dtype=it)
    return pos[_corner_next(twin, it)[order]]  # in vertex order: position -> position of the next corner


def _fan_count(he_from: np.ndarray, twin: np.ndarray, order: np.ndarray, n: int) -> np.ndarray:
    """Number of face fans around each vertex (more than one: a pinched vertex).

    Corner c (the corner where half-edge c starts) is followed around its vertex by
    the corner of the twin of the half-edge arriving at c. The fans are the orbits
    of that map; their minimum corner is found by pointer doubling in both
    directions, which also covers open fans (paths). The corners are first put in
    vertex order (``order``, a stable argsort of he_from), so that every gather stays
    within a vertex's few corners.
    """
    nc = len(he_from)
    if nc == 0:
        return np.zeros(n, np.int64)
    fwd = _next_corner(he_from, twin, order)
    it = fwd.dtype.type
    order = order.astype(it)
    ident = np.arange(nc, dtype=it)
    bwd = ident.copy()
    moved = fwd != ident
    bwd[fwd[moved]] = ident[moved]
    del moved
    lf = ident.copy()
    lb = ident.copy()
    for _ in range(40):
        lf2 = np.minimum(lf, lf[fwd])
        lb2 = np.minimum(lb, lb[bwd])
        fwd = fwd[fwd]
        bwd = bwd[bwd]
        if np.array_equal(lf2, lf) and np.array_equal(lb2, lb):
            break  # no window doubled its minimum: every orbit has converged
        lf, lb = lf2, lb2
    roots = np.minimum(lf, lb) == ident
    return np.bincount(he_from[order[roots]], minlength=n)
