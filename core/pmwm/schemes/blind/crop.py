"""The frame of a cropped copy: the plane that cut the surface, and the centre the cut took away.

A plane crop removes a cap of the surface beyond a plane. The area centroid of what is left moves away
from the cut by 5-21 bin widths and the range [lo, hi] by up to 9 (10 % crops of the four benchmark
models), far beyond ``radial.refine_frame``'s reach. But the original centroid c0 is the area-weighted
mean of what is left (centroid c) and of the cap: c0 = c + lam (c_cap - c), lam the cap's share of the
area; and the cap lies beyond the cut, around the hole it left: c_cap ~ h + t n, h the centroid of the
cut's boundary edges, n the cut plane's normal pointing away from c. Measured on the bunny, dragon, Venus
head and Igea, 6 crops of 10 % each: c0 lies within 0.7 bin widths of this two-parameter family in 20
of 24 crops and within 1 in 23 (1.8 at most), the rest of the way mostly off the family's plane (the
plane through c spanned by h - c and n). The reader searches it (``crop_frames``, for each word length):

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
instead of 6000: 24; with t >= 0 only and no offsets: 30; fitting again all 6 finalists instead of
the best 3: 33, a sixth slower. A 30 % crop mostly moves the width beyond the range searched.
"""

from __future__ import annotations

import numpy as np

from ...adjacency import build_adjacency, is_closed
from .radial import (QUANTILES, REFINE_SAMPLE, Frame, excess_energy, refine_frame, scale_energies,
                     statistics_in, weighted_quantiles)

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
    if is_closed(F, len(V)):
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


def _plane(P: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares plane of points P (k, 3), weights w (k,): centroid (3,), unit normal (3,)."""
    h = (P * w[:, None]).sum(0) / w.sum()
    d = P - h
    return h, np.linalg.eigh((d * w[:, None]).T @ d)[1][:, 0]


def _thickness(P: np.ndarray, w: np.ndarray, h: np.ndarray, n: np.ndarray) -> float:
    """RMS distance of the edge midpoints P (k, 3) (weights w, the edges' lengths) to the plane (h, n), in
    mean edge lengths."""
    return float(np.sqrt(np.average(((P - h) @ n) ** 2, weights=w)) / np.mean(w))


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
        lo = weighted_quantiles(rho, area, QUANTILES[0] / (1.0 - lam[s:s + _BATCH]))[:, 0]
        e = scale_energies(rho, np.ones(len(P)), lo, width * COARSE_WIDTHS, COARSE_PHASES, n_bins)
        score[s:s + _BATCH] = e.reshape(len(rho), -1).max(1)
    return score


def crop_frames(V: np.ndarray, a: np.ndarray, area: np.ndarray, own: Frame, planes: list,
                bin_counts) -> list[tuple[Frame, float]]:
    """For each count in ``bin_counts``, the frame of that many bins where a cropped copy shows the most
    mark energy near the families of the cut ``planes`` (``cut_planes``, not empty), and that frame's
    ``excess_energy``. V (n, 3); a (n,) the reader's vertex weights; area (n,) ``vertex_areas``;
    ``own`` the suspect's own frame (its centre and range)."""
    keep = np.flatnonzero(a > 0)
    by_rho = keep[np.argsort(np.linalg.norm(V[keep] - own.centre, axis=1), kind="stable")]
    sub = by_rho[:: max(1, -(-len(by_rho) // COARSE_SAMPLE))]
    fine = by_rho[:: max(1, -(-len(by_rho) // REFINE_SAMPLE))]
    Pc, area_sub = V[sub] - own.centre, area[sub]
    Pf, af, area_f = V[fine], a[fine], area[fine]
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    total = float(a.sum())
    found = []
    for n_bins in bin_counts:
        width = (own.hi - own.lo) / n_bins
        C, L, N = _candidates(own.centre, planes, width, diag)
        Cc = C - own.centre
        score = _coarse(Pc, area_sub, Cc, L, width, n_bins)

        def fit(centre: np.ndarray, lam: float) -> tuple[float, Frame]:
            fr = refine_frame(V, a, _fit_scale(Pf, af, area_f, centre, lam, width, n_bins), n_bins)
            return excess_energy(*statistics_in(V, a, fr, [n_bins])[0], total), fr

        fits = []
        for i in np.argsort(-score, kind="stable")[:TOP]:
            # off the family's plane (the cap's centroid off the hole's axis), then the scale and the frame
            off = Cc[i] + np.outer(OFF_PLANE * width, N[i])
            best_off = off[int(np.argmax(_coarse(Pc, area_sub, off, np.full(len(off), L[i]), width, n_bins)))]
            fits.append((*fit(own.centre + best_off, L[i]), L[i]))
        fits.sort(key=lambda f: -f[0])
        # the FINAL best, and each fitted again at its refined centre: the one of most energy
        finals = [f for z, fr, lam in fits[:FINAL] for f in ((z, fr), fit(fr.centre, lam))]
        z, fr = max(finals, key=lambda f: f[0])
        found.append((fr, z))
    return found


def _fit_scale(P: np.ndarray, a: np.ndarray, area: np.ndarray, centre: np.ndarray, lam: float, width: float,
               n_bins: int) -> Frame:
    """The frame around ``centre`` whose lo (near the area quantile the crop left of the original's,
    ``lam`` its share taken) and bin width (FINE_WIDTHS times ``width``) show the most mark energy on the
    vertices P (k, 3) with reader weights a (k,) and areas (k,)."""
    rho = np.linalg.norm(P - centre, axis=1)[None]
    lo = weighted_quantiles(rho, area, [QUANTILES[0] / (1.0 - lam)])[:, 0]
    e = scale_energies(rho, a, lo, width * FINE_WIDTHS, FINE_PHASES, n_bins)[0]
    wi, pi = np.unravel_index(int(np.argmax(e)), e.shape)
    w = width * FINE_WIDTHS[wi]
    start = float(lo[0] + FINE_PHASES[pi] * w)
    return Frame(centre, start, start + n_bins * w, n_bins)
