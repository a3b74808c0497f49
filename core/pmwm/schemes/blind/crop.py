"""The frame of a cropped copy: the plane that cut the surface, and the centre the cut took away.

A plane crop removes a cap of the surface beyond a plane. The area centroid of what is left moves away
from the cut by 5-21 bin widths and the range [lo, hi] by up to 9 (10 % crops of the four benchmark
models), far beyond ``radial.refine_frame``'s reach. But the original centroid c0 is the area-weighted
mean of what is left (centroid c) and of the cap: c0 = c + lam (c_cap - c), lam the cap's share of the
area; and the cap lies beyond the cut, around the hole it left: c_cap ~ h + t n, h the centroid of the
cut's boundary edges, n the cut plane's normal pointing away from c. Measured on the bunny, dragon, Venus
head and Igea, 6 crops of 10 % each: c0 lies within 0.7 bin widths of this two-parameter family in 22
of 24 crops (1.8 at most), the rest of the way mostly off the family's plane (the plane through c
spanned by h - c and n). The reader searches it (``crop_frame``):

1. the cut planes (``cut_planes``): boundary loops that lie in a plane, coplanar loops together (a
   plane that cuts two ears leaves two loops);
2. candidate centres on the family (lam <= LAMBDA_MAX, t in T_RANGE, within REACH bin widths of c), on
   a lattice of LATTICE bin widths;
3. for each candidate, lo from the area quantile of what is left that is the original's 2 % quantile if
   the cap held none of the innermost vertices (2 % / (1 - lam)), and the bin width over -20 % .. +25 %
   (a crop moves hi by several bins), scored by the mark's energy (``radial.scale_energies``) on
   COARSE_SAMPLE vertices;
4. the TOP best candidates: the best of OFF_PLANE offsets off the family's plane, then the width and lo
   again, finely, on up to REFINE_SAMPLE vertices, and ``radial.refine_frame``; the FINAL best of those
   once more from their refined centre; the frame whose reading shows the most energy wins.

The integer part of lo comes from the quantile alone: a frame one bin off shows nearly the same energy
(the same bins, one end swapped) but reads the word shifted. Nothing here involves the pass phrase,
so the search costs the p-value nothing. Measured (scratch, 40 crops of 10 %: the packaged bunny's
test key on 8 crops, then 2 keys x 4 crops on each benchmark model, the 64-bin word): the frame found
reads with at most 3 bit errors in 33 of 40 (packaged bunny 6 of 8, bunny 7, dragon 5, Venus head 8,
Igea 7; whole payloads: BENCHMARKS.md, section ``blind``); with coarse samples of 2000 vertices
instead of 6000: 25; with t >= 0 only and no offsets: 30; fitting again all 6 finalists instead of
the best 3: 33, a sixth slower. A 30 % crop mostly moves the width beyond the range searched.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ...adjacency import build_adjacency
from .radial import (QUANTILES, REFINE_SAMPLE, Frame, excess_energy, refine_frame, scale_energies,
                     statistics_in, vertex_areas)

LAMBDA_MAX = 0.4  # the largest share of the area a crop may have taken
T_RANGE = (-0.1, 0.6)  # the cap's centroid from the cut, along its normal, in bounding-box diagonals
REACH = 30.0  # candidate centres within this many bin widths of the suspect's centroid
LATTICE = 0.3  # spacing of the candidate centres, in bin widths (the mark shows within about 0.5)
COARSE_SAMPLE = 6000  # vertices scoring every candidate centre
COARSE_WIDTHS = np.linspace(0.8, 1.25, 23)  # bin widths tried, relative to the suspect's own
COARSE_PHASES = np.linspace(-0.75, 0.75, 5)  # lo offsets tried, in bin widths
FINE_WIDTHS = np.linspace(0.8, 1.25, 361)
FINE_PHASES = np.linspace(-0.5, 0.5, 33)  # within half a bin: a whole bin off reads the word shifted
TOP = 6  # candidates searched finely
OFF_PLANE = np.linspace(-1.5, 1.5, 11)  # offsets of a candidate off its family's plane, in bin widths
FINAL = 3  # of those, the best fitted again at their refined centre
MIN_EDGES = 12  # a boundary loop of fewer edges is not a cut
MAX_LOOPS = 32  # the largest loops are looked at, no more (a mesh may have thousands of holes)
MAX_PLANES = 4  # the cut planes searched, those of the largest loops first
THICKNESS = 2.0  # a loop is planar when it lies within this many mean edge lengths (RMS) of a plane
_BATCH = 32  # candidate centres scored together


def cut_planes(V: np.ndarray, F: np.ndarray, centre: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The planes in which the mesh V (n, 3), F (m, 3) was cut: [(h (3,), normal (3,))], h the
    length-weighted centroid of the boundary edges in the plane, the unit normal pointing away from
    ``centre``. A boundary loop of at least MIN_EDGES edges is a cut when its edges' midpoints lie within
    THICKNESS of its mean edge length from a plane (RMS; a crop deletes the faces of the vertices beyond
    the plane, so the loop zigzags within about an edge of it); loops in the same plane (the largest
    first) count together, and the plane is fitted to all of them. The MAX_LOOPS largest loops are looked
    at, and the planes of the MAX_PLANES largest are returned."""
    if _closed(F, len(V)):
        return []
    adj = build_adjacency(F, len(V), detect_pinches=False)
    E = adj.edges[adj.edge_face_count == 1]
    if len(E) < MIN_EDGES:
        return []
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    _, label = connected_components(graph, directed=False)
    loop = label[E[:, 0]]
    mid = 0.5 * (V[E[:, 0]] + V[E[:, 1]])
    length = np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)
    loops, size = np.unique(loop, return_counts=True)
    flat = []
    for k in loops[np.argsort(-size, kind="stable")][:MAX_LOOPS]:
        on = loop == k
        if on.sum() < MIN_EDGES:
            break
        if not length[on].sum() > 0:
            continue
        h, n = _plane(mid[on], length[on])
        if _thickness(mid[on], length[on], h, n) <= THICKNESS:
            flat.append((h, n, on))
    planes = []
    used = np.zeros(len(flat), bool)
    for i, (h, n, on) in enumerate(flat):
        if used[i]:
            continue
        group = on.copy()
        for j in range(i + 1, len(flat)):
            if not used[j] and _thickness(mid[flat[j][2]], length[flat[j][2]], h, n) <= THICKNESS:
                group |= flat[j][2]
                used[j] = True
        h, n = _plane(mid[group], length[group])
        planes.append((h, n if (h - centre) @ n >= 0 else -n))
    return planes[:MAX_PLANES]


