"""The carrier of the blind scheme: the distribution of the vertices' distances to their centroid.

Everything here is computed from the mesh alone, so the reader needs no original:

- centre c: the area-weighted vertex centroid (each vertex weighs a third of its faces' area), an
  estimate of the surface centroid that vertex density does not move (simplification, subdivision);
- rho_i = |v_i - c| and the range [lo, hi]: the area-weighted quantiles ``QUANTILES`` of rho (Cho et
  al. use the extreme vertices, which any noise moves; a quantile barely moves);
- M equal-width bins over [lo, hi] (vertices outside carry nothing); inside bin j the normalised
  radius r in [0, 1] and the bin's statistic, the mean of r over its vertices (unit weights).

Embedding (Cho et al.'s method I, with another push): within every bin r -> r + beta sin^2(pi r) moves
the mean above 1/2 + alpha_j (bit 1, beta > 0) or below 1/2 - alpha_j (bit 0, beta < 0); a vertex moves
to its new radius partly along the surface (``moved_to_radius``: its radial direction with the part across
the surface scaled by NORMAL_SHARE), which the distortion measures see less of than a move along the radius.
The margin alpha_j is alpha * sqrt(median count / count of bin j) (clipped,
``bin_margins``): the same signal-to-noise ratio in every bin at the distortion of one margin for
all. The push is monotone for |beta| < 1/pi and leaves r = 0 and r = 1 in place with slope 1 there,
so no vertex changes bin and the density at the bin edges, where noise and remeshing move vertices
across, is left as it was (Cho's r -> r**k empties one edge and crowds the other). It moves a bin
mean by at most about 0.155; a bin asked for more gets Cho's r**k. Reading: the sign of (bin mean -
1/2). The embedder re-reads its own output (float32, frame recomputed from the marked mesh) and
raises the margin of any bin that came out wrong or weak (below alpha_j / 2), keeping the round with
the fewest wrong, then weak, bins.

Why this push: at the same MRMS it reads more whole payloads than r**k after simplification, smoothing,
quantization and subdivision, and as many after the other attacks.

Reading: the statistics (after ``equalized``: an attack that blurs the radii by a good part of a bin
makes each bin's neighbours interfere, and their interference is removed, key-free) in the suspect's
own frame and in the frame near it (1.5 bin widths at most)
where the mark's energy is largest (``refine_frame``, a compass search; the energy involves no pass
phrase, so the choice costs the p-value nothing but the second frame's readings, which the union bound
counts). Which frames the reader reads in, a cropped copy's included: ``frames``.

Why these weights (area-weighted centre and range, unit-weight statistics): a vertex mean moves when
simplification removes vertices unevenly, and area weights in the statistics follow the mark and the noise.
The measurements behind these choices: docs/decisions/082-blind-carrier-and-word.md; the algorithm:
docs/schemes/blind.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ...adjacency import stable_argsort
from ...errors import MeshError
from ...features import row_norms, vertex_areas, vertex_normals

QUANTILES = (0.02, 0.98)  # the range of rho the bins cover, as area-weighted quantiles
K_GRID = 1e-3  # the step of the exponent k (Cho's)
K_NEWTON = 4  # Newton steps towards a bin's exponent, the search's guess
BETA_GRID = 1e-4  # the step of the push beta
BETA_MAX = 0.999 / np.pi  # |beta| below 1/pi: the push stays monotone
MARGIN_SPREAD = (0.5, 3.0)  # a bin's margin is alpha * sqrt(median count / its count), clipped to this
NORMAL_SHARE = 0.4  # a vertex moves to its new radius along its radius, the part across the surface scaled by this


@dataclass
class Frame:
    """The shape's own radial frame: centre (3,) float64, range [lo, hi] of rho, bins."""

    centre: np.ndarray
    lo: float
    hi: float
    n_bins: int

    @property
    def width(self) -> float:
        return (self.hi - self.lo) / self.n_bins


def weighted_quantiles(x: np.ndarray, w: np.ndarray, q) -> np.ndarray:
    """Per row of x (B, n), the w-weighted quantiles q (B, Q) (w (n,) >= 0): the smallest value whose
    cumulative weight, in increasing order, reaches q of the total; (B, Q)."""
    q = np.asarray(q, dtype=np.float64).reshape(len(x), -1)
    order = np.argsort(x, axis=1, kind="stable")
    cw = np.cumsum(w[order], axis=1)
    idx = np.minimum((cw[:, :, None] < q[:, None, :] * w.sum()).sum(1), x.shape[1] - 1)
    return np.take_along_axis(np.take_along_axis(x, order, 1), idx, 1)


def low_quantile(x: np.ndarray, w: np.ndarray, q: float) -> float:
    """``weighted_quantiles`` of one row x (n,) at one small q, sorting only the smallest values that can
    hold it (the same value: the same weights summed in the same order)."""
    target = q * w.sum()
    m = min(len(x), 2 * int(q * len(x)) + 256)
    if m < len(x):
        part = np.argpartition(x, m - 1)[:m]
        part.sort()  # (by index: the stable sort below then orders ties as argsort of all of x does)
        order = part[np.argsort(x[part], kind="stable")]
        cw = np.cumsum(w[order])
        if cw[-1] >= target:  # (ties beyond the m-th value would be read as that same value)
            return float(x[order[int((cw < target).sum())]])
    return float(weighted_quantiles(x[None], w, [q])[0, 0])


