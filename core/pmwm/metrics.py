"""Watermark and distortion metrics (DESIGN.md section 6).

Bits:        ``ber``, ``correlation`` (the paper's eq. 6).
Distortion:  ``vertex_rmse``, ``vsnr`` (centred or not), ``psnr``, ``surface_distance`` (MRMS and
             Hausdorff from surface samples, both directions, % of the first mesh's bbox diagonal);
             ``displaced_surface_distance``, the same for a displaced copy (same faces) without a
             spatial index.
The limit:   ``matched_filter_bound`` (best correlation any detector can reach for a given
             embedding energy per bit against noise of a given std).

Bit sequences may be strings of '0'/'1' or sequences of 0/1; any other symbol (e.g. '?' or -1) is an
erasure: it counts as an error in the BER and as the neutral value 1/2 in the correlation.

Point-to-surface distances are exact, searched by ``pmwm.spatial.surface_distances`` (KD-trees over
the triangles' centres bound the candidates; each gets an exact closest-point test, Ericson,
Real-Time Collision Detection, 5.1.5: ``closest_point_on_triangles``, kept here under its old name).
"""

from __future__ import annotations

import math

import numpy as np

from . import spatial
from .errors import MeshError, PayloadError
from .adjacency import ranges, stable_order
from .background import parallel_map
from .sampling import sample_faces, sample_surface
from .features import squared_norms
from .spatial import closest_point_on_triangles
from .validate import parse_bits

# ----------------------------------------------------------------------------------------------
# bits


def _bit_pair(a, b) -> tuple[np.ndarray, np.ndarray]:
    x, y = parse_bits(a, erasures=True), parse_bits(b, erasures=True)
    if len(x) != len(y):
        raise PayloadError(f"bit sequences differ in length ({len(x)} vs {len(y)}); compare equal payloads")
    if len(x) == 0:
        raise PayloadError("empty bit sequences; compare at least one bit")
    return x, y


def ber(a, b) -> float:
    """Bit error rate: share of positions that differ (an erasure counts as an error)."""
    x, y = _bit_pair(a, b)
    errors = ~(x == y)  # NaN compares unequal
    return float(errors.mean())


def correlation(a, b) -> float:
    """Correlation coefficient of two bit sequences (paper eq. 6, over all N bits).

    Eq. 6 is Pearson's coefficient, undefined when either sequence is constant. Then we return
    1 - 2 * BER, the value the coefficient takes for balanced sequences with that BER: 1.0 for equal
    sequences, -1.0 for complementary ones, 0 at chance level. Erasures count as 1/2.
    """
    x, y = _bit_pair(a, b)
    x = np.where(np.isnan(x), 0.5, x)
    y = np.where(np.isnan(y), 0.5, y)
    dx, dy = x - x.mean(), y - y.mean()
    sxx, syy = float(dx @ dx), float(dy @ dy)
    if sxx <= 1e-12 or syy <= 1e-12:
        return 1.0 - 2.0 * ber(a, b)
    return float((dx @ dy) / math.sqrt(sxx * syy))


