"""The frame of a cropped copy: the plane that cut the surface, and the centre the cut took away.

A plane crop moves the surface's area centroid and range far beyond ``radial.refine_frame``'s reach. The
original centroid c0 = c + lam (c_cap - c) (c the centroid of what is left, lam the cap's share of the area)
lies near a two-parameter family given by the cut: c_cap ~ h + t n, h the centroid of the cut's boundary edges,
n the cut plane's normal. ``cut_planes`` finds the cuts; ``crop_frames`` searches the family and copies of it
off its plane for the frame of each word length that shows the most mark energy. Key-free: the search costs
the p-value nothing. Its settings: ``config.CropConfig``. The algorithm: docs/schemes/blind.md; the
measurements behind them: docs/decisions/081-blind-crop-frame-search.md."""

from __future__ import annotations

import threading

import numpy as np

from ...adjacency import boundary_edges, component_labels, unique_values
from ...background import parallel_map
from ...base import Progress, no_progress
from ...features import row_norms
from ...metrics import bbox_diagonal
from ...spatial import pairs_within
from .config import READER, CropConfig, CutConfig
from .radial import (
    QUANTILES,
    REFINE_SAMPLE,
    SCALE_CELLS,
    Frame,
    by_distance,
    cell_energies,
    cumulative_cells,
    distances,
    excess_energy,
    in_phase,
    low_quantile,
    refine_frame_on,
    scale_energies,
    statistics_in,
    thinned,
)

_BATCH = 32  # candidate centres scored together (a memory bound, not a tuning)


