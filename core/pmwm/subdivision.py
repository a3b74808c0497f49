"""Undoing one step of subdivision: the coarse mesh a subdivided copy was made from.

A copy subdivided once carries the original mesh in its connectivity (Taubin, "Detecting and
reconstructing subdivision connectivity", The Visual Computer 18, 2002): after a 1-to-4 step (midpoint,
Loop) the original vertices are an independent set, every new vertex sits on an original edge between
two of them, and each original triangle left one central triangle of new vertices; after a sqrt(3)
step (Kobbelt) every new vertex is an original triangle's centroid, joined to its three corners; after
a Catmull-Clark step (Blender's Subdivision Surface) each triangle is three quads, which Blender's
exporters and its own triangulation split from their corner (all but a few), so that every triangle has
one original vertex, one edge point and one face point. The positions carry it too: a Loop edge vertex is
3/8 (a + b) + 1/8 (c + d) of the original edge (a, b) and its two opposite vertices, a sqrt(3) or
Catmull-Clark face point the mean of its triangle's corners, a Catmull-Clark edge point
(a + b + f1 + f2) / 4 with its two face points, whatever the scheme does to the original vertices (each
variant smooths them with its own weights). So the original positions follow from the new vertices by
linear least squares, exactly when the copy is exact (and closely when Blender's modifier puts the
vertices on its limit surface, its default: residual about 3e-5 of the diagonal, read as well).

Finding the original vertices. Around an interior vertex of valence 6, the vertices three steps apart
in its ring (opposite) are both original or both new in a 1-to-4 step (the ring of a new vertex on the
edge (a, b) runs a, new, new, b, new, new); two steps apart, both original or both new in a sqrt(3)
step (a face vertex's ring alternates original and new). The connected components of those pairs
(``_components``: numpy's on a small mesh, ``scipy.sparse.csgraph``'s on a large one) that hold no edge
of the mesh between two of their vertices (interior edges: a sqrt(3) step may keep the boundary's
original edges) are the candidates, and the structure is then checked in full (``coarse_mesh``); a
mesh that is not a subdivision fails the check. After a Catmull-Clark step no vertex touches one of its
own kind, and the kinds follow from the face counts and the neighbours (``_catmull_clark``); looked for
only when at least a fifth as many vertices as faces are in 4 faces or 2 (the edge points), which few
meshes have.

Everything here is from the suspect alone (no key, no pass phrase).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .adjacency import component_labels, edge_face_counts, flip_edges, numpy_sparse, twin_half_edges, unique_values
from .base import Progress, no_progress
from .metrics import bbox_diagonal, vertex_rmse

LOOP_ODD = (0.375, 0.125)  # a Loop edge vertex: 3/8 of each end of its edge, 1/8 of each opposite vertex
SOLVE_TOL = 1e-9  # the least-squares solve's relative residual (positions to about 1e-8 of the size)
SOLVE_REPORT = 10  # the solve calls its progress callback every this many iterations
KIND_ROUNDS = 4  # rounds of the neighbour rule that names a Catmull-Clark step's kinds of vertex
CC_LOOSE = 0.02  # the share of a Catmull-Clark copy's triangles whose quads may be left out (turned ones)
TURNED = 0.01  # a mesh with more vertices in an odd number of faces has no turned quads to put back
EXACT = 1e-9  # a rule fits exactly when its RMS residual is below this share of the bounding-box diagonal


@dataclass
class Coarse:
    """A coarse mesh found under a subdivided one. ``rule``: "midpoint" (the original vertices kept
    where they are), "loop" (solved from the edge vertices), "sqrt3" (solved from the face vertices) or
    "catmull-clark" (from both); ``vertices`` (n0, 3) float64, ``faces`` (m0, 3) int64; ``original``
    (n0,) int64 the suspect's index of each coarse vertex; ``residual`` the rule's RMS residual over the
    new vertices, a share of the bounding-box diagonal (0 for an exact copy, about the noise after an
    attack)."""

    rule: str
    vertices: np.ndarray
    faces: np.ndarray
    original: np.ndarray
    residual: float


def coarse_mesh(
    V: np.ndarray,
    F: np.ndarray,
    edge_counts: Optional[tuple[np.ndarray, np.ndarray]] = None,
    untangle: bool = True,
    progress: Progress = None,
) -> Optional[Coarse]:
    """The coarse mesh the mesh V (n, 3) float64, F (m, 3) int64 is one step of subdivision of (module
    docstring), or None for a mesh that is not one (0.02-0.1 s on 29k-270k faces). ``edge_counts``: the
    mesh's ``adjacency.edge_face_counts``, when the caller has them. ``untangle``: when no step is found,
    look again with the quads Blender's triangulation turned put back (``_unturned``). ``progress(fraction,
    message)``: after each coordinate of a least-squares solve (``_solve``), the longest steps."""
    report = progress or no_progress
    n, m = len(V), len(F)
    kinds = [k for k in (("1-to-4", 3, 4), ("sqrt3", 2, 3)) if m % k[2] == 0]
    if m < 8 or not (kinds or m % 6 == 0):
        return None
    count = np.bincount(F.ravel(), minlength=n)  # faces per vertex
    used = count > 0
    diag = bbox_diagonal(V) or 1.0
    if m % 6 == 0 and np.count_nonzero((count == 4) | (count == 2)) * 5 >= m:  # edge points, cheaply
        c = _catmull_clark(V, F, count, diag, report)
        if c is not None:
            return c
    if kinds:  # a necessary count before the structure
        sixes, fewest = np.count_nonzero(count == 6), _fewest_sixes(F, n, edge_counts)
        kinds = [k for k in kinds if sixes >= fewest[k[0]]]
    if not kinds:
        return None
    y, ring = _rings_of_six(F, count)
    if len(y) == 0:
        return None
    for kind, hops, _ in kinds:
        old = _old_vertices(F, used, y, ring, hops)
        if old is None or not _counts_fit(F, used, old, kind):
            continue
        new = np.flatnonzero(used & ~old)
        c = (
            _one_to_four(V, F, old, new, diag, report)
            if kind == "1-to-4"
            else _sqrt3(V, F, old, new, y, ring, diag, report)
        )
        if c is not None:
            return c
    turned = _unturned(F, count) if untangle else None
    return None if turned is None else coarse_mesh(V, turned, untangle=False, progress=report)


def _unturned(F: np.ndarray, count: np.ndarray) -> Optional[np.ndarray]:
    """F with the quads Blender's triangulation turned put back, or None when there is none.

    Two levels of Subdivision Surface on a triangle mesh read as a 1-to-4 step of the first level split
    along its quads' corner-to-centre diagonals, but Blender splits a concave quad along the other
    diagonal (a few per 100,000). Every vertex there is in an even number of faces, and a turned quad
    makes its four corners odd: an interior edge whose two ends and two opposite vertices are all in an
    odd number of faces, each vertex in one such edge, is flipped to the other diagonal. A mesh with no
    such edge (every exact 1-to-4 step: a new vertex is in 6 faces), or with more than TURNED of its
    vertices odd, is left alone."""
    odd = count % 2 == 1
    n = len(count)
    if not odd.any() or np.count_nonzero(odd) > TURNED * n:
        return None
    near = np.flatnonzero(odd[F].sum(1) >= 2)  # the faces that may hold such an edge (few)
    h1, h2 = twin_half_edges(F[near], n)
    h1, h2 = near[h1 // 3] * 3 + h1 % 3, near[h2 // 3] * 3 + h2 % 3  # (into F)
    Fl = F.ravel()
    quad = np.stack([Fl[h1], Fl[h2]] + [Fl[h - h % 3 + (h % 3 + 2) % 3] for h in (h1, h2)], 1)
    sel = odd[quad].all(1)  # both ends and both opposite vertices odd
    quad, h1, h2 = quad[sel], h1[sel], h2[sel]
    once = (np.bincount(quad.ravel(), minlength=n)[quad] == 1).all(1)  # each vertex in one flip only
    if not once.any():
        return None
    out = F.copy()
    flip_edges(out, h1[once], h2[once])
    return out


def _fewest_sixes(
    F: np.ndarray, n: int, edge_counts: Optional[tuple[np.ndarray, np.ndarray]] = None
) -> dict[str, float]:
    """The fewest vertices in exactly six faces that a 1-to-4 or a sqrt(3) step leaves in a mesh of the
    faces F (m, 3) over n vertices: a necessary count, checked before the structure: many meshes that are no
    subdivision (scanned or remeshed ones) fall short of it (docs/decisions/083-numpy-fast-paths.md).
    Every new vertex of a 1-to-4 step on an edge of two faces is in six (3 m / 8 of them, less a quarter
    of the boundary's edges); every face vertex of a sqrt(3) step in a triangle whose edges all flipped is
    (m / 3, less one per boundary edge); an edge of more than two faces takes one per face, counted
    generously."""
    _, sides = edge_face_counts(F, n) if edge_counts is None else edge_counts
    m = len(F)
    boundary = np.count_nonzero(sides == 1)
    extra = int(sides[sides > 2].sum())
    return {"1-to-4": 3 * m / 8 - boundary / 4 - extra, "sqrt3": m / 3 - boundary - extra}


def _catmull_clark(
    V: np.ndarray, F: np.ndarray, count: np.ndarray, diag: float, progress: Progress = None
) -> Optional[Coarse]:
    """The coarse mesh of a Catmull-Clark step of a triangle mesh (``attacks.subdivide``), or None when
    the structure does not hold. ``count`` (n,): faces per vertex.

    The step makes three kinds of vertices: the original ones (O), a point per edge (E), a point per
    face (P); each triangle three quads (o, e, p, e'), written as two triangles. Split from the corner
    (o, p), as Blender's exporters and triangulation split nearly all of them, every triangle has one
    vertex of each kind and no vertex touches one of its kind; Blender's triangulation splits a few
    quads (e, e') instead (concave ones: 1-2 of 209,000 quads on the bunny, 47-81 of 300,000 on the
    dragon, measured). The kinds: a first guess from the face counts (an E in 4, 2 on the boundary; a P
    in 6; an odd count, beside a turned quad, unknown), then KIND_ROUNDS rounds in which a vertex that
    touches its own kind while another kind is absent around it takes the absent one. A vertex is sure
    when its neighbours are what its kind has (an O: no O; an E: no E, two O, one or two P; a P: no P,
    three E); the coarse faces and the equations use sure vertices only, so a turned quad and the
    faces beside it are left out (CC_LOOSE of the triangles at most). The coarse mesh comes from the
    quads' sides, (o, e) and (e, p), whichever diagonal each quad has.

    Positions: a face point is its triangle's centroid, an interior edge point (a + b + p1 + p2) / 4 of
    its edge (a, b) and its two face points, a boundary one (a + b) / 2; the original vertices, whatever
    the variant does to them, follow by least squares as for Loop."""
    n = len(V)
    a, b = F.ravel(), np.roll(F, -1, axis=1).ravel()
    third = np.roll(F, -2, axis=1).ravel()
    used = count > 0
    ue = unique_values(np.minimum(a, b) * n + np.maximum(a, b))
    u, w = ue // n, ue % n  # the edges, once each

    def around(kind: np.ndarray) -> np.ndarray:
        """(n, 4) int64: each vertex's neighbours of each kind (0 O, 1 E, 2 P, 3 unknown)."""
        return (np.bincount(u * 4 + kind[w], minlength=4 * n) + np.bincount(w * 4 + kind[u], minlength=4 * n)).reshape(
            n, 4
        )

    # a first guess from the face counts (0 O, 1 E, 2 P, 3 unknown): 4 or 2 an edge point, 6 a face point
    # (or an original vertex of 3 edges), odd unknown; then KIND_ROUNDS rounds of the neighbour rule
    kind = np.select([(count == 4) | (count == 2), count == 6, count % 2 == 1], [1, 2, 3], 0)
    rows = np.arange(n)
    for _ in range(KIND_ROUNDS):
        seen = around(kind)
        absent = seen[:, :3] == 0
        n_absent = absent.sum(1)
        own = np.where(kind < 3, seen[rows, np.minimum(kind, 2)], 1)
        # a vertex whose own kind is among its neighbours while another is absent takes the absent one
        # (E when E is among them); an unknown one whose neighbours have all three is an E
        target = np.where((n_absent > 1) & absent[:, 1], 1, np.argmax(absent, axis=1))
        kind = np.where((own > 0) & (n_absent >= 1), target, np.where((kind == 3) & (n_absent == 0), 1, kind))
    kind = np.where(used, kind, -1)
    ka, kb = kind[a], kind[b]
    lo_k, hi_k = np.minimum(ka, kb), np.maximum(ka, kb)
    # the quads' sides, (o, e) and (e, p), whichever diagonal each quad has: each edge point's ends and
    # face points, each face point's edge points
    side_oe, side_ep = (lo_k == 0) & (hi_k == 1), (lo_k == 1) & (hi_k == 2)
    x_oe, y_oe = np.where(ka == 1, a, b)[side_oe], np.where(ka == 1, b, a)[side_oe]
    x_ep, y_ep = np.where(ka == 1, a, b)[side_ep], np.where(ka == 1, b, a)[side_ep]
    n_ends, ends_at, ends_of = _groups(x_oe, y_oe, n)
    n_pts, pts_at, pts_of = _groups(x_ep, y_ep, n)
    n_eps, eps_at, eps_of = _groups(y_ep, x_ep, n)
    # a vertex whose neighbours are what its kind has (an O: no O; an E: no E, two O, one or two P; a P:
    # no P, three E) is sure; the equations use sure vertices only (none of a turned quad's edge points)
    seen = around(np.maximum(kind, 0))
    sure = np.select(
        [kind == 0, kind == 1, kind == 2],
        [
            seen[:, 0] == 0,
            (seen[:, 1] == 0) & (seen[:, 0] == 2) & (seen[:, 2] >= 1) & (seen[:, 2] <= 2),
            (seen[:, 2] == 0) & (seen[:, 1] == 3),
        ],
        False,
    )
    ok_e = sure & (kind == 1) & (n_ends == 2) & (n_pts >= 1) & (n_pts <= 2)
    ok_e[ok_e] = sure[ends_of[ends_at[ok_e][:, None] + np.arange(2)]].all(1)
    ok_p = sure & (kind == 2) & (n_eps == 3)
    fv = np.flatnonzero(ok_p)
    e3 = eps_of[eps_at[fv][:, None] + np.arange(3)]  # each face point's three edge points
    ok_p[fv] = ok_e[e3].all(1)
    fv, e3 = fv[ok_p[fv]], e3[ok_p[fv]]
    ev = np.flatnonzero(ok_e)
    ends = np.full((n, 2), -1, np.int64)
    ends[ev] = ends_of[ends_at[ev][:, None] + np.arange(2)]
    # each face point's corners: the ends of its three edge points, each twice
    corners = np.sort(ends[e3].reshape(-1, 6), axis=1)[:, ::2]
    distinct = (corners[:, 0] < corners[:, 1]) & (corners[:, 1] < corners[:, 2])
    ok_p[fv[~distinct]] = False
    # orientation: the side o -> e of a quad runs from its corner o towards the next corner (the other
    # end of e), in the face whose point is the triangle's third vertex, or else the one face point of
    # the triangle's two edge points (a turned quad's corner triangle (o, e, e'))
    fwd = (ka == 0) & (kb == 1) & ok_e[b]
    o_, e_, z_ = a[fwd], b[fwd], third[fwd]
    nxt = np.where(ends[e_, 0] == o_, ends[e_, 1], ends[e_, 0])
    pts = np.full((n, 2), -1, np.int64)
    pts[ev, 0] = pts_of[pts_at[ev]]
    two = ev[n_pts[ev] == 2]
    pts[two, 1] = pts_of[pts_at[two] + 1]
    zp = pts[z_]
    shared = np.where((zp[:, 0] >= 0) & ((zp[:, 0] == pts[e_, 0]) | (zp[:, 0] == pts[e_, 1])), zp[:, 0], zp[:, 1])
    owner = np.where(kind[z_] == 2, z_, np.where(kind[z_] == 1, shared, -1))
    good = (owner >= 0) & ok_p[np.maximum(owner, 0)]
    first = np.full((n, 2), -1, np.int64)
    first[owner[good]] = np.stack([o_[good], nxt[good]], 1)  # one directed side per face point
    tri_f = np.stack([first[fv, 0], first[fv, 1], corners.sum(1) - first[fv].sum(1)], 1)
    ok_p[fv[(first[fv, 0] < 0) | ~(np.sort(tri_f, axis=1) == corners).all(1)]] = False
    keep_p = ok_p[fv]
    fv, tri_f = fv[keep_p], tri_f[keep_p]
    # nearly every triangle's quad is whole (a few near turned quads may not be): else no such step
    if len(fv) * 6 < (1.0 - CC_LOOSE) * len(F):
        return None
    # the equations: a face point is the mean of its corners, an edge point (a + b + p1 + p2) / 4
    inner = n_pts[ev] == 2
    terms = np.concatenate([tri_f, np.c_[ends[ev], np.full(len(ev), -1)]])  # (R, 3) vertices, -1: none
    weight = np.concatenate([np.full(len(fv), 1.0 / 3.0), np.where(inner, 0.25, 0.5)])
    psum = V[pts[ev, 0]] + np.where(inner[:, None], V[pts[ev, 1]], 0.0)
    rhs = np.concatenate([V[fv], V[ev] - np.where(inner[:, None], 0.25 * psum, 0.0)])
    keep, x, fit = _solve_terms(terms, weight, rhs, n, progress)
    index = np.full(n, -1, np.int64)
    index[keep] = np.arange(len(keep))
    return Coarse("catmull-clark", x, index[tri_f], keep, vertex_rmse(fit, rhs) / diag)


def _solve_terms(
    terms: np.ndarray, weight: np.ndarray, rhs: np.ndarray, n: int, progress: Progress = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares over the equations sum_k weight[r] x[terms[r, k]] = rhs[r] (terms (R, 3) vertex
    indices below n, -1 for none; weight (R,); rhs (R, 3)): the vertices solved for (K,) ascending, their
    positions (K, 3) and each equation's left side at them (R, 3)."""
    from scipy.sparse import coo_matrix

    keep = unique_values(terms[terms >= 0])
    index = np.full(n, -1, np.int64)
    index[keep] = np.arange(len(keep))
    used = terms >= 0
    r = np.broadcast_to(np.arange(len(terms))[:, None], terms.shape)[used]
    A = coo_matrix(
        (np.broadcast_to(weight[:, None], terms.shape)[used], (r, index[terms[used]])), shape=(len(terms), len(keep))
    ).tocsr()
    x = _solve(A, rhs, progress)
    return keep, x, A @ x


def _groups(x: np.ndarray, y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct y of each vertex x, for the pairs (x, y) (p,) int64 of vertices below n: how many
    (n,), where each vertex's start in the third array (n,), and the y grouped by x, ascending."""
    keys = unique_values(x * n + y)
    per = np.bincount(keys // n, minlength=n)
    return per, np.cumsum(per) - per, keys % n


def _counts_fit(F: np.ndarray, used: np.ndarray, old: np.ndarray, kind: str) -> bool:
    """The counts a subdivision of that kind has, before the full check: 1-to-4, no face with two
    original vertices and a quarter of the faces with none (the central ones); sqrt(3), one new vertex
    per three faces."""
    per_face = old[F].sum(1)
    if kind == "1-to-4":
        return int(per_face.max()) <= 1 and int(np.count_nonzero(per_face == 0)) * 4 == len(F)
    return int(np.count_nonzero(used & ~old)) * 3 == len(F)


def _rings_of_six(F: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices of exactly six faces (``count`` (n,): faces per vertex) whose faces close one fan
    around them (interior, manifold, valence 6): y (R,) int64 and their rings in fan order, (R, 6) int64."""
    corners = F.ravel()
    y = np.flatnonzero(count == 6)
    if len(y) == 0:
        return y, np.zeros((0, 6), np.int64)
    order = np.argsort(corners, kind="stable")  # the corners grouped by vertex
    first = np.cumsum(count) - count
    sel = order[first[y][:, None] + np.arange(6)]  # (R, 6) flat corner ids
    # the corner's face is (y, p, q): the fan goes p -> q
    p, q = np.roll(F, -1, axis=1).ravel()[sel], np.roll(F, -2, axis=1).ravel()[sel]
    match = q[:, :, None] == p[:, None, :]  # (R, i, j): corner j follows corner i
    nxt = np.argmax(match, axis=2)
    ok = (match.sum(2) == 1).all(1)  # every corner followed by exactly one
    ring = np.empty_like(p)
    rows = np.arange(len(y))
    cur = np.zeros(len(y), np.int64)
    seen = np.zeros((len(y), 6), bool)
    for s in range(6):
        ring[:, s] = p[rows, cur]
        seen[rows, cur] = True
        cur = nxt[rows, cur]
    ok &= (cur == 0) & seen.all(1)  # one closed fan of six
    return y[ok], ring[ok]


def _old_vertices(F: np.ndarray, used: np.ndarray, y: np.ndarray, ring: np.ndarray, hops: int) -> Optional[np.ndarray]:
    """(n,) bool: the candidate original vertices (module docstring), or None when there are none.
    used (n,): the vertices of a face; y (R,), ring (R, 6): the interior valence-6 vertices and their
    rings in fan order (``_rings_of_six``)."""
    n = len(used)
    p = ring.ravel()
    q = np.roll(ring, -hops, axis=1).ravel()
    label, n_comp = _components(p, q, n)
    # a component is a candidate when no edge joins two of its vertices, one of them an interior vertex
    # of valence 6 (a sqrt(3) step may keep the boundary's original edges; the full check follows)
    six = np.zeros(n, bool)
    six[y] = True
    a, b = F.ravel(), np.roll(F, -1, axis=1).ravel()
    same = (label[a] == label[b]) & (six[a] | six[b])
    joined = np.zeros(n_comp, bool)
    joined[label[a[same]]] = True
    # (a vertex in no pair, e.g. an original one on the boundary whose faces all touch it, stands alone;
    # a vertex of no face is none of the mesh's)
    old = ~joined[label] & used
    return old if old.any() else None


def _components(p: np.ndarray, q: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """The connected components of the graph on n vertices with edges (p, q) (k,) int64: each vertex's
    label (n,) and the labels' bound. A small mesh (``adjacency.numpy_sparse``) takes them from
    ``adjacency.component_labels`` (each labelled by its smallest vertex id; a vertex on no edge by its
    own), without importing scipy.sparse: the unmarked bundled bunny's subdivision look (157,272 pairs,
    labelled here in 37 ms) would otherwise pay the import (0.11-0.17 s of a fresh process; measured:
    docs/decisions/083-numpy-fast-paths.md). Larger graphs go to
    scipy's ``connected_components`` (``component_labels``' docstring says why). Both give the same
    partition, which is all ``_old_vertices`` uses."""
    if numpy_sparse(n):
        label = np.arange(n)
        if len(p):
            edge_label = component_labels(np.stack([p, q], axis=1))
            label[p] = edge_label
            label[q] = edge_label
        return label, n
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_comp, label = connected_components(coo_matrix((np.ones(len(p), np.int8), (p, q)), shape=(n, n)), directed=False)
    return label, n_comp


def _old_of_new(F: np.ndarray, old: np.ndarray, new: np.ndarray, count: int) -> Optional[np.ndarray]:
    """For each of the vertices ``new`` (k,) (ascending, none of them in ``old``), the ``count`` vertices
    of ``old`` it shares a face with, (k, count) int64 ascending; None when one has another number."""
    is_new = np.zeros(len(old), bool)
    is_new[new] = True
    # every (new, old) pair of a face
    pn = np.broadcast_to(F[:, :, None], (len(F), 3, 3))
    po = np.broadcast_to(F[:, None, :], (len(F), 3, 3))
    pick = is_new[F][:, :, None] & old[F][:, None, :]
    return _distinct(pn[pick], po[pick], new, count, len(old))


def _distinct(a: np.ndarray, b: np.ndarray, new: np.ndarray, count: int, n: int) -> Optional[np.ndarray]:
    """Of the pairs (a, b) (p,) int64 of vertices below n, where every a is in ``new`` (k,) ascending: the
    distinct b of each vertex of ``new``, (k, count) int64 ascending; None when one has another number."""
    per, _, of = _groups(a, b, n)
    if np.any(per[new] != count):
        return None
    return of.reshape(-1, count)  # (grouped by a, ascending)


def _solve(A, b: np.ndarray, progress: Progress = None) -> np.ndarray:
    """Least squares A x = b, A sparse (r, c), b (r, 3): the normal equations by conjugate gradients
    (Jacobi preconditioned; 50-120 iterations on the meshes tried); ``progress(fraction, message)`` every
    SOLVE_REPORT iterations and after each coordinate."""
    report = progress or no_progress
    from scipy.sparse import diags
    from scipy.sparse.linalg import cg

    N = (A.T @ A).tocsr()
    rhs = A.T @ b
    d = N.diagonal()
    M = diags(1.0 / np.where(d > 0, d, 1.0))
    x = np.empty((A.shape[1], 3))
    for k in range(3):
        done = [0]

        def iteration(_, k: int = k) -> None:
            done[0] += 1
            if done[0] % SOLVE_REPORT == 0:  # (the iterations' count is not known: at most 0.9 of a coordinate)
                report((k + min(0.9, done[0] / 150)) / 3, "solving for the mesh it was subdivided from")

        x[:, k] = cg(N, rhs[:, k], rtol=SOLVE_TOL, maxiter=1000, M=M, callback=iteration)[0]
        report((k + 1) / 3, "solving for the mesh it was subdivided from")
    return x


def _one_to_four(
    V: np.ndarray, F: np.ndarray, old: np.ndarray, new: np.ndarray, diag: float, progress: Progress = None
) -> Optional[Coarse]:
    """The coarse mesh of a 1-to-4 step (midpoint, Loop), or None when the structure does not hold."""
    from scipy.sparse import coo_matrix

    ends = _old_of_new(F, old, new, 2)
    if ends is None:
        return None
    slot = np.full(len(old), -1, np.int64)
    slot[new] = np.arange(len(new))
    central = F[~old[F].any(1)]
    x, y, z = (slot[central[:, k]] for k in range(3))

    def common(s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The original vertex the edge vertices s and t (slots) share, -1 where not exactly one."""
        a, b = ends[s], ends[t]
        first = (a[:, :1] == b).any(1)
        second = (a[:, 1:] == b).any(1)
        return np.where(first & ~second, a[:, 0], np.where(second & ~first, a[:, 1], -1))

    ca, cb, cc = common(z, x), common(x, y), common(y, z)
    if min(ca.min(), cb.min(), cc.min()) < 0:
        return None
    keep = np.flatnonzero(old)
    index = np.full(len(old), -1, np.int64)
    index[keep] = np.arange(len(keep))
    faces = index[np.stack([ca, cb, cc], 1)]
    # central face (x, y, z) over the coarse (a, b, c): x on edge (a, b) opposite c, y opposite a, z opposite b
    odd = np.concatenate([x, y, z])
    opp = index[np.concatenate([cc, ca, cb])]
    sides = np.bincount(odd, minlength=len(new))  # 2 central faces: an interior edge; 1: a boundary one
    if np.any((sides < 1) | (sides > 2)):
        return None
    e = V[new]
    mid = vertex_rmse(e, 0.5 * (V[ends[:, 0]] + V[ends[:, 1]])) / diag
    if mid <= EXACT:
        return Coarse("midpoint", V[keep].copy(), faces, keep, mid)
    interior = sides == 2
    w_end = np.where(interior, LOOP_ODD[0], 0.5)
    rows = np.concatenate([np.repeat(np.arange(len(new)), 2), odd])
    cols = np.concatenate([index[ends].ravel(), opp])
    vals = np.concatenate([np.repeat(w_end, 2), np.where(interior[odd], LOOP_ODD[1], 0.0)])
    A = coo_matrix((vals, (rows, cols)), shape=(len(new), len(keep))).tocsr()
    loop = _solve(A, e, progress)
    res = vertex_rmse(A @ loop, e) / diag
    if res < mid:
        return Coarse("loop", loop, faces, keep, res)
    return Coarse("midpoint", V[keep].copy(), faces, keep, mid)


def _sqrt3(
    V: np.ndarray,
    F: np.ndarray,
    old: np.ndarray,
    new: np.ndarray,
    y: np.ndarray,
    ring: np.ndarray,
    diag: float,
    progress: Progress = None,
) -> Optional[Coarse]:
    """The coarse mesh of a sqrt(3) step, or None when the structure does not hold. The faces take the
    orientation of the face vertex's fan where it has valence 6 (all but the boundary's)."""
    from scipy.sparse import coo_matrix

    corners = _old_of_new(F, old, new, 3)
    if corners is None:
        return None
    keep = np.flatnonzero(old)
    index = np.full(len(old), -1, np.int64)
    index[keep] = np.arange(len(keep))
    # valence-6 face vertices: their ring alternates original and new; the originals in fan order
    row = np.full(len(old), -1, np.int64)
    row[y] = np.arange(len(y))
    r = row[new]
    six = r >= 0
    rr = ring[r[six]]
    start = np.where(old[rr[:, 0]], 0, 1)
    fan = np.take_along_axis(rr, start[:, None] + np.array([[0, 2, 4]]), axis=1)
    fits = (np.sort(fan, axis=1) == corners[six]).all(1)
    ordered = corners.copy()
    ordered[np.flatnonzero(six)[fits]] = fan[fits]
    faces = index[ordered]
    rows = np.repeat(np.arange(len(new)), 3)
    A = coo_matrix((np.full(len(rows), 1.0 / 3.0), (rows, faces.ravel())), shape=(len(new), len(keep))).tocsr()
    e = V[new]
    x = _solve(A, e, progress)
    return Coarse("sqrt3", x, faces, keep, vertex_rmse(A @ x, e) / diag)