def binomial_tail(k: int, n: int, p: float = 0.5) -> float:
    """P(K >= k) for K ~ Binomial(n, p), computed in log space (exact, no scipy)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    i = np.arange(k, n + 1)
    logs = (
        np.array([math.lgamma(n + 1) - math.lgamma(j + 1) - math.lgamma(n - j + 1) for j in i])
        + i * math.log(p)
        + (n - i) * math.log1p(-p)
    )
    top = logs.max()
    return float(min(1.0, math.exp(top) * np.exp(logs - top).sum()))


def union_bound(p: float, tries: int) -> float:
    """The p-value of the best of ``tries`` readings, each of p-value ``p`` at best: min(1, p * tries)
    (Bonferroni; holds whatever the dependence between the readings)."""
    return float(min(1.0, p * max(int(tries), 1)))


# ----------------------------------------------------------------------------------------------
# vertex distortion


def _pair(orig, marked) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(orig, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(marked, dtype=np.float64).reshape(-1, 3)
    if a.shape != b.shape:
        raise MeshError(
            f"vertex counts differ ({len(a)} vs {len(b)}); vertex metrics need the same vertices in the "
            "same order, use surface_distance otherwise"
        )
    return a, b


def vertex_rmse(orig, marked) -> float:
    """Root mean square of the 3-D vertex displacements."""
    a, b = _pair(orig, marked)
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))) if len(a) else 0.0


def vsnr(orig, marked, centred: bool = True) -> float:
    """VSNR = 10 log10(sum |v_i - c|^2 / sum |v_i - v'_i|^2) in dB; inf for identical meshes.

    ``centred=True`` takes c = vertex mean of the original; ``False`` takes c = origin (the paper
    does not say which it uses, so both are reported).
    """
    a, b = _pair(orig, marked)
    noise = float(np.sum((a - b) ** 2))
    signal = float(np.sum((a - a.mean(axis=0)) ** 2)) if centred else float(np.sum(a**2))
    if noise == 0.0:
        return math.inf
    return 10.0 * math.log10(signal / noise)


def bbox_diagonal(vertices) -> float:
    """The length of the diagonal of the bounding box of the points (n, 3) (0 for none). The extremes a
    column at a time: numpy's axis-0 reduction of an (n, 3) array (``v.max(0)``) is many times slower
    (docs/decisions/083-numpy-fast-paths.md), with the same values (a maximum does not round)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if not len(v):
        return 0.0
    return float(np.linalg.norm(np.array([v[:, k].max() - v[:, k].min() for k in range(3)])))


def psnr(orig, marked) -> float:
    """PSNR = 20 log10(bbox diagonal of the original / vertex RMSE) in dB; inf for identical meshes."""
    rmse = vertex_rmse(orig, marked)
    if rmse == 0.0:
        return math.inf
    return 20.0 * math.log10(bbox_diagonal(orig) / rmse)


# ----------------------------------------------------------------------------------------------
# the limit


def q_function(x: float) -> float:
    """Gaussian tail Q(x) = P(Z > x)."""
    return 0.5 * math.erfc(x / math.sqrt(2.0))


def matched_filter_bound(E_per_bit: float, sigma: float) -> float:
    """Best expected correlation 1 - 2 Q(sqrt(E/N) / sigma) against noise of per-coordinate std sigma.

    ``E_per_bit`` is the embedding's total squared displacement (sum over vertices of |v - v'|^2,
    = n d^2 for an RMS displacement d) divided by the number of payload bits. Uniform noise of
    amplitude a has sigma = a / sqrt(3). No detector beats the matched filter (DESIGN section 6).
    """
    if E_per_bit < 0 or sigma < 0:
        raise ValueError("E_per_bit and sigma must be >= 0")
    if sigma == 0:
        return 1.0 if E_per_bit > 0 else 0.0
    return 1.0 - 2.0 * q_function(math.sqrt(E_per_bit) / sigma)


def energy_per_bit(orig, marked, n_bits: int) -> float:
    """Total squared vertex displacement of the embedding divided by the number of bits."""
    a, b = _pair(orig, marked)
    return float(np.sum((a - b) ** 2)) / int(n_bits)


# ----------------------------------------------------------------------------------------------
# surface distance


def point_surface_distance(points, vertices, faces) -> np.ndarray:
    """Exact distance from each point (m, 3) to the triangle surface (vertices, faces): (m,)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        raise MeshError("the mesh has no faces; surface metrics need triangles")
    return spatial.surface_distances(np.asarray(points, dtype=np.float64).reshape(-1, 3), v[f])


def surface_distance(v1, f1, v2, f2, n_samples: int = 20000, seed: int | None = None) -> tuple[float, float]:
    """(MRMS %, Hausdorff %) between two surfaces, both directions, % of mesh 1's bbox diagonal.

    ``n_samples`` area-uniform points are drawn on each surface and their exact distance to the
    other surface is measured. MRMS = max of the two one-sided RMS distances (METRO-style maximum
    root mean square, as in the benchmark); Hausdorff = max of the two one-sided maxima (an estimate
    from the samples, so a lower bound of the true Hausdorff distance).
    """
    s1, s2 = _sample_seeds(seed)
    p1, _ = sample_surface(v1, f1, n_samples, s1)
    p2, _ = sample_surface(v2, f2, n_samples, s2)
    return _mrms_hausdorff(point_surface_distance(p1, v2, f2), point_surface_distance(p2, v1, f1), v1)


def displaced_surface_distance(v1, v2, faces, n_samples: int = 20000, seed: int | None = None) -> tuple[float, float]:
    """(MRMS %, Hausdorff %) between a mesh (v1, faces) and a displaced copy of it (v2, the same faces),
    as ``surface_distance(v1, faces, v2, faces, n_samples, seed)`` measures them, on the same sample
    points, without a spatial index: each sample's nearest point on the other surface is searched on
    the faces that share a vertex with the sample's own face. That is exact while the nearest point
    lies on those faces, as it does when the vertices move by much less than an edge (an
    embedding's displacement; the blind scheme calibrates its margin with it); otherwise the
    distance found is an upper bound. v1, v2 : (n, 3) float64; faces : (m, 3) int64.
    """
    a = np.asarray(v1, dtype=np.float64)
    b = np.asarray(v2, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if a.shape != b.shape:
        raise MeshError(f"a displaced copy has the same vertices; got {len(a)} and {len(b)}. Use surface_distance")
    s1, s2 = _sample_seeds(seed)

    def one_way(way: tuple[np.ndarray, np.ndarray, int]) -> np.ndarray:
        src, dst, s = way
        return _distance_near_own_face(src, dst, F, *sample_faces(src, F, n_samples, s))

    # the two directions side by side (independent; numpy releases the GIL in their loops)
    d12, d21 = parallel_map(one_way, [(a, b, s1), (b, a, s2)])
    return _mrms_hausdorff(d12, d21, a)


def _sample_seeds(seed: int | None) -> tuple[int, int]:
    """The seeds of the two surfaces' samples, from the measure's seed."""
    s1, s2 = np.random.default_rng(seed).integers(0, 2**63 - 1, size=2)
    return int(s1), int(s2)


def _mrms_hausdorff(d12: np.ndarray, d21: np.ndarray, v1) -> tuple[float, float]:
    """(MRMS %, Hausdorff %) from the one-sided sample distances (k,), % of v1's bbox diagonal."""
    diag = bbox_diagonal(v1)
    if diag == 0:
        raise MeshError("the first mesh has a zero-size bounding box; nothing to measure against")
    rms = max(float(np.sqrt(np.mean(d12**2))), float(np.sqrt(np.mean(d21**2))))
    haus = max(float(d12.max()), float(d21.max()))
    return 100.0 * rms / diag, 100.0 * haus / diag


def _distance_near_own_face(
    src: np.ndarray, dst: np.ndarray, F: np.ndarray, face: np.ndarray, w: np.ndarray
) -> np.ndarray:
    """Distance (k,) from the points with barycentric weights w (k, 3) in faces ``face`` (k,) of
    (src, F) to the faces of (dst, F) sharing a vertex with their own face. Only the sampled faces'
    vertices have their faces grouped (one sort of their corners): a whole ``Adjacency`` would cost
    more than the measure (about 90 ms on Igea)."""
    p = np.einsum("ij,ijk->ik", w, src[F[face]])
    need = np.zeros(len(src), bool)
    need[F[face]] = True
    corners = np.flatnonzero(need[F.ravel()])  # corners at a vertex of a sampled face
    order, vert = stable_order(F.ravel()[corners])
    around = corners[order] // 3  # their faces, grouped by vertex
    start = np.searchsorted(vert, F[face])  # (k, 3): each sample's vertices' groups
    count = np.searchsorted(vert, F[face], side="right") - start
    cand = around[ranges(start.ravel(), count.ravel())]
    owner = np.repeat(np.arange(len(face)), count.sum(axis=1))
    # the own face first; then only the faces whose plane passes nearer than it (the distance to a
    # triangle is at least that to its plane; the margin covers rounding): the same minimum, with a
    # fraction of the closest-point work
    own = dst[F[face]]
    out = np.linalg.norm(closest_point_on_triangles(p, own[:, 0], own[:, 1], own[:, 2]) - p, axis=1)
    tri = dst[F[cand]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nn = np.sqrt(squared_norms(n))
    with np.errstate(divide="ignore", invalid="ignore"):
        plane = np.abs(np.einsum("ij,ij->i", n, p[owner] - tri[:, 0])) / nn
    near = ~(plane * (1 - 1e-9) > out[owner])  # (NaN for a face of no area: kept)
    near &= cand != face[owner]
    i = np.flatnonzero(near)
    tri, q = tri[i], p[owner[i]]
    d = np.linalg.norm(closest_point_on_triangles(q, tri[:, 0], tri[:, 1], tri[:, 2]) - q, axis=1)
    np.minimum.at(out, owner[i], d)
    return out


__all__ = [
    "ber",
    "correlation",
    "binomial_tail",
    "vertex_rmse",
    "vsnr",
    "psnr",
    "bbox_diagonal",
    "q_function",
    "matched_filter_bound",
    "energy_per_bit",
    "closest_point_on_triangles",
    "point_surface_distance",
    "surface_distance",
    "displaced_surface_distance",
]