def high_quantile(x: np.ndarray, w: np.ndarray, q: float) -> float:
    """``weighted_quantiles`` of one row x (n,) at one large q, sorting only the largest values that can
    hold it (``low_quantile`` from the other end): the same value, the weight below them summed at once
    instead of along the sorted order (the two sums differ by rounding, about 1e-16 of the total, far
    below one vertex's weight)."""
    total = w.sum()
    target = q * total
    n = len(x)
    m = min(n, 2 * int((1.0 - q) * n) + 256)
    if m < n and q < 1.0:  # (at q = 1 the full sort's rounding decides: its own answer is kept)
        part = np.argpartition(x, n - m)[n - m :]
        part.sort()  # (by index: the stable sort below then orders ties as argsort of all of x does)
        order = part[np.argsort(x[part], kind="stable")]
        tail = np.take(w, order)
        below = total - tail.sum()  # the weight of the values not sorted
        cw = below + np.cumsum(tail)
        if below < target <= cw[-1]:  # (else the quantile lies below the values sorted)
            return float(x[order[int((cw < target).sum())]])
    return float(weighted_quantiles(x[None], w, [q])[0, 0])


def frame_of(V: np.ndarray, F: np.ndarray, n_bins: int) -> tuple[Frame, np.ndarray]:
    """The frame of a mesh (area-weighted centre and range) and the vertices' weights in the bin
    statistics (n,) (1 on a face of positive area, else 0). MeshError when the surface has no area
    or no radial range."""
    return frame_of_areas(V, vertex_areas(V, F), n_bins)


def frame_of_areas(V: np.ndarray, area: np.ndarray, n_bins: int) -> tuple[Frame, np.ndarray]:
    """``frame_of`` from the vertices' areas (n,) (``vertex_areas``), for a caller that needs them too."""
    total = area.sum()
    if not total > 0:
        raise MeshError("the mesh has no surface area; the blind scheme reads a surface")
    c = (area[:, None] * V).sum(0) / total  # the surface's centroid: vertex density does not move it
    rho = row_norms(V - c)
    lo, hi = low_quantile(rho, area, QUANTILES[0]), high_quantile(rho, area, QUANTILES[1])
    a = (area > 0).astype(np.float64)  # in the statistics every vertex of the surface weighs 1
    if not hi > lo * (1 + 1e-9) or not hi > 0:
        raise MeshError("the surface has no range of distances from its centre; the blind scheme needs one")
    return Frame(c, float(lo), float(hi), n_bins), a


@dataclass
class Binned:
    """Vertices in a frame: rho (n,), unit radial direction (n, 3), bin (n,) (-1 outside the
    range), r (n,) in [0, 1] inside the bin."""

    rho: np.ndarray
    unit: np.ndarray
    bin: np.ndarray
    r: np.ndarray


def bin_vertices(V: np.ndarray, fr: Frame) -> Binned:
    d = V - fr.centre
    rho = row_norms(d)
    unit = np.divide(d, rho[:, None], out=np.zeros_like(d), where=rho[:, None] > 0)
    b, r = _bins((rho - fr.lo) / fr.width, fr.n_bins)
    return Binned(rho, unit, b, r)