def cut_planes(
    V: np.ndarray, F: np.ndarray, centre: np.ndarray, cfg: CutConfig = READER.crop.cut
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The planes in which the mesh V (n, 3), F (m, 3) was cut: [(h (3,), normal (3,))], h the
    length-weighted centroid of the boundary edges in the plane, the unit normal pointing away from
    ``centre``. A boundary loop of at least ``cfg.min_edges`` edges is a cut when its edges' midpoints lie within
    ``cfg.thickness`` of its mean edge length from a plane (RMS; a crop deletes the faces of the vertices beyond
    the plane, so the loop zigzags within about an edge of it); loops in the same plane (the largest
    first) count together, and the plane is fitted to all of them. The ``cfg.max_loops`` largest loops are
    looked at, and the planes of the ``cfg.max_planes`` largest are returned."""
    E = boundary_edges(F, len(V))
    if len(E) < cfg.min_edges:
        return []
    loop = component_labels(E)
    mid = 0.5 * (V[E[:, 0]] + V[E[:, 1]])
    length = row_norms(V[E[:, 1]] - V[E[:, 0]])
    loops, size = np.unique(loop, return_counts=True)
    flat = []
    for k in loops[np.argsort(-size, kind="stable")][: cfg.max_loops]:
        on = loop == k
        if on.sum() < cfg.min_edges:
            break
        if not length[on].sum() > 0:
            continue
        h, n = _plane(mid[on], length[on])
        if _thickness(mid[on], length[on], h, n) <= cfg.thickness:
            flat.append((h, n, on))
    planes = []
    used = np.zeros(len(flat), bool)
    for i, (h, n, on) in enumerate(flat):
        if used[i]:
            continue
        group = on.copy()
        for j in range(i + 1, len(flat)):
            if not used[j] and _thickness(mid[flat[j][2]], length[flat[j][2]], h, n) <= cfg.thickness:
                group |= flat[j][2]
                used[j] = True
        h, n = _plane(mid[group], length[group])
        planes.append((h, n if (h - centre) @ n >= 0 else -n))
    return planes[: cfg.max_planes]


def _plane(P: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares plane of points P (k, 3), weights w (k,): centroid (3,), unit normal (3,)."""
    h = (P * w[:, None]).sum(0) / w.sum()
    d = P - h
    return h, np.linalg.eigh((d * w[:, None]).T @ d)[1][:, 0]


def _thickness(P: np.ndarray, w: np.ndarray, h: np.ndarray, n: np.ndarray) -> float:
    """RMS distance of the edge midpoints P (k, 3) (weights w, the edges' lengths) to the plane (h, n), in
    mean edge lengths."""
    return float(np.sqrt(np.average(((P - h) @ n) ** 2, weights=w)) / np.mean(w))


def _candidates(
    c: np.ndarray, planes, width: float, diag: float, cfg: CropConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Candidate centres (K, 3) on every plane's family c + lam (h + t n - c), ``cfg.lattice`` bin widths apart,
    with their lam (K,) and the unit normal of their family's plane (K, 3) (the plane through c spanned
    by h - c and n)."""
    lam = np.linspace(0.0, cfg.lambda_max, 161)[:, None, None]
    t = np.linspace(cfg.t_range[0] * diag, cfg.t_range[1] * diag, 121)[None, :, None]
    C, L, N = [], [], []
    for h, n in planes:
        off = np.cross(h - c, n)
        C.append((c + lam * (h + t * n - c)).reshape(-1, 3))
        L.append(np.broadcast_to(lam, (161, 121, 1)).reshape(-1))
        N.append(np.broadcast_to(off / max(float(np.linalg.norm(off)), 1e-300), (161 * 121, 3)))
    C, L, N = np.concatenate(C), np.concatenate(L), np.concatenate(N)
    off = np.asarray(cfg.layers, float) * width  # the family's plane and its copies off it
    C = (C[None] + off[:, None, None] * N[None]).reshape(-1, 3)
    L, N = np.tile(L, len(off)), np.tile(N, (len(off), 1))
    near = row_norms(C - c) <= cfg.reach * width
    first = np.flatnonzero(near)[_spread(C[near] - c, cfg.lattice * width)]
    return C[first], L[first], N[first]


def _spread(D: np.ndarray, spacing: float) -> np.ndarray:
    """Indices (ascending) of the first of the points D (K, 3) in each cell of a lattice of ``spacing``
    (cells centred on the lattice's points). The cells of spacing 3s are unions of those of s, so the
    points kept at 3s from those kept at s are the ones kept at 3s from all."""
    if len(D) == 0:
        return np.zeros(0, np.int64)
    cell = np.round(D / spacing).astype(np.int64)
    cell -= cell.min(0)
    size = cell.max(0) + 1
    # one integer per cell (a few hundred cells per axis): np.unique of the rows takes 7 times as long
    key = (cell[:, 0] * size[1] + cell[:, 1]) * size[2] + cell[:, 2]
    first = np.unique(key, return_index=True)[1]
    first.sort()
    return first


def _screen(P: np.ndarray, C: np.ndarray, width: float, cfg: CropConfig) -> tuple[np.ndarray, np.ndarray]:
    """The screening's score of candidate centres C (K, 3): how strongly the distances of the vertices
    P (k, 3) add up in phase at a bin width within ``cfg.screen_widths`` times ``width`` (``radial.in_phase``),
    (K,), and that bin width, (K,). P and C relative to a point near them (``radial.distances``),
    float32 is enough."""
    w_min, w_max = width * cfg.screen_widths[0], width * cfg.screen_widths[1]
    score, at = np.empty(len(C)), np.empty(len(C))
    for s0 in range(0, len(C), _BATCH):
        score[s0 : s0 + _BATCH], at[s0 : s0 + _BATCH] = in_phase(
            distances(P, C[s0 : s0 + _BATCH]), w_min / cfg.screen_cells, w_min, w_max, cfg.screen_pad
        )
    return score, at


def _coarse(
    P: np.ndarray,
    area: np.ndarray,
    C: np.ndarray,
    lam: np.ndarray,
    widths: np.ndarray,
    n_bins: int,
    phases: np.ndarray,
    cells: int = SCALE_CELLS,
) -> np.ndarray:
    """The coarse score of candidate centres C (K, 3) with their lam (K,): the most mark energy over
    each one's bin ``widths`` (K, W) x ``phases`` (in bin widths) from lo, on the vertices P (k, 3) of
    areas (k,); P and C relative to a point near them (``radial.distances``), float32 is enough.

    lo is the area quantile that the original's 2 % would be if the cap held none of the area. Each
    centre's distances are counted once in cells of 1/``cells`` of the smallest width of its batch, from
    its nearest vertex out (``radial.cumulative_cells``: count, sum of positions and area); lo is a cell,
    and every frame's bins come from the cells at their edges, rounded to the nearest cell edge
    (``radial.cell_energies``, as in ``radial.scale_energies``)."""
    j = np.arange(n_bins + 1)
    score = np.empty(len(C))
    for s0 in range(0, len(C), _BATCH):
        rho = distances(P, C[s0 : s0 + _BATCH])
        B = len(rho)
        cell = float(widths[s0 : s0 + B].min()) / cells
        wc = widths[s0 : s0 + B, :, None, None] / cell  # (B, W, 1, 1) bin widths in cells
        start = phases[:, None] * wc  # (B, W, P, 1) from lo, in cells
        offs = np.rint(start + j * wc).astype(np.int64)  # (B, W, P, J + 1) the edges from lo
        shift = int(max(0, -offs.min()))  # empty cells below the nearest vertex, for negative phases
        x = (rho - rho.min(1)[:, None]) / cell + shift
        # cells up to the farthest vertex: an edge beyond it reads the last entry, the row's total (the
        # outermost edges reach up to twice as far: those cells would only repeat it)
        n_cells = int(x.max()) + 1
        cum_n, cum_x, cum_a = cumulative_cells(x, n_cells, None, area)
        # the cell of the area quantile the original's 2 % would be if the cap held none of the area
        lo = (cum_a[:, 1:] < (QUANTILES[0] / (1.0 - lam[s0 : s0 + B]) * cum_a[:, -1])[:, None]).sum(1)
        lo = lo[:, None, None, None]
        mids = lo + start + (j[:-1] + 0.5) * wc  # (B, W, P, J) the bins' centres
        en = cell_energies(cum_n, cum_x, np.minimum(lo + offs, n_cells), mids, wc[..., 0])
        score[s0 : s0 + B] = en.reshape(B, -1).max(1)
    return score


def crop_frames(
    V: np.ndarray,
    a: np.ndarray,
    area: np.ndarray,
    own: Frame,
    planes: list,
    bin_counts,
    cfg: CropConfig = READER.crop,
    progress: Progress = None,
) -> list[Frame]:
    """For each count in ``bin_counts``, the frame of that many bins where a cropped copy shows the most
    mark energy (``excess_energy``) near the families of the cut ``planes`` (``cut_planes``, not empty).
    V (n, 3); a (n,) the reader's vertex weights; area (n,) ``vertex_areas``; ``own`` the suspect's own
    frame (its centre and range); ``cfg`` the search's settings (``config.CropConfig``, named below without
    the prefix).

    Stages, per count: the candidate centres (``_candidates``) screened by how their radii add up in phase
    (screen_*), the kept ones scored by the mark's energy over widths and phases (coarse_*), the ``top`` best
    moved off their family's plane (off_plane) and fitted finely (``_fit_scale``), the ``refined`` best of those
    refined (``radial.refine_frame_on``) and the ``final`` best fitted again at their refined centre; the frame
    of most energy wins. The counts are searched in parallel threads (``background.parallel_map``).

    The vertices farther from the centroid than own.hi + 2 reach bin widths (of the fewest bins) + beyond
    ranges (hi - lo) are left out. No frame the search tries reaches them: its centre lies within reach
    bin widths of the centroid; its lo below the distance of the innermost 2 / (1 - lambda_max) of the
    area, so below own.hi + reach bin widths; its bins span at most screen_widths[1] = 1.6 ranges, and
    the phases and the refinement move them by a few bins. But its histograms would reach them: a stray
    part far from the model would make every candidate's counts and FFT as long as its distance. A model
    has none there.

    ``progress(fraction, message)`` is called after each of the 5 stages of each count, from the search
    threads, one call at a time, the fractions growing."""
    report, lock, done = progress or no_progress, threading.Lock(), [0]

    def stage() -> None:
        with lock:
            done[0] += 1
            report(done[0] / (5 * len(bin_counts)), "looking for a cropped copy's frame")

    dist = row_norms(V - own.centre)
    within = dist <= own.hi + (2.0 * cfg.reach / min(bin_counts) + cfg.beyond) * (own.hi - own.lo)
    by_rho = by_distance(V, a, own.centre)
    by_rho = by_rho[within[by_rho]]
    sub, fine = thinned(by_rho, cfg.coarse_sample), thinned(by_rho, REFINE_SAMPLE)
    # the coarse stages in float32: distances of a few hundred bin widths, accurate to 1e-5 bins
    Pc, area_c = (V[sub] - own.centre).astype(np.float32), area[sub]
    Pf, af = V[fine], a[fine]
    sub_first = thinned(by_rho, cfg.refine_first)
    first_sample = V[sub_first], a[sub_first]
    Pw, aw, area_w = V[by_rho], a[by_rho], area[by_rho]  # the fine width fit: every vertex of positive weight
    diag = bbox_diagonal(V[within])
    total = float(a.sum())
    around, phases = np.asarray(cfg.coarse_around), np.asarray(cfg.coarse_phases)
    off_plane = np.asarray(cfg.off_plane)

    def frame_for(n_bins: int) -> Frame:
        width = (own.hi - own.lo) / n_bins
        C, L, N = _candidates(own.centre, planes, width, diag, cfg)
        Cc = (C - own.centre).astype(np.float32)
        # screening: the candidates screen_lattice apart, then those a lattice apart near the best of them
        s = _spread(C - own.centre, cfg.screen_lattice * width)
        first = _screen(Pc, Cc[s], width, cfg)[0]
        stage()
        top = C[s[np.argsort(-first, kind="stable")[: max(cfg.screen_min, int(cfg.screen_top * len(s)))]]]
        near = unique_values(pairs_within(top, C, cfg.expand * width)[1])
        second, at = _screen(Pc, Cc[near], width, cfg)
        stage()
        keep = max(cfg.screen_min, int(cfg.screen_keep * len(C) / len(cfg.layers)))  # (a share of one layer's)
        best = np.argsort(-second, kind="stable")[:keep]
        kept = near[best]
        score, w_phase = np.full(len(C), -np.inf), np.zeros(len(C))
        w_phase[kept] = at[best]  # each one's in-phase width, around which the coarse stage tries widths
        score[kept] = _coarse(Pc, area_c, Cc[kept], L[kept], np.outer(at[best], around), n_bins, phases)
        stage()

        def refined(fr: Frame, sample: tuple[np.ndarray, np.ndarray]) -> tuple[float, Frame]:
            fr = refine_frame_on(*sample, fr, n_bins)
            return excess_energy(*statistics_in(V, a, fr, [n_bins])[0], total), fr

        scaled = []
        for i in np.argsort(-score, kind="stable")[: cfg.top]:
            # off the family's plane (the cap's centroid off the hole's axis), then the scale
            off = C[i] - own.centre + np.outer(off_plane * width, N[i])
            e = _coarse(
                Pc,
                area_c,
                off.astype(np.float32),
                np.full(len(off), L[i]),
                np.tile(w_phase[i] * around, (len(off), 1)),
                n_bins,
                phases,
            )
            best_off = off[int(np.argmax(e))]
            scaled.append((*_fit_scale(Pw, aw, area_w, own.centre + best_off, L[i], width, n_bins, cfg), L[i]))
        scaled.sort(key=lambda f: -f[0])
        stage()
        fits = sorted(((*refined(fr, first_sample), lam) for _, fr, lam in scaled[: cfg.refined]), key=lambda f: -f[0])
        # the ``final`` best, and each fitted again at its refined centre: the one of most energy
        finals = [
            f
            for z, fr, lam in fits[: cfg.final]
            for f in ((z, fr), refined(_fit_scale(Pw, aw, area_w, fr.centre, lam, width, n_bins, cfg)[1], (Pf, af)))
        ]
        stage()
        return max(finals, key=lambda f: f[0])[1]

    # the word lengths are searched independently, each in its own thread
    return parallel_map(frame_for, list(bin_counts))


def _fit_scale(
    P: np.ndarray,
    a: np.ndarray,
    area: np.ndarray,
    centre: np.ndarray,
    lam: float,
    width: float,
    n_bins: int,
    cfg: CropConfig,
) -> tuple[float, Frame]:
    """The frame around ``centre`` whose lo (near the area quantile the crop left of the original's,
    ``lam`` its share taken) and bin width (within ``cfg.fine_half`` steps of ``cfg.fine_step`` of the width
    where the radii add up in phase, within ``cfg.screen_widths`` times ``width``) show the most mark energy on the
    vertices P (k, 3) with reader weights a (k,) and areas (k,); and that energy."""
    rho = row_norms(P - centre)[None]
    lo = np.array([low_quantile(rho[0], area, QUANTILES[0] / (1.0 - lam))])
    # the widths near the one where the radii add up in phase, at a few phases; then the widths of
    # most energy at every phase
    w_min, w_max = width * cfg.screen_widths[0], width * cfg.screen_widths[1]
    w_phase = float(in_phase(rho, w_min / cfg.fine_cells, w_min, w_max, cfg.fine_pad)[1][0])
    widths = w_phase * (1.0 + cfg.fine_step * np.arange(-cfg.fine_half, cfg.fine_half + 1))
    phases = np.asarray(cfg.fine_phases)
    e = scale_energies(rho, a, lo, widths, phases[::4], n_bins)[0].max(1)
    rel = widths[np.sort(np.argsort(-e, kind="stable")[: cfg.fine_keep])]
    e = scale_energies(rho, a, lo, rel, phases, n_bins)[0]
    wi, pi = np.unravel_index(int(np.argmax(e)), e.shape)
    w = float(rel[wi])
    start = float(lo[0] + phases[pi] * w)
    return float(e.max()), Frame(centre, start, start + n_bins * w, n_bins)