def _closed(F: np.ndarray, n: int) -> bool:
    """Whether every half-edge (a, b) of the faces F (m, 3) has its twin (b, a), so that no edge is on a
    boundary: the sums of x_a y_b and of x_b y_a over the half-edges agree (random 64-bit x, y from a
    fixed seed, arithmetic modulo 2^64), a test without sorting the edges (Igea: 13 ms against about 50
    for the adjacency). A mesh that fails it is looked at edge by edge."""
    x, y = np.random.default_rng(0).integers(1, 2**63, size=(2, n), dtype=np.uint64)
    a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
    return bool(np.sum(x[a] * y[b], dtype=np.uint64) == np.sum(x[b] * y[a], dtype=np.uint64))


def _plane(P: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares plane of points P (k, 3), weights w (k,): centroid (3,), unit normal (3,)."""
    h = (P * w[:, None]).sum(0) / w.sum()
    d = P - h
    return h, np.linalg.eigh((d * w[:, None]).T @ d)[1][:, 0]


def _thickness(P: np.ndarray, w: np.ndarray, h: np.ndarray, n: np.ndarray) -> float:
    """RMS distance of the edge midpoints P (k, 3) (weights w, the edges' lengths) to the plane (h, n), in
    mean edge lengths."""
    return float(np.sqrt(np.average(((P - h) @ n) ** 2, weights=w)) / np.mean(w))


def _low_quantile(rho: np.ndarray, w: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Per row of rho (B, n), the w-weighted quantile q (B,). Small q: the lowest values are sorted
    alone, unless their weight falls short of the quantile (then the whole rows)."""
    n = rho.shape[1]
    k = min(n, max(8, int(np.ceil(3 * float(q.max()) * n)) + 8))
    target = q * w.sum()
    while True:
        part = np.argpartition(rho, k - 1, axis=1)[:, :k] if k < n else np.broadcast_to(np.arange(n), rho.shape)
        low = np.take_along_axis(rho, part, 1)
        order = np.argsort(low, axis=1)
        low = np.take_along_axis(low, order, 1)
        cw = np.cumsum(w[np.take_along_axis(part, order, 1)], axis=1)
        if k == n or np.all(cw[:, -1] >= target):
            return low[np.arange(len(rho)), np.argmax(cw >= target[:, None], axis=1)]
        k = n


def _candidates(c: np.ndarray, planes, width: float, diag: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Candidate centres (K, 3) on every plane's family c + lam (h + t n - c), with their lam (K,) and the
    unit normal of their family's plane (K, 3) (the plane through c spanned by h - c and n)."""
    lam = np.linspace(0.0, LAMBDA_MAX, 161)[:, None, None]
    t = np.linspace(T_RANGE[0] * diag, T_RANGE[1] * diag, 121)[None, :, None]
    C, L, N = [], [], []
    for h, n in planes:
        off = np.cross(h - c, n)
        C.append((c + lam * (h + t * n - c)).reshape(-1, 3))
        L.append(np.broadcast_to(lam, (161, 121, 1)).reshape(-1))
        N.append(np.broadcast_to(off / max(float(np.linalg.norm(off)), 1e-300), (161 * 121, 3)))
    C, L, N = np.concatenate(C), np.concatenate(L), np.concatenate(N)
    near = np.linalg.norm(C - c, axis=1) <= REACH * width
    C, L, N = C[near], L[near], N[near]
    cell = np.round((C - c) / (LATTICE * width)).astype(np.int64)
    _, first = np.unique(cell, axis=0, return_index=True)
    first.sort()
    return C[first], L[first], N[first]


def _coarse(P: np.ndarray, area: np.ndarray, C: np.ndarray, lam: np.ndarray, width: float, n_bins: int) -> np.ndarray:
    """The coarse score of candidate centres C (K, 3) with their lam (K,): the most mark energy over
    COARSE_WIDTHS x COARSE_PHASES, lo from the area quantile, on the vertices P (k, 3) of areas (k,).
    P and C relative to a point near them (the suspect's centroid): the distances come from a matrix
    product, |p|^2 + |c|^2 - 2 c.p (a third of the time of the differences; the error, about 1e-16 of
    the squared radius, is far below a bin)."""
    score = np.empty(len(C))
    p2 = np.einsum("ij,ij->i", P, P)
    for s in range(0, len(C), _BATCH):
        Cb = C[s:s + _BATCH]
        rho = np.sqrt(np.maximum(p2 + np.einsum("ij,ij->i", Cb, Cb)[:, None] - 2.0 * (Cb @ P.T), 0.0))
        lo = _low_quantile(rho, area, QUANTILES[0] / (1.0 - lam[s:s + _BATCH]))
        e = scale_energies(rho, np.ones(len(P)), lo, width * COARSE_WIDTHS, COARSE_PHASES, n_bins)
        score[s:s + _BATCH] = e.reshape(len(rho), -1).max(1)
    return score


def crop_frame(V: np.ndarray, F: np.ndarray, a: np.ndarray, own: Frame, n_bins: int,
               planes: Optional[list] = None) -> Optional[tuple[Frame, float]]:
    """The frame of n_bins bins where a cropped copy shows the most mark energy, and that energy's
    ``excess_energy``; None when the mesh has no cut plane. V (n, 3), F (m, 3), a (n,) the reader's
    vertex weights, ``own`` the suspect's own frame (its centre and range). ``planes``: ``cut_planes``
    when the caller has them."""
    if planes is None:
        planes = cut_planes(V, F, own.centre)
    if not planes:
        return None
    width = (own.hi - own.lo) / n_bins
    area = vertex_areas(V, F)
    keep = np.flatnonzero(a > 0)
    rho_own = np.linalg.norm(V[keep] - own.centre, axis=1)
    by_rho = keep[np.argsort(rho_own, kind="stable")]
    sub = by_rho[:: max(1, -(-len(by_rho) // COARSE_SAMPLE))]
    C, L, N = _candidates(own.centre, planes, width, float(np.linalg.norm(V.max(0) - V.min(0))))
    Pc, Cc = V[sub] - own.centre, C - own.centre
    score = _coarse(Pc, area[sub], Cc, L, width, n_bins)
    fine = by_rho[:: max(1, -(-len(by_rho) // REFINE_SAMPLE))]
    total = float(a.sum())

    def fit(centre: np.ndarray, lam: float) -> tuple[float, Frame]:
        fr = refine_frame(V, a, _fit_scale(V[fine], a[fine], area[fine], centre, lam, width, n_bins), n_bins)
        return excess_energy(*statistics_in(V, a, fr, [n_bins])[0], total), fr

    fits = []
    for i in np.argsort(-score, kind="stable")[:TOP]:
        # off the family's plane (the cap's centroid off the hole's axis), then the scale and the frame
        off = Cc[i] + np.outer(OFF_PLANE * width, N[i])
        best_off = off[int(np.argmax(_coarse(Pc, area[sub], off, np.full(len(off), L[i]), width, n_bins)))]
        fits.append((*fit(own.centre + best_off, L[i]), L[i]))
    fits.sort(key=lambda f: -f[0])
    best = None
    for z, fr, lam in fits[:FINAL]:  # the scale again at the refined centre, and the frame nearby
        z, fr = max((z, fr), fit(fr.centre, lam), key=lambda f: f[0])
        if best is None or z > best[1]:
            best = (fr, z)
    return best


def _fit_scale(P: np.ndarray, a: np.ndarray, area: np.ndarray, centre: np.ndarray, lam: float, width: float,
               n_bins: int) -> Frame:
    """The frame around ``centre`` whose lo (near the area quantile the crop left of the original's,
    ``lam`` its share taken) and bin width (FINE_WIDTHS times ``width``) show the most mark energy on the
    vertices P (k, 3) with reader weights a (k,) and areas (k,)."""
    rho = np.linalg.norm(P - centre, axis=1)[None]
    lo = _low_quantile(rho, area, np.array([QUANTILES[0] / (1.0 - lam)]))
    e = scale_energies(rho, a, lo, width * FINE_WIDTHS, FINE_PHASES, n_bins)[0]
    wi, pi = np.unravel_index(int(np.argmax(e)), e.shape)
    w = width * FINE_WIDTHS[wi]
    start = float(lo[0] + FINE_PHASES[pi] * w)
    return Frame(centre, start, start + n_bins * w, n_bins)