def _bins(t: np.ndarray, n_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions t (n,) in bin widths from lo -> bin (n,) int64 (-1 outside the n_bins) and r (n,),
    the place inside the bin in [0, 1) (0 outside)."""
    floor = np.floor(t)
    b = floor.astype(np.int64)
    inside = (b >= 0) & (b < n_bins)
    return np.where(inside, b, -1), np.where(inside, t - floor, 0.0)


def bin_statistics(r: np.ndarray, b: np.ndarray, a: np.ndarray, n_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Per bin: the weighted mean of r (NaN when empty) and the bin's total weight, both (M,)."""
    means = BinMeans(b, a, n_bins)
    return means(r), means.weight


class BinMeans:
    """The weighted means per bin of values over fixed bins b (n,) int64 (-1 outside the n_bins) with
    weights a (n,): ``bin_statistics``'s means, for a search that reads the same bins many times (the bins'
    indices and total weights, ``weight`` (M,), made once)."""

    def __init__(self, b: np.ndarray, a: np.ndarray, n_bins: int):
        # the vertices outside (b = -1) go to one extra bin, dropped: cheaper than compressing the arrays,
        # and each bin sums the same values in the same order
        self.index = np.where(b >= 0, b, n_bins)
        self.a, self.n_bins = a, n_bins
        self.weight = np.bincount(self.index, weights=a, minlength=n_bins + 1)[:n_bins]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The mean of x (n,) in each bin (M,), NaN in an empty one (the values outside play no part)."""
        s = np.bincount(self.index, weights=self.a * x, minlength=self.n_bins + 1)[: self.n_bins]
        return np.divide(s, self.weight, out=np.full(self.n_bins, np.nan), where=self.weight > 0)


def _least_step(reached, j_max: np.ndarray, guess: Optional[np.ndarray] = None) -> np.ndarray:
    """Per bin, the smallest step j in 0 .. j_max (M,) int64 for which ``reached(j)`` ((M,) -> (M,)
    bool, monotone in j) holds; j_max where none does. Bisection, all bins at once; a ``guess`` (M,)
    int64 of the answer is tried first, then the steps 1, 2, 4, ... from it (down where the guess
    reaches, up where it does not) until they bracket the answer, and the bisection searches the bracket:
    a right guess settles its bin in two readings, one d off in about 2 log2(d), instead of about
    log2(j_max)."""
    lo = np.zeros_like(j_max)
    hi = j_max.copy()
    if guess is not None:
        g = np.clip(guess, 0, j_max)
        down = reached(g)  # the answer is at most g where g reaches, above it where it does not
        hi = np.where(down, g, hi)
        lo = np.where(down, lo, np.minimum(g + 1, hi))
        step = np.ones_like(g)
        galloping = lo < hi
        while galloping.any():  # the answer in [lo, hi]: steps away from g close the bracket
            probe = np.clip(np.where(down, g - step, g + step), lo, hi)
            sat = reached(np.where(galloping, probe, lo))  # (a bin not galloping: its reading is not used)
            hi = np.where(galloping & sat, probe, hi)
            lo = np.where(galloping & ~sat, np.minimum(probe + 1, hi), lo)
            galloping &= (sat == down) & (lo < hi)  # down while it reaches, up while it does not
            step *= 2
    while np.any(lo < hi):
        mid = (lo + hi) // 2
        sat = reached(mid)
        hi = np.where(sat & (lo < hi), mid, hi)
        lo = np.where(~sat & (lo < hi), mid + 1, lo)
    return lo


def _meets(means: BinMeans, r_new, one, targets) -> np.ndarray:
    """Per bin (M,) bool: its mean of the moved radii r_new (n,) (``means``) is past its target (above for
    the bins ``one``, below for the others), or the bin is empty."""
    mean = means(r_new)
    return np.where(one, mean > targets, mean < targets) | np.isnan(mean)


def _solve_k(r, b, a, n_bins, one, targets) -> np.ndarray:
    """Per bin, the exponent on the grid 1 -+ j*K_GRID nearest 1 meeting its target. The search starts
    from the exponent Newton's method gives for the bin mean of r**k (K_NEWTON steps from k = 1)."""
    j_max = np.where(one, int(np.floor((1.0 - K_GRID) / K_GRID)), int(round(50.0 / K_GRID))).astype(np.int64)
    bb = np.where(b >= 0, b, 0)
    means = BinMeans(b, a, n_bins)

    def k_of(j):
        return np.where(one, 1.0 - j * K_GRID, 1.0 + j * K_GRID)

    # the log of the bin mean of r**k falls with k, convex and nearly straight: Newton's steps on it
    log_r = np.log(np.where(r > 0, r, 1.0))  # (r = 0 adds nothing to the slope: taken as 1)
    k = np.ones(n_bins)
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(K_NEWTON):
            rk = r ** k[bb]
            mean, slope = means(rk), means(rk * log_r)
            k = np.clip(k - (np.log(mean) - np.log(targets)) * mean / slope, K_GRID, 51.0)  # (the grid's ends)
            k = np.where(np.isfinite(k), k, 1.0)
        steps = np.ceil(np.where(one, 1.0 - k, k - 1.0) / K_GRID)
    guess = np.where(np.isfinite(steps), np.clip(steps, 0, j_max), 0).astype(np.int64)
    guess = np.where(np.where(one, targets >= 1.0, targets <= 0.0), j_max, guess)  # (out of any exponent's reach)
    return k_of(_least_step(lambda j: _meets(means, r ** k_of(j)[bb], one, targets), j_max, guess))


def _push(r: np.ndarray, beta: np.ndarray, lift: Optional[np.ndarray] = None) -> np.ndarray:
    """The edge-preserving push r + beta sin^2(pi r) of normalised radii r (n,) by beta (n,); ``lift``, the
    sin^2(pi r) of r when the caller pushes the same radii many times."""
    return r + beta * (np.sin(np.pi * r) ** 2 if lift is None else lift)


def _solve_beta(r, b, a, n_bins, one, targets) -> tuple[np.ndarray, np.ndarray]:
    """Per bin, the push on the grid +- j * BETA_GRID nearest 0 meeting its target, and whether it
    does (M,) bool: at BETA_MAX a bin mean moves by about 0.155 at most."""
    bb = np.where(b >= 0, b, 0)
    sign = np.where(one, 1.0, -1.0)
    means = BinMeans(b, a, n_bins)
    lift = np.sin(np.pi * r) ** 2  # (``_push``'s, made once)

    def reached(j: np.ndarray) -> np.ndarray:
        return _meets(means, _push(r, (sign * j * BETA_GRID)[bb], lift), one, targets)

    # a bin's mean of the pushed radii is linear in beta: its mean of r plus beta times its mean of
    # sin^2(pi r); the step that line gives is the guess, read as the bisection reads it
    mean_r, mean_s = means(r), means(lift)
    with np.errstate(divide="ignore", invalid="ignore"):
        steps = np.ceil(sign * (targets - mean_r) / (mean_s * BETA_GRID))
    j_max = np.full(n_bins, int(np.floor(BETA_MAX / BETA_GRID)), np.int64)
    guess = np.where(np.isfinite(steps), np.clip(steps, 0, j_max), 0).astype(np.int64)
    j = _least_step(reached, j_max, guess)
    return sign * j * BETA_GRID, reached(j)


def bin_margins(counts: np.ndarray) -> np.ndarray:
    """Each bin's margin in units of alpha (M,): sqrt(median count / its count), clipped to
    ``MARGIN_SPREAD``, from the bins' vertex counts (M,). A bin mean read through an attack errs by
    about sigma / sqrt(n_j), so this gives every bin the same signal-to-noise ratio, at the same
    distortion as equal margins (the squared displacement grows as n_j margin_j^2, summed: the same
    total); fewer bin errors than equal margins or other exponents (docs/decisions/082-blind-carrier-and-word.md)."""
    c = np.asarray(counts, dtype=np.float64)
    filled = c[c > 0]
    med = float(np.median(filled)) if len(filled) else 1.0
    return np.clip(np.sqrt(med / np.maximum(c, 1e-300)), *MARGIN_SPREAD)


def moved_to_radius(
    V: np.ndarray, centre: np.ndarray, bv: Binned, rho_new: np.ndarray, normals: np.ndarray, share: float = NORMAL_SHARE
) -> np.ndarray:
    """The vertices V (n, 3) moved to the distances rho_new (n,) from ``centre`` (``bv``: their distances and
    directions in that frame), each along e = u - (1 - share)(u . n) n, normalised: its radial direction u with
    the part across the surface (n its unit normal, ``normals`` (n, 3), zero where it has none) scaled by
    ``share``; (n, 3) float64. ``share`` 1 moves along the radius (Cho's); a vertex at the centre, or one that
    cannot reach its radius that way, moves along its radius.

    Why: the distortion a mark is judged by (MRMS, the distance between the two surfaces) sees a vertex's move
    across the surface and, to first order, not its move along it; the reader sees its change of radius. Where
    the surface is oblique to the radius, moving partly along it reaches the same radius with less distortion,
    so at the same MRMS the margins grow. The price: a vertex slides farther along the surface, and what
    resamples the surface (simplification, Laplacian smoothing) keeps less of that part; at ``share`` 0.4 the
    simplified copies that smaller shares lose still read (docs/decisions/082-blind-carrier-and-word.md)."""
    u = bv.unit
    c = np.einsum("ij,ij->i", u, normals)
    e = u - (1.0 - share) * c[:, None] * normals
    size = row_norms(e)  # at least share for a unit u and a unit (or zero) normal; 0 for u = 0
    e = np.divide(e, size[:, None], out=np.zeros_like(e), where=size[:, None] > 0)
    p = V - centre
    pe = np.einsum("ij,ij->i", p, e)
    # |p + s e| = rho_new: the root s of s^2 + 2 s (p.e) + |p|^2 - rho_new^2 nearest 0, in its stable form
    gap = rho_new * rho_new - bv.rho * bv.rho
    disc = pe * pe + gap
    ok = (pe > 0) & (disc > 0)
    s = np.divide(gap, pe + np.sqrt(np.maximum(disc, 0.0)), out=np.zeros_like(pe), where=ok)
    out = V + s[:, None] * e
    far = ~ok
    if far.any():
        out[far] = centre + u[far] * rho_new[far, None]
    return out


@dataclass
class Host:
    """What ``embed_signs`` needs of the unmarked mesh, computed once for the calibration's several markings
    of it: its frame for n_bins bins, the reader's vertex weights (n,), its vertices binned in that frame and
    their unit normals (n, 3)."""

    frame: Frame
    weights: np.ndarray
    binned: Binned
    normals: np.ndarray

    @staticmethod
    def of(V: np.ndarray, F: np.ndarray, n_bins: int) -> "Host":
        fr, a = frame_of(V, F, n_bins)
        return Host(fr, a, bin_vertices(V, fr), vertex_normals(V, F))


def embed_signs(
    V: np.ndarray,
    F: np.ndarray,
    signs: np.ndarray,
    alpha: float,
    rounds: int = 8,
    share: float = NORMAL_SHARE,
    host: Optional[Host] = None,
) -> np.ndarray:
    """Marked vertices (n, 3) float64 (float32-exact) whose bins read ``signs`` (M,) (+1 / -1; 0 =
    leave the bin alone) with margin ``alpha`` on the bin mean of r in a bin of the median count of
    vertices (``bin_margins``). An empty bin carries nothing (the reader sees an erasure). ``host``:
    ``Host.of(V, F, len(signs))``, when the caller marks the same mesh more than once."""
    n_bins = len(signs)
    host = Host.of(V, F, n_bins) if host is None else host
    fr, a, bv, normals = host.frame, host.weights, host.binned, host.normals
    one = signs > 0
    base = float(alpha) * bin_margins(bin_statistics(bv.r, bv.bin, a, n_bins)[1])
    margin = base.copy()
    marked = V
    best = None  # ((wrong bins, weak bins), marked): on small meshes the rounds can oscillate
    for _ in range(rounds):
        targets = np.where(one, 0.5 + margin, 0.5 - margin)
        beta, pushed = _solve_beta(bv.r, bv.bin, a, n_bins, one, targets)
        use_k = ~pushed & (signs != 0)  # beyond the push's reach: Cho's r**k alone
        beta = np.where(pushed & (signs != 0), beta, 0.0)
        inside = bv.bin >= 0
        bi = np.where(inside, bv.bin, 0)
        r_new = np.where(inside, _push(bv.r, beta[bi]), bv.r)
        if use_k.any():  # (on the vertices of those bins only: a bin's mean is its own vertices')
            sub = np.flatnonzero(use_k[bi] & inside)
            k = _solve_k(bv.r[sub], bv.bin[sub], a[sub], n_bins, one, targets)
            r_new[sub] = bv.r[sub] ** k[bv.bin[sub]]  # (their push is 0)
        rho_new = fr.lo + fr.width * (bi + r_new)
        moved = inside & (r_new != bv.r)
        marked = np.where(moved[:, None], moved_to_radius(V, fr.centre, bv, rho_new, normals, share), V)
        marked = marked.astype(np.float32).astype(np.float64)
        seen, seen_a = frame_of(marked, F, n_bins)  # the frame the reader will see, and what it reads
        stat, _ = statistics_in(marked, seen_a, seen, [n_bins])[0]
        wrong = (signs != 0) & ~(np.sign(np.nan_to_num(stat)) == signs)
        weak = (signs != 0) & (np.abs(np.nan_to_num(stat)) < 0.5 * base)
        score = (int(wrong.sum()), int(weak.sum()))
        if best is None or score < best[0]:
            best = (score, marked)
        if not (wrong | weak).any():
            break
        margin = np.where(wrong | weak, margin + 0.5 * base, margin)
        fr = seen
        bv = bin_vertices(V, fr)
    return best[1] if best is not None else marked


# --------------------------------------------------------------------------- frame refinement (reader)

REFINE_SAMPLE = 20000  # vertices the frame search looks at (every k-th by rho: independent of the order)
REFINE_STEPS = (0.5, 0.25, 0.125, 0.0625)  # compass-search steps, in bin widths
REFINE_BOUND = 1.5  # the search stays within this many bin widths of the suspect's own frame
REFINE_MOVES = 12  # moves per step size at most


def energies(
    V: np.ndarray, a: np.ndarray, centres: np.ndarray, lo: np.ndarray, hi: np.ndarray, n_bins: int
) -> np.ndarray:
    """The mark's energy in K candidate frames, (K,) float64: sum over bins of n_j (mean_j - 1/2)^2,
    i.e. S_j^2 / n_j with S_j the bin's sum of (r - 1/2). V (n, 3), a (n,) weights, centres (K, 3),
    lo, hi (K,). Under no mark it is about n_bins / 12 whatever the frame; the pass phrase plays no part."""
    K = len(centres)
    t = distances(V, centres)  # (in place from here: each (K, n) array a pass fewer)
    t -= lo[:, None]
    t *= (n_bins / (hi - lo))[:, None]
    b = np.floor(t)
    ok = (b >= 0) & (b < n_bins)
    # out-of-range vertices go to one extra cell, dropped: cheaper than compressing (K, n) arrays
    idx = b.astype(np.int64)
    idx += n_bins * np.arange(K)[:, None]
    idx[~ok] = K * n_bins
    idx = idx.ravel()
    t -= b
    t -= 0.5
    t *= a
    n = np.bincount(idx, weights=np.broadcast_to(a, t.shape).ravel(), minlength=K * n_bins + 1)[:-1]
    s = np.bincount(idx, weights=t.ravel(), minlength=K * n_bins + 1)[:-1]
    e = np.divide(s * s, n, out=np.zeros(K * n_bins), where=n > 0)
    return e.reshape(K, n_bins).sum(1)


def distances(P: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The distances of points P (n, 3) to centres C (K, 3), (K, n), in their dtype (float32 is enough
    for the searches when P and C are relative to a point near the centres: distances of a few hundred
    bin widths to 1e-5 bins). The coordinates' differences, broadcast: no matrix product, whose BLAS
    threads, for products this thin, fight the reader's own threads (the word lengths' crop searches,
    ``background.parallel_map``) and made two searches side by side slower than one after the other."""
    PT = P.T
    d = np.subtract(C[:, 0:1], PT[0])
    r = d * d
    for k in (1, 2):
        np.subtract(C[:, k : k + 1], PT[k], out=d)
        d *= d
        r += d
    return np.sqrt(r, out=r)


SCALE_CELLS = 16  # scale_energies: cells per bin width of the cumulative histograms


def _cell_ids(x: np.ndarray, n_cells: int) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """For B rows of positions x (B, n) in cells: the flat cell id (row * n_cells + cell) of each point in
    [0, n_cells), raveled, and the mask (B, n) of those points (None when every point is in: two
    reductions tell, cheaper than the mask, which only a frame reaching past the points needs)."""
    flat = x.astype(np.int64)  # (the floor, for x >= 0)
    flat += n_cells * np.arange(len(x))[:, None]
    if x.min() >= 0 and x.max() < n_cells:
        return flat.ravel(), None
    ok = (x >= 0) & (x < n_cells)
    return flat[ok], ok


def cumulative_cells(x: np.ndarray, n_cells: int, weights: Optional[np.ndarray], *more: np.ndarray) -> list[np.ndarray]:
    """Cumulative per-cell sums of B rows of points, for many frames' bins at once (``cell_energies``).

    x (B, n) float: each point's position from its row's origin, in cells (points outside [0, n_cells)
    are left out); weights (n,) or (B, n): each point's weight (None: counts); more: further (n,) or
    (B, n) weights, summed alone. Returns [cum_w, cum_wx, *cum_more], each (B, n_cells + 1) float64:
    entry k is the sum over the row's points in cells below k of w, of w x (the positions, in cells),
    and of each further weight."""
    B = len(x)
    flat, ok = _cell_ids(x, n_cells)

    def cum(w: Optional[np.ndarray]) -> np.ndarray:
        if w is not None:
            w = np.broadcast_to(w, x.shape)
            w = w.ravel() if ok is None else w[ok]
        out = np.zeros((B, n_cells + 1))
        out[:, 1:] = np.bincount(flat, weights=w, minlength=B * n_cells).reshape(B, n_cells)
        return np.cumsum(out, axis=1, out=out)

    return [cum(weights), cum(x if weights is None else weights * x), *(cum(m) for m in more)]


def cell_energies(
    cum_w: np.ndarray, cum_wx: np.ndarray, edges: np.ndarray, mids: np.ndarray, widths: np.ndarray
) -> np.ndarray:
    """The mark's energy (as ``energies``) of many frames from ``cumulative_cells``' tables, (B, ...).

    cum_w, cum_wx (B, N + 1): the cumulative weights and weighted positions (in cells) of B rows;
    edges (B, ..., J + 1) int64: each frame's bin edges, as cell indices in 0..N (a bin takes the whole
    cells between its edges); mids (..., J), broadcast against edges' frames: the bins' centres in cells
    (exact, not rounded); widths (...): the frames' bin widths in cells. A bin's sum of (t - j - 1/2)
    is its sum of (x - mid) over its width."""
    rows = (cum_w.shape[1] * np.arange(len(cum_w))).reshape((-1,) + (1,) * (edges.ndim - 1))
    e = edges + rows
    n = np.diff(np.take(cum_w, e), axis=-1)
    s = np.diff(np.take(cum_wx, e), axis=-1)
    s -= n * mids
    s *= s
    s /= np.maximum(n, np.finfo(np.float64).tiny)  # (an empty bin has s == 0)
    return s.sum(-1) / (widths * widths)


def scale_energies(
    rho: np.ndarray, a: np.ndarray, lo: np.ndarray, widths: np.ndarray, phases: np.ndarray, n_bins: int
) -> np.ndarray:
    """The mark's energy (as ``energies``) of many frames around B centres at once, (B, W, P) float64:
    around centre b, n_bins bins of width ``widths[w]`` from ``lo[b] + phases[p] * widths[w]``.

    rho (B, n) float64: the distances of the same n vertices to each centre; a (n,) their weights; lo (B,);
    widths (W,) > 0; phases (P,) in bin widths. Instead of binning the vertices once per frame (W * P
    passes over them), each centre's distances are counted once in cells of 1/SCALE_CELLS of the smallest
    width (``cumulative_cells``), and every bin's weight and sum of (t - j - 1/2) come from the cells at
    its edges, rounded to the nearest cell edge (1/32 of a bin at most: ``cell_energies``)."""
    cell = float(widths.min()) / SCALE_CELLS
    origin = lo + float(min(phases.min(), 0.0)) * float(widths.max()) - cell
    end = lo + (float(phases.max()) + n_bins) * float(widths.max())
    n_cells = int(np.ceil(float(np.max(end - origin)) / cell)) + 2
    cum_w, cum_wx = cumulative_cells((rho - origin[:, None]) / cell, n_cells, a)
    wc = widths / cell  # (W,)
    start = (lo - origin)[:, None, None, None] / cell + phases[None, None, :, None] * wc[None, :, None, None]
    edges = np.clip(np.rint(start + np.arange(n_bins + 1) * wc[None, :, None, None]), 0, n_cells).astype(np.int64)
    mids = start + (np.arange(n_bins) + 0.5) * wc[None, :, None, None]  # (B, W, P, J)
    return cell_energies(cum_w, cum_wx, edges, mids, wc[None, :, None])


def in_phase(rho: np.ndarray, cell: float, w_min: float, w_max: float, pad: int) -> tuple[np.ndarray, np.ndarray]:
    """How strongly each row's distances add up in phase at one bin width in [w_min, w_max], and that
    width: rho (B, n) the distances of n vertices to B centres (every vertex counts 1). Returns the
    power max_w |sum_i exp(2 pi i rho_i / w)|^2 (B,) and the w of the maximum (B,).

    Why: the push r -> r + beta sin^2(pi r), of either sign, raises a bin's mean of cos(2 pi r) (by
    about pi^2 beta^2 / 2, the same for bits 0 and 1), so that a marked mesh's radii add up in phase
    at its centre and bin width whatever the word, where the bin energy (``scale_energies``) needs every
    width and lo apart. Measured in the marked meshes' own frames: |sum| / n 0.13 (bunny), 0.24 (Venus
    head), 0.20 (Igea) against 0.004-0.006 unmarked, the noise 1 / sqrt(n) 0.003-0.009. Each row is
    counted in cells of ``cell`` from its nearest vertex, and one FFT of the counts (zero-padded to
    ``pad`` times their length: a peak between two of its frequencies loses less) gives every width at
    once."""
    x = (rho - rho.min(1)[:, None]) / cell
    n_cells = int(x.max()) + 1
    counts = np.bincount(_cell_ids(x, n_cells)[0], minlength=len(rho) * n_cells).reshape(len(rho), n_cells)
    n_fft = 1 << int(np.ceil(np.log2(pad * n_cells)))
    k_lo = max(int(np.floor(n_fft * cell / w_max)), 1)  # frequency k: a width of n_fft * cell / k
    k_hi = int(np.ceil(n_fft * cell / w_min)) + 1
    band = np.fft.rfft(counts, n=n_fft, axis=1)[:, k_lo:k_hi]
    power = band.real**2 + band.imag**2
    return power.max(1), n_fft * cell / (k_lo + np.argmax(power, axis=1))


def refine_frame(V: np.ndarray, a: np.ndarray, fr: Frame, n_bins: int, sample: int = REFINE_SAMPLE) -> Frame:
    """The frame near ``fr`` (centre, lo, hi within ``REFINE_BOUND`` bin widths of n_bins bins) that
    maximises the mark's ``energies``: a compass search over the 5 parameters on a subsample of the
    vertices (every k-th by distance to the centre, ``sample`` of them at most). Attacks that move the
    frame by a fraction of a bin (simplification, noise, quantisation) leave the marked bins' bias in
    place; this finds the frame that shows it again. Key-independent: the reader may use it without
    counting it as a choice made with the secret."""
    sub = thinned(by_distance(V, a, fr.centre), sample)
    return refine_frame_on(V[sub], a[sub], fr, n_bins)


def by_distance(V: np.ndarray, a: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The vertices of positive weight a (n,), nearest ``centre`` first (ties in index order), (k,) int64."""
    keep = np.flatnonzero(a > 0)
    return keep[stable_argsort(row_norms(V[keep] - centre))]


def thinned(order: np.ndarray, k: int) -> np.ndarray:
    """Every j-th of ``order`` (at most k of them): a sample that does not depend on the vertex order
    when ``order`` does not (``by_distance``)."""
    return order[:: max(1, -(-len(order) // k))]


def refine_frame_on(Vs: np.ndarray, As: np.ndarray, fr: Frame, n_bins: int) -> Frame:
    """``refine_frame`` on the sample Vs (k, 3) with weights As (k,) (``thinned``)."""
    w = (fr.hi - fr.lo) / n_bins
    dirs = np.concatenate([np.eye(5), -np.eye(5)])

    def evaluate(X: np.ndarray) -> np.ndarray:
        return energies(Vs, As, fr.centre + w * X[:, :3], fr.lo + w * X[:, 3], fr.hi + w * X[:, 4], n_bins)

    x = np.zeros(5)
    best = float(evaluate(x[None])[0])
    for st in REFINE_STEPS:
        back = -1  # the move back to the point just left (its energy is known to be lower)
        for _ in range(REFINE_MOVES):
            cands = x + st * dirs
            ok = np.all(np.abs(cands) <= REFINE_BOUND, axis=1)
            if back >= 0:
                ok[back] = False
            which = np.flatnonzero(ok)
            if not len(which):
                break
            e = evaluate(cands[which])
            i = int(np.argmax(e))
            if not e[i] > best:
                break
            best, x, back = float(e[i]), cands[which[i]], (int(which[i]) + 5) % 10
    return Frame(fr.centre + w * x[:3], float(fr.lo + w * x[3]), float(fr.hi + w * x[4]), fr.n_bins)


def excess_energy(stat: np.ndarray, share: np.ndarray, n_vertices: float) -> float:
    """How far the energy of a reading (bin statistics (M,), shares (M,)) is above an unmarked mesh's,
    in standard deviations: (12 E - M) / sqrt(2 M), E = sum n_j stat_j^2 (the mark's energy)."""
    n = share * n_vertices
    e = float(np.sum(np.where(n > 0, n * np.nan_to_num(stat) ** 2, 0.0)))
    M = int(np.sum(n > 0))
    return (12.0 * e - M) / np.sqrt(2.0 * max(M, 1))


ISI_MIN = 0.25  # equalize when a neighbour's sign moves a bin by at least this share of its own sign's move
# (8-bit quantization and 0.5 % noise show 0.3-0.4; sqrt3 subdivision up to 0.25, which is better left as read:
# docs/decisions/082-blind-carrier-and-word.md)
ISI_ROUNDS = 4  # fits of g and c, each on the signs the Viterbi search found with the one before


def equalized(stat: np.ndarray) -> np.ndarray:
    """The bins' statistics (M,) float64, in radial order (NaN: an empty bin), each in units of its
    standard error (``word_read``), with the interference of each bin's two radial neighbours removed.

    An attack that blurs the radii by a good part of a bin (8-bit quantization: the bin means fall to about a
    third of the mark's and each neighbour's sign pulls a bin the other way by about 0.4 of that) spills each
    bin's pushed vertices into its neighbours. Model: stat_j = g s_j + c (s_{j-1} + s_{j+1}) + noise, s = +-1 the
    bins' signs. g and c come from a regression on the signs read, the signs from the most likely sequence under
    the model (a Viterbi search, 4 states: two consecutive signs), alternately, from the hard decisions on, until
    the signs settle (ISI_ROUNDS fits at most); the interference is judged on the last fit. The result is each
    bin's own reading with its neighbours' signs summed out, not guessed: the log posterior odds of its sign under
    the model (a forward-backward pass over the same chain, the noise's variance from the fit's residuals), times
    sigma^2 / (2 g) to stay in the statistic's units (without interference that is stat_j itself). A bin whose
    neighbours are uncertain keeps a small value, so the reader's search (``word.likely_flips``) tries it early;
    subtracting the most likely neighbours' interference instead, stat_j - c (s_{j-1} + s_{j+1}), doubles it when
    a neighbour's sign is wrong. Nothing here involves the pass phrase: the p-value stays exact. When c is above
    -ISI_MIN g (no interference to speak of: an intact copy, smoothing, most subdivisions and simplifications) the
    statistics are returned as they are.

    Why the rounds: a fit on the hard decisions alone, many of them wrong after 8-bit quantization, sees much
    less interference than there is (docs/decisions/082-blind-carrier-and-word.md)."""
    empty, x, s, g, c = _settled_fit(stat)
    if not (g > 0 and c < -ISI_MIN * g):
        return stat
    var = float(np.mean((x - g * s - c * _neighbours(s))[~empty] ** 2))
    if not var > 0:
        return np.where(empty, np.nan, x - c * _neighbours(s))  # (a noiseless fit: the signs are known)
    return np.where(empty, np.nan, _posterior_odds(x, empty, g, c, var) * (var / (2.0 * g)))


def interferes(stat: np.ndarray) -> bool:
    """Whether the bins' statistics (M,) (in standard errors, radial order, NaN: empty) show their
    neighbours' interference as ``equalized`` judges it: c < -ISI_MIN g once the fit's signs settle."""
    _, _, _, g, c = _settled_fit(stat)
    return bool(g > 0 and c < -ISI_MIN * g)


def in_standard_errors(stat: np.ndarray, share: np.ndarray) -> np.ndarray:
    """Bin means (M,) in units of their standard errors, up to a common factor: times sqrt(share), the
    bins' shares of the vertices (M,) (a bin mean of n vertices errs by about 1 / sqrt(12 n)); an empty
    bin stays NaN."""
    return stat * np.sqrt(np.nan_to_num(share))


def _settled_fit(stat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """(empty bins, the statistics with 0 there, the signs, g, c): ``equalized``'s fit of g and c
    alternating with the Viterbi signs from the hard decisions on, until the signs settle (ISI_ROUNDS
    fits at most), then once more on them; stopped where g is not positive."""
    empty = np.isnan(stat)
    x = np.where(empty, 0.0, stat)
    s = np.sign(x)
    for _ in range(ISI_ROUNDS):
        g, c = _fit(x, s)
        if not g > 0:
            return empty, x, s, g, c
        found = np.where(empty, 0.0, _most_likely_signs(x, g, c))  # an empty bin spills nothing
        if np.array_equal(found, s):
            break
        s = found
    g, c = _fit(x, s)
    return empty, x, s, g, c


def _fit(x: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """(g, c) of the least-squares fit x_j = g s_j + c (s_{j-1} + s_{j+1}) over the bins (M,)."""
    (g, c), *_ = np.linalg.lstsq(np.stack([s, _neighbours(s)], 1), x, rcond=None)
    return float(g), float(c)


def _posterior_odds(x: np.ndarray, empty: np.ndarray, g: float, c: float, var: float) -> np.ndarray:
    """log P(s_j = +1 | x) - log P(s_j = -1 | x) for each bin (M,) under x_j = g s_j + c (s_{j-1} +
    s_{j+1}) + N(0, var), the signs +-1 equally likely a priori, an empty bin's sign 0 (it spills nothing
    and reads nothing), 0 beyond the ends: forward-backward over pairs of consecutive signs, in logs."""
    M = len(x)
    values = np.array([-1.0, 0.0, 1.0])
    sign_prior = np.array([0.0, -np.inf, 0.0])
    zero_prior = np.array([-np.inf, 0.0, -np.inf])
    prior = np.vstack([np.where(empty[:, None], zero_prior, sign_prior), zero_prior])  # (M + 1, 3): s_M = 0
    prev, cur, nxt = values[:, None, None], values[None, :, None], values[None, None, :]
    fit = g * cur + c * (prev + nxt)  # (3, 3, 3): x_j's mean for (s_{j-1}, s_j, s_{j+1})
    loglik = np.where(empty[:, None, None, None], 0.0, -((x[:, None, None, None] - fit[None]) ** 2) / (2.0 * var))
    step = loglik + prior[1:, None, None, :]  # (M, 3, 3, 3), with s_{j+1}'s prior
    fwd = np.full((M + 1, 3, 3), -np.inf)  # fwd[j][s_{j-1}, s_j]
    fwd[0, 1, :] = prior[0]  # s_{-1} = 0
    for j in range(M):
        fwd[j + 1] = np.logaddexp.reduce(fwd[j][:, :, None] + step[j], axis=0)
    bwd = np.full((M + 1, 3, 3), -np.inf)  # bwd[j][s_{j-1}, s_j]
    bwd[M, :, 1] = 0.0  # s_M = 0
    for j in range(M - 1, -1, -1):
        bwd[j] = np.logaddexp.reduce(step[j] + bwd[j + 1][None, :, :], axis=2)
    marginal = np.logaddexp.reduce(fwd[:M] + bwd[:M], axis=1)  # (M, 3): over s_j
    with np.errstate(invalid="ignore"):
        return np.where(empty, 0.0, marginal[:, 2] - marginal[:, 0])


def _neighbours(s: np.ndarray) -> np.ndarray:
    """s_{j-1} + s_{j+1} for each bin j (0 beyond the ends)."""
    out = np.zeros_like(s)
    out[1:] += s[:-1]
    out[:-1] += s[1:]
    return out


def _most_likely_signs(x: np.ndarray, g: float, c: float) -> np.ndarray:
    """The signs (M,) +-1 minimising sum_j (x_j - g s_j - c (s_{j-1} + s_{j+1}))^2 (s = 0 beyond the
    ends): a Viterbi search whose state is two consecutive signs (one step per bin: 64-96 steps)."""
    S = np.array([-1.0, 1.0])
    M = len(x)
    if M < 2:
        return np.where(x >= 0, 1.0, -1.0)
    prev, cur, nxt = S[:, None, None], S[None, :, None], S[None, None, :]
    # each inner bin's cost for every (s_{j-1}, s_j, s_{j+1}), all at once: the loop only adds and compares
    step = (x[1 : M - 1, None, None, None] - g * cur - c * (prev + nxt)) ** 2  # (M - 2, 2, 2, 2)
    cost = (x[0] - g * S[:, None] - c * S[None, :]) ** 2  # [s_0, s_1]
    back = np.zeros((M, 2, 2), np.int64)  # back[j][s_j, s_{j+1}]: the best s_{j-1} (the first on a tie)
    for j in range(1, M - 1):
        total = cost[:, :, None] + step[j - 1]  # [s_{j-1}, s_j, s_{j+1}]
        back[j] = total[1] < total[0]
        cost = np.minimum(total[0], total[1])  # [s_j, s_{j+1}]
    last = cost + (x[M - 1] - g * S[None, :] - c * S[:, None]) ** 2  # [s_{M-2}, s_{M-1}], s_M = 0
    a, b = np.unravel_index(int(np.argmin(last)), last.shape)
    out = np.empty(M)
    out[M - 1], out[M - 2] = S[b], S[a]
    for j in range(M - 2, 0, -1):
        p = back[j][a, b]
        out[j - 1] = S[p]
        a, b = p, a
    return out


def statistics_in(V: np.ndarray, a: np.ndarray, fr: Frame, bin_counts) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per bin count: each bin's mean of r minus 1/2 (M,) (NaN: empty) and its share of the vertices
    (M,), in the frame ``fr`` (its n_bins is ignored)."""
    d = V - fr.centre
    t0 = (np.sqrt(np.einsum("ij,ij->i", d, d)) - fr.lo) / (fr.hi - fr.lo)
    out = []
    for n_bins in bin_counts:
        b, r = _bins(t0 * n_bins, n_bins)
        mean, wsum = bin_statistics(r, b, a, n_bins)
        out.append((mean - 0.5, wsum / a.sum()))
    return out
