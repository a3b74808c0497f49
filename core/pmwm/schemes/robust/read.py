"""Reading the robust mark (see ``pmwm.schemes.robust``): heights along each site's normal, by vertex
index or where lines cross the suspect surface, the matched filter per site, the swirl by index,
and the per-bit scores. Shapes: S sites, K samples per site."""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Callable, Iterator, Optional

import numpy as np

from ...base import Progress, Verdict, VerdictDetail, decode_text, no_progress, verdict_from_scores
from ...errors import KeyFileError
from ...key import WatermarkKey, face_fingerprint
from ...register import POSES, register_poses, similarity_fit
from ...smoothing import mean_operator
from ...spatial import nearest
from ...validate import check_mesh
from .code import coded_bits, confirm_with
from .fields import OUTER, heights, index_templates, profile
from .keydata import RobustKeyData

NAME = "robust"
TAU = 0.5  # prior size of a site's offset/tilt, in bump amplitudes (ridge of the nuisance fit)
LAPLACE_POWERS = 3  # powers of the unmarked mesh's Laplacian fitted by index (what smoothing moves)
VAR_FLOOR = 0.01  # floor of a site's soft-value variance (an intact site is not infinitely sure)
MIN_COVER = 0.3  # a site needs this share of its filter energy readable
IN_PLACE_SHARE = 0.1  # share of site vertices exactly in place for a copy to be read in the key's frame
INDEX_MATCH = 0.3  # index reading when sample vertices are within this share of the size and the faces are kept
INDEX_CLOSE = 0.05  # ... or within this share, whatever the faces (noise, smoothing and quantization keep both)
SCREEN_PER_BIT = 2  # sites per bit a registered pose is screened on
FULL_READS = 2  # the strongest screened poses read in full
CLEAR = 0.5  # a screened pose whose strength reaches this share of the largest possible is read in full at once
GAIN_MAX = 1.2  # the largest gain a site's own reading may show, in bump amplitudes (site_llr)
MODEL_VAR = 0.04  # variance added to a site's own, for what its noise estimate misses (site_llr)
OUTLIER_SHARE = 0.05  # prior share of sites whose reading is not their own mark's (site_llr)
OUTLIER_SPAN = 10.0  # such a reading may be anything over this span, in bump amplitudes


ALIGNED = "none (already in the key's frame)"  # RobustDetail.registration of a copy read in place
BY_INDEX = "by vertex index"  # ... of a copy registered by its sample vertices


@dataclass(frozen=True)
class RobustDetail(VerdictDetail):
    """How the robust reader read a suspect. registration: ``ALIGNED``, ``BY_INDEX``, or the start of the
    surface registration that won (``pmwm.register``: "identity", "pca..."), then ``residual`` (its trimmed
    RMS distance, in the key's frame) and ``scale`` (suspect size / marked size); heights: "by vertex index"
    or "by position" (", site vertices first" for a copy in the key's frame); sites_read of sites_total:
    the sites whose bump could be read."""

    registration: str
    heights: str
    sites_read: int
    sites_total: int
    residual: Optional[float] = None
    scale: Optional[float] = None
    mirrored: bool = False
    poses_read: int = 1
    poses_paid: int = 1
    payload_code: str = "none"
    corrected: int = 0
    coded_bits: str = ""
    coded_key_bits: str = ""

    def notes(self) -> list[str]:
        return ["read as a mirror image of the marked mesh (the copy was mirrored)"] if self.mirrored else []

    def in_words(self) -> list[tuple[str, str]]:
        if self.registration == ALIGNED:
            found = "it sits where the marked mesh was: read in place"
        elif self.registration == BY_INDEX:
            found = "it keeps the marked mesh's vertex order: lined up with the key vertex by vertex"
        else:
            found = "it was moved, re-ordered or re-meshed: lined up with the key by its shape"
        how = (
            "each place read on its own vertices"
            if self.heights.startswith("by vertex index")
            else "each place read where the surface passes"
        )
        rows = [
            ("How the copy was found", found),
            ("How it was read", how),
            ("Places read", f"{self.sites_read} of the {self.sites_total} places that carry the mark"),
        ]
        if self.mirrored:
            rows.append(("Mirrored", "yes: the copy is a mirror image of the marked mesh"))
        if self.corrected:
            rows.append(("Corrected", f"{self.corrected} coded bits read wrong were corrected by the payload code"))
        return rows

    def numbers(self) -> list[tuple[str, str]]:
        rows = [
            ("registration", self.registration),
            ("heights", self.heights),
            ("sites read", f"{self.sites_read}/{self.sites_total}"),
        ]
        if self.residual is not None:
            rows += [("registration residual", f"{self.residual:.3g}"), ("scale", f"{self.scale:.6g}")]
        rows += [
            ("mirrored", "yes" if self.mirrored else "no"),
            ("poses read", str(self.poses_read)),
            ("poses paid (union bound)", str(self.poses_paid)),
            ("payload code", self.payload_code),
            ("coded bits corrected", str(self.corrected)),
        ]
        return rows


def key_data(key: WatermarkKey) -> RobustKeyData:
    """The key's robust data: read when the key file was read, or read now (and kept) from ``extra``."""
    if key.scheme != NAME:
        raise KeyFileError(f"this key is for the {key.scheme!r} scheme, not {NAME!r}; use pmwm.verify")
    if not isinstance(key.data, RobustKeyData):
        key.data = RobustKeyData.from_extra(key.extra, key.n_bits, key.n_vertices)
    return key.data


def _sample_heights(X: np.ndarray, F: np.ndarray, s: RobustKeyData, by_index: bool) -> np.ndarray:
    """Suspect height along each site's normal at each sample (S, K), NaN where there is none."""
    sm = s.samples
    P, N = s.origin, s.normal
    if by_index:
        H = np.einsum("skj,sj->sk", X[sm.vertex] - P[:, None, :], N)
        return np.where(sm.mask, H, np.nan)
    t1, t2 = s.t1, s.t2
    far = 1e30  # padding lines far outside any face
    uv = np.stack([np.where(sm.mask, sm.u, far), np.where(sm.mask, sm.v, far)], axis=2)
    shift = s.amplitude * profile(sm.u, sm.v, s.radius)
    expect = np.stack([sm.h + shift, sm.h - shift], axis=2)  # the two possible marked heights
    reach = (OUTER + 0.3) * s.radius
    return heights(X, F, P, N, t1, t2, uv, reach, expect=expect)


def _centre_heights(X: np.ndarray, P: np.ndarray, N: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Height along N of the suspect vertex nearest each site's place P (NaN when none is within
    ``reach``), and how far off the line P + h N that vertex lies."""
    j, d2 = nearest(X, P)
    rel = X[j] - P
    h = np.einsum("ij,ij->i", rel, N)
    off = np.linalg.norm(rel - h[:, None] * N, axis=1)
    return np.where(d2 <= reach * reach, h, np.nan), off


def centre_soft(X: np.ndarray, s: RobustKeyData, by_index: bool) -> np.ndarray:
    """Soft value per site read at the site's own vertex alone (its height change over the bump
    height; NaN where unreadable): exact on the marked mesh and its levels of detail, where the
    site vertex is kept and the other samples lie on a coarser surface. By position it is the
    suspect vertex within 1.5 bump heights of the site's place (a neighbour's bump may add to its
    own on a small mesh); lines would miss it where a coarse fan folds over its own vertex."""
    sm = s.samples
    P, N, A = s.origin, s.normal, s.amplitude
    has = sm.centre >= 0
    if by_index:
        v = sm.vertex[np.arange(len(P)), np.maximum(sm.centre, 0)]
        h = np.einsum("ij,ij->i", X[v] - P, N)
    else:
        h, _ = _centre_heights(X, P, N, 1.5 * A + 1e-6 * s.frame.scale)
    return np.where(has, h / A, np.nan)


def host_laplacians(X: np.ndarray, F: np.ndarray, s: RobustKeyData) -> tuple[np.ndarray, ...]:
    """The uniform Laplacian (neighbour mean minus the vertex) of the UNMARKED mesh at each sample vertex, and
    its powers up to LAPLACE_POWERS, in the key's frame, (S, K, 3) each, with the suspect's faces F (m, 3) over
    X (n, 3) in the key's frame (a copy in the marked vertex order). The unmarked places are the key's where
    it stores them (every sample of every site), the suspect's elsewhere. Why: k uniform smoothing steps
    (I + lam L)^k move the unmarked surface by k lam L + C(k, 2) lam^2 L^2 + ..., which varies from vertex to
    vertex with the triangulation and the curvature; fitted (``shared_fit``), it no longer biases the reading."""
    sm = s.samples
    U = np.array(X, np.float64)
    U[sm.vertex[sm.mask]] = _sample_places(s)[sm.mask]
    M = mean_operator(np.asarray(F, np.int64).reshape(-1, 3), len(U))
    out = []
    for _ in range(LAPLACE_POWERS):
        U = M @ U - U
        out.append(U[sm.vertex])
    return tuple(out)


def shared_fit(Z: np.ndarray, y: np.ndarray, D: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The coefficients (k,) that every site shares in the least-squares fit of y (S, K) on Z (S, K, z), whose
    coefficients are each site's own, and D (S, K, k), whose coefficients are the same at every site; samples
    where ok (S, K) is False are left out. Each site's own terms are projected out of y and D first
    (Frisch-Waugh), so the shared coefficients are fitted on thousands of samples at once and cost no site
    any of its filter's energy."""
    Z = Z * ok[..., None]
    ZtZ = np.einsum("ski,skj->sij", Z, Z) + 1e-9 * np.eye(Z.shape[2])

    def rest(v):
        v = v * ok
        coef = np.linalg.solve(ZtZ, np.einsum("ski,sk->si", Z, v)[..., None])[..., 0]
        return (v - np.einsum("ski,si->sk", Z, coef)) * ok

    ry = rest(y)
    rD = np.stack([rest(D[..., j]) for j in range(D.shape[2])], axis=2)
    G = np.einsum("ski,skj->ij", rD, rD)
    scale = max(float(np.trace(G)), 1e-300)
    with np.errstate(invalid="ignore"):
        c = np.linalg.solve(G + 1e-12 * scale * np.eye(len(G)), np.einsum("ski,sk->i", rD, ry))
    return np.where(np.isfinite(c), c, 0.0)


def site_soft(
    X: np.ndarray, F: np.ndarray, s: RobustKeyData, by_index: bool, laplacians: Optional[tuple] = None
) -> tuple[np.ndarray, np.ndarray]:
    """(soft value, its variance) per site; soft ~ +-1 when intact, NaN when unreadable.

    y = height - stored height = a p + offset + tilt + noise. The filter is p minus its projection on
    (1, u/r, v/r), ridge-regularised by the site's noise level over (TAU A)^2, so the nuisance is removed
    where the noise is low and the filter tends to p where it is high. By index, what Laplacian smoothing
    moved the unmarked surface by along the site normal is taken off y first: c1 L + c2 L^2 + c3 L^3, the
    unmarked mesh's own Laplacian and its powers (``host_laplacians``; ``laplacians`` when the caller has
    them) with coefficients shared by every site (``shared_fit``: one smoothing, the same at every vertex),
    about 0 on a copy that was not smoothed.
    """
    sm = s.samples
    r, A = s.radius, s.amplitude
    H = _sample_heights(X, F, s, by_index)
    ok = sm.mask & np.isfinite(H)
    y = np.where(ok, H - sm.h, 0.0)
    # vertex heights (by index) also carry the swirl's part along the site normal
    p_all = index_templates(sm, r, s.swirl / A)[0] if by_index else profile(sm.u, sm.v, r) * sm.mask
    p = p_all * ok
    B = np.stack([np.ones_like(sm.u), sm.u / r, sm.v / r], axis=2) * ok[..., None]
    if by_index:
        laplacians = host_laplacians(X, F, s) if laplacians is None else laplacians
        D = np.stack([np.einsum("skj,sj->sk", L, s.normal) for L in laplacians], axis=2)
        y = (y - D @ shared_fit(np.concatenate([p[..., None], B], axis=2), y, D, ok)) * ok
    BtB = np.einsum("ski,skj->sij", B, B) + 1e-9 * np.eye(3)

    def filt(M):
        coef = np.linalg.solve(M, np.einsum("ski,sk->si", B, p)[..., None])[..., 0]
        f = (p - np.einsum("ski,si->sk", B, coef)) * ok
        return f, np.maximum((f * p).sum(axis=1), 1e-300)

    f0, fp0 = filt(BtB)  # the full nuisance fit, for the noise level
    a0 = (f0 * y).sum(axis=1) / fp0
    rest = y - a0[:, None] * p
    c = np.linalg.solve(BtB, np.einsum("ski,sk->si", B, rest)[..., None])[..., 0]
    resid = (rest - np.einsum("ski,si->sk", B, c)) * ok
    s2 = (resid**2).sum(axis=1) / np.maximum(ok.sum(axis=1) - 4, 1)
    f, fp = filt(BtB + (s2 / (TAU * A) ** 2)[:, None, None] * np.eye(3))
    with np.errstate(invalid="ignore", over="ignore"):  # a garbled site: no weight, not a NaN score
        soft = (f * y).sum(axis=1) / fp / A
        var = s2 * (f * f).sum(axis=1) / fp**2 / A**2 + VAR_FLOOR
    readable = (ok.sum(axis=1) >= 5) & (fp > MIN_COVER * (p_all**2).sum(axis=1)) & np.isfinite(soft) & np.isfinite(var)
    return np.where(readable, soft, np.nan), var


def swirl_soft(
    X: np.ndarray, F: np.ndarray, s: RobustKeyData, laplacians: Optional[tuple] = None
) -> tuple[np.ndarray, np.ndarray]:
    """(soft value, variance) per site of the in-surface swirl, read by vertex index: the sample
    vertices' tangent-plane shifts fitted as a * swirl + a common shift (a / swirl amplitude), once the
    tangential part of what Laplacian smoothing moved them by is taken off as in ``site_soft`` (smoothing
    also drifts vertices along the surface)."""
    sm = s.samples
    r, B = s.radius, s.swirl
    t1, t2 = s.t1, s.t2

    def tangent(D):
        return np.stack([np.einsum("skj,sj->sk", D, t1), np.einsum("skj,sj->sk", D, t2)], axis=2)

    m = sm.mask[..., None]
    n = np.maximum(sm.mask.sum(axis=1), 1)[:, None, None]

    def centred(a):
        return np.where(m, a - (a * m).sum(axis=1, keepdims=True) / n, 0.0)

    d = centred(tangent(X[sm.vertex] - _sample_places(s)))
    g = centred(index_templates(sm, r, B / s.amplitude)[1])
    laplacians = host_laplacians(X, F, s) if laplacians is None else laplacians
    S, K = sm.mask.shape
    D = np.stack([centred(tangent(L)) for L in laplacians], axis=3).reshape(S, 2 * K, -1)
    ok2 = np.repeat(sm.mask, 2, axis=1)
    d = d - (D @ shared_fit(g.reshape(S, 2 * K, 1), d.reshape(S, 2 * K), D, ok2)).reshape(S, K, 2) * m
    gg = np.maximum((g * g).sum(axis=(1, 2)), 1e-300)
    a = (g * d).sum(axis=(1, 2)) / gg
    s2 = ((d - a[:, None, None] * g) ** 2).sum(axis=(1, 2)) / np.maximum(2 * sm.mask.sum(axis=1) - 3, 1)
    readable = sm.mask.sum(axis=1) >= 5
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # a damaged key: no weight, no warning
        return np.where(readable, a / B, np.nan), s2 / gg / B**2 + VAR_FLOOR


def _combine(soft_a, var_a, soft_b, var_b) -> tuple[np.ndarray, np.ndarray]:
    """Inverse-variance combination of two readings of the same sites (NaN: not read)."""
    wa = np.where(np.isfinite(soft_a), 1.0 / var_a, 0.0)
    wb = np.where(np.isfinite(soft_b), 1.0 / var_b, 0.0)
    w = wa + wb
    with np.errstate(invalid="ignore", divide="ignore"):
        soft = (np.nan_to_num(soft_a) * wa + np.nan_to_num(soft_b) * wb) / w
    return np.where(w > 0, soft, np.nan), np.where(w > 0, 1.0 / np.maximum(w, 1e-300), var_a)


def bit_scores(soft: np.ndarray, var: np.ndarray, s: RobustKeyData, n_bits: int) -> np.ndarray:
    """Each bit's score (n_bits,) float64: the chip-signed sum of its readable sites' log-likelihood
    ratios (``site_llr``; NaN soft values are not read; 0 when no site of the bit is)."""
    ok = np.isfinite(soft)
    return np.bincount(s.bit[ok], weights=(s.chip * site_llr(soft, var))[ok], minlength=n_bits)


def site_llr(soft: np.ndarray, var: np.ndarray) -> np.ndarray:
    """Per site (S,) float64, the log-likelihood ratio of its chip-signed bit being +1 rather than -1
    (0 where soft is NaN). A site reads its sign times a gain g plus Gaussian noise of variance
    ``var`` + ``MODEL_VAR``, g anywhere in [0, ``GAIN_MAX``] (smoothing shrinks a mark, an average of
    copies halves some sites and keeps others), except with probability ``OUTLIER_SHARE``, when it
    reads anything within ``OUTLIER_SPAN`` bump amplitudes: a bump of another mark on or near the site
    (a copy marked again by another key), a site torn by the damage.

    A site that reads within its gains weighs about as much as its noise lets it (in proportion to
    soft / var where the noise is large), a sure site no more than about log(1 / OUTLIER_SHARE) (no single site, however
    sure it seems, outweighs a few others), and a reading that neither sign explains (|soft| beyond
    GAIN_MAX by several noise widths) weighs nothing. The ratio is odd in soft, so on a copy without the
    mark each bit still takes either sign with probability 1/2."""
    ok = np.isfinite(soft) & np.isfinite(var)
    x = np.where(ok, soft, 0.0)
    sd = np.sqrt(np.where(ok, var, 1.0) + MODEL_VAR)
    own = np.log1p(-OUTLIER_SHARE) - np.log(GAIN_MAX)  # the density of a gain in [0, GAIN_MAX]
    other = np.log(OUTLIER_SHARE / OUTLIER_SPAN)

    def log_density(z):  # of reading z for a mark of sign +1: the noise density averaged over the gains
        return own + np.log(np.maximum(_normal_cdf(z / sd) - _normal_cdf((z - GAIN_MAX) / sd), 1e-300))

    return np.where(ok, np.logaddexp(log_density(x), other) - np.logaddexp(log_density(-x), other), 0.0)


def _normal_cdf(z: np.ndarray) -> np.ndarray:
    """The standard normal distribution function at z (any shape), to 1e-7 absolute (Abramowitz and
    Stegun 7.1.26): ample beside the outliers' density in ``site_llr``, and it spares a command-line
    verify the import of scipy."""
    x = np.abs(z) / np.sqrt(2.0)
    t = 1.0 / (1.0 + 0.3275911 * x)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
    half_tail = 0.5 * poly * np.exp(-x * x)  # P(N > |z|)
    return np.where(z >= 0, 1.0 - half_tail, half_tail)


@dataclass
class Reading:
    """One reading of a suspect in one pose: per-bit ``scores`` (N,) float64 (sign = scrambled bit, 0 =
    erasure), how it was aligned (``mode``) and how it was read (``detail``), where the mark was read (``places``
    (k, 3) float64 the sites read, in the suspect's coordinates; ``place_bits`` (k,) int64 the bit of
    each), and ``poses``: how many poses a reading of this kind may have been chosen from (1 when the
    copy sits in the key's frame or keeps the marked vertex order; ``pmwm.register.POSES`` after
    registration), the factor of the union bound its p-value pays (``pose_bound``)."""

    scores: np.ndarray
    mode: str
    detail: RobustDetail
    places: np.ndarray
    place_bits: np.ndarray
    poses: int = 1


def pose_bound(p: np.ndarray, poses: int) -> np.ndarray:
    """A p-value read in the best of ``poses`` poses, corrected for them (union bound: the chance that
    any of them reads a mark by chance is at most ``poses`` times a single pose's), in [0, 1]."""
    return np.minimum(1.0, np.asarray(p, np.float64) * poses)


def readings(
    vertices,
    faces,
    key: WatermarkKey,
    strength: Optional[Callable[[np.ndarray], float]] = None,
    progress: Progress = None,
) -> Iterator[Reading]:
    """The suspect's readings, one per pose worth reading, most promising first (a generator: the caller
    stops when it has found its mark). vertices (n, 3), faces (m, 3).

    A copy in the key's frame or in the marked vertex order has one pose. After registration there may
    be several (a symmetric shape, a mirror image): each is first screened on a third of the sites
    (``SCREEN_PER_BIT`` per bit), by increasing residual, and ranked by ``strength`` (per-bit scores (N,) ->
    how strongly they show the caller's mark, at most sqrt(N); None: the poses' own order); a pose whose
    strength reaches ``CLEAR`` sqrt(N) is read in full at once (a caller that finds its mark there stops the
    screening), then the strongest are, ``FULL_READS`` full readings in all. Every registered reading pays for
    ``POSES`` poses (``pose_bound``), whichever were read. ``progress(fraction, message)`` at its stages (up to 0.9)."""
    report = progress or no_progress
    report(0.0, "loading the suspect")
    s = key_data(key)
    V, F = check_mesh(vertices, faces)
    if _in_key_frame(V, s, key):
        report(0.7, "reading the sites")
        yield _read_at(V, F, s, key, _identity, True, {"registration": ALIGNED})
        return
    X, back, mirrored = V, _identity, False
    if len(V) == key.n_vertices:
        # the marked vertices in their order (noise, smoothing, quantization, any pose, a mirror): the
        # similarity fit of the sample vertices is the registration, no ICP needed
        X, back, mirrored = _refined(V, s, back)
    if _same_vertices(X, F, s, key):
        report(0.7, "reading the sites")
        yield _read_at(X, F, s, key, back, False, {"registration": BY_INDEX, "mirrored": mirrored})
        return
    poses = register_poses(V, F, s.frame, progress=lambda f, m: report(0.1 + 0.6 * f, m))
    first = next(poses)
    if first[1].init == "identity":  # already at the sampling noise: read before any other pose is tried
        report(0.7, "reading the sites")
        yield _posed(first, F, s, key)
        first = None
    rest = ([first] if first is not None else []) + list(poses)
    if len(rest) > 1 and strength is not None:
        screen = _subset(s, _screen_sites(s))
        ranks, read = [], []
        for i, (X, _) in enumerate(rest):  # by increasing residual: the likeliest pose first
            scores = _read_at(X, F, screen, key, _identity, False, {"registration": "screening"}).scores
            ranks.append(strength(scores))
            if ranks[-1] >= CLEAR * np.sqrt(len(scores)) and len(read) < FULL_READS:  # clearly the mark's pose
                read.append(i)
                report(0.7, "reading the sites")
                yield _posed(rest[i], F, s, key)  # (the caller stops here when it is marked and confirmed)
        order = [i for i in np.argsort(-np.asarray(ranks), kind="stable") if i not in read]
        rest = [rest[i] for i in order[: FULL_READS - len(read)]]
    report(0.7, "reading the sites")
    for posed in rest:
        yield _posed(posed, F, s, key)


def _posed(posed, F: np.ndarray, s: RobustKeyData, key: WatermarkKey) -> Reading:
    """The full reading of one registered pose (X (n, 3) in the key's frame, its RegistrationInfo)."""
    X, info = posed
    R, k, t = info.rotation, info.scale, info.translation  # X = k V R^T + t
    back = lambda P: (P - t) @ R / k  # noqa: E731
    how = {
        "registration": info.init,
        "residual": float(info.residual),
        "scale": float(info.scale),
        "mirrored": bool(info.mirrored),
    }
    if _same_vertices(X, F, s, key):
        X, back, _ = _refined(X, s, back)
    return _read_at(X, F, s, key, back, False, how, poses=POSES)


def _screen_sites(s: RobustKeyData) -> np.ndarray:
    """The sites a pose is screened on: the first ``SCREEN_PER_BIT`` usable sites of each bit, (k,) int64."""
    order = np.flatnonzero(s.usable)
    order = order[np.argsort(s.bit[order], kind="stable")]
    rank = np.arange(len(order)) - np.searchsorted(s.bit[order], s.bit[order])
    return np.sort(order[rank < SCREEN_PER_BIT])


def _subset(s: RobustKeyData, sites: np.ndarray) -> RobustKeyData:
    """The key data of the ``sites`` (k,) int64 alone."""
    sm = copy.copy(s.samples)
    for name in ("mask", "u", "v", "h", "vertex", "normal_tt", "centre"):
        if getattr(sm, name) is not None:
            setattr(sm, name, getattr(sm, name)[sites])
    return dataclasses.replace(
        s,
        bit=s.bit[sites],
        chip=s.chip[sites],
        usable=s.usable[sites],
        centre_ok=s.centre_ok[sites],
        swirl_ok=s.swirl_ok[sites],
        index_ok=s.index_ok[sites],
        origin=s.origin[sites],
        normal=s.normal[sites],
        samples=sm,
    )


def _read_at(
    X: np.ndarray,
    F: np.ndarray,
    s: RobustKeyData,
    key: WatermarkKey,
    back: Callable[[np.ndarray], np.ndarray],
    aligned: bool,
    how: dict,
    poses: int = 1,
) -> Reading:
    """The reading of the suspect X (n, 3), F (m, 3) in the key's frame; ``back`` maps the key's frame to
    the suspect's; ``aligned``: X sits exactly in the key's frame; ``how``: RobustDetail's registration
    fields (registration, and residual, scale, mirrored where known)."""
    by_index = _same_vertices(X, F, s, key)
    soft, var = np.full(len(s.bit), np.nan), np.full(len(s.bit), VAR_FLOOR)
    full = (s.index_ok if by_index else s.usable).copy()
    if aligned:  # exact at the site vertex, where that reading was right on the marked mesh
        centre = centre_soft(X, s, by_index)
        at_centre = s.centre_ok & np.isfinite(centre)
        if by_index:  # a site read by index reads by all its vertices: its own vertex alone cannot tell
            at_centre &= ~full  # its bump from another mark's on or near it
        soft[at_centre] = centre[at_centre]
        full &= ~at_centre
    if full.any():
        laplacians = host_laplacians(X, F, s) if by_index else None
        soft_f, var_f = site_soft(X, F, s, by_index, laplacians)
        soft[full], var[full] = soft_f[full], var_f[full]
        if by_index and s.swirl > 0:  # keys from before the swirl have none
            soft_t, var_t = swirl_soft(X, F, s, laplacians)
            soft, var = _combine(soft, var, np.where(full & s.swirl_ok, soft_t, np.nan), var_t)
    heights = ("by vertex index" if by_index else "by position") + (", site vertices first" if aligned else "")
    detail = RobustDetail(heights=heights, sites_read=int(np.isfinite(soft).sum()), sites_total=int(len(soft)), **how)
    read = np.flatnonzero(np.isfinite(soft))
    return Reading(
        bit_scores(soft, var, s, s.coded_length(key.n_bits)),
        "aligned" if aligned else "registered",
        detail,
        back(s.origin[read]),
        s.bit[read].astype(np.int64),
        poses,
    )


def _identity(P: np.ndarray) -> np.ndarray:
    return P.copy()


def read_scores(vertices, faces, key: WatermarkKey) -> tuple[np.ndarray, str, RobustDetail]:
    """Per-bit scores (sign = scrambled bit, 0 = erasure) of a suspect, how it was aligned, and details:
    the reading ``verify`` keeps."""
    reading, _ = _strongest(vertices, faces, key, 1e-6)
    return reading.scores, reading.mode, reading.detail


def verify(vertices, faces, key: WatermarkKey, p_threshold: float = 1e-6, progress: Progress = None) -> Verdict:
    """Read the robust mark from a suspect mesh (any order, pose, mirror, resolution), with the key: the
    strongest of its readings (``readings``), its p-value paying for the poses tried (``pose_bound``).
    ``progress(fraction, message)`` at its stages (loading, registration, reading), ending at 1.0."""
    report = progress or no_progress
    verdict = _strongest(vertices, faces, key, p_threshold, report)[1]
    report(1.0, "read")
    return verdict


def _strongest(
    vertices, faces, key: WatermarkKey, p_threshold: float, progress: Progress = None
) -> tuple[Reading, Verdict]:
    """The reading of smallest p-value and its verdict; the readings stop at the first marked one whose
    payload is confirmed."""
    expected = expected_signs(key)

    def strength(scores: np.ndarray) -> float:  # how strongly per-bit scores show the key's coded bits
        return float(expected @ scores / max(np.sqrt(scores @ scores), 1e-300))

    best, n = None, 0
    for n, reading in enumerate(readings(vertices, faces, key, strength, progress), 1):
        verdict = _verdict(reading, key, p_threshold)
        if best is None or verdict.p_value < best[1].p_value:
            best = (reading, verdict)
        if verdict.marked and verdict.payload_confirmed:
            break
    (progress or no_progress)(0.9, "deciding")
    best[1].detail = dataclasses.replace(best[1].detail, poses_read=n)
    return best


def expected_signs(key: WatermarkKey) -> np.ndarray:
    """(N,) float64 +-1: the sign each coded bit's score has in a copy carrying the key's mark (its coded
    payload bits, scrambled by the key's stream)."""
    coded = coded_bits(key.bits, key_data(key).code)
    return 2.0 * (coded ^ key.stream("scramble", len(coded))).astype(np.float64) - 1.0


def confirm(bits_read_or_scores: np.ndarray, key: WatermarkKey) -> tuple[np.ndarray, bool, int]:
    """Whether a reading confirms the key's payload: (payload bits (k,) uint8, the key's when confirmed,
    else the bits as read, never to be shown as the payload; confirmed; coded bits corrected). The reading
    is one score per coded bit (N,) float64 (sign = the scrambled bit, 0 = erased) or the descrambled
    coded bits (N,) uint8; the key's payload code (``code.confirm_with``) decides, or without one, every bit
    read and right."""
    return confirm_with(bits_read_or_scores, key, key_data(key).code)


def _verdict(reading: Reading, key: WatermarkKey, p_threshold: float) -> Verdict:
    """The verdict of one reading: the p-value of its coded bits against the key's, corrected for the poses
    it was chosen from; the payload shown only when ``confirm`` confirms it."""
    code = key_data(key).code
    coded_key = key if code is None else dataclasses.replace(key, bits=code.encode(key.bits), payload_kind="bits")
    verdict = verdict_from_scores(reading.scores, coded_key, reading.mode, p_threshold, reading.detail)
    verdict.p_value = float(pose_bound(verdict.p_value, reading.poses))
    verdict.marked = bool(verdict.p_value < p_threshold)
    payload, confirmed, corrected = confirm_with(reading.scores, key, code)
    confirmed = confirmed and verdict.marked
    coded_read, coded_key_bits = verdict.bits, "".join(map(str, coded_key.bits.tolist()))
    verdict.bits = "".join(map(str, payload.tolist()))
    verdict.payload = decode_text(payload) if confirmed and key.payload_kind == "text" else None
    verdict.payload_confirmed = confirmed
    verdict.detail = dataclasses.replace(
        reading.detail,
        poses_paid=reading.poses,
        payload_code=code.name if code is not None else "none",
        corrected=corrected,
        coded_bits=coded_read,
        coded_key_bits=coded_key_bits,
    )  # read, and the key's
    verdict.places, verdict.place_bits = reading.places, reading.place_bits
    return verdict


def _same_vertices(X: np.ndarray, F: np.ndarray, s: RobustKeyData, key: WatermarkKey) -> bool:
    """True when the suspect X (n, 3), F (m, 3) has the marked mesh's vertices in their order (noise,
    smoothing and quantization keep it): its sample vertices lie close to their stored places, or near them
    and the faces are the marked mesh's. A copy re-numbered along its faces (an STL re-export) puts each
    index near its old place without keeping it: its faces tell."""
    if len(X) != key.n_vertices:
        return False
    sm = s.samples
    dist = np.linalg.norm(X[sm.vertex] - _sample_places(s), axis=2)[sm.mask]
    if not len(dist):
        return False
    median = np.median(dist)
    if median < INDEX_CLOSE * s.frame.scale:
        return True
    kept = {key.faces_fingerprint, key.pm_faces_fingerprint} - {""}
    return bool(median < INDEX_MATCH * s.frame.scale and face_fingerprint(F) in kept)


def _sample_places(s: RobustKeyData) -> np.ndarray:
    """Each sample's place on the unmarked surface, in the key's frame, (sites, K, 3)."""
    sm = s.samples
    t1, t2 = s.t1[:, None, :], s.t2[:, None, :]
    P, N = s.origin[:, None, :], s.normal[:, None, :]
    return P + sm.u[..., None] * t1 + sm.v[..., None] * t2 + sm.h[..., None] * N


def _index_fit(X: np.ndarray, s: RobustKeyData) -> Optional[tuple[np.ndarray, float, np.ndarray]]:
    """The similarity (R, k, t), mirror images included, that best fits the stored places of the sample vertices to X's
    (X[vertex] ~ k place R^T + t), or None when those vertices collapsed to a point. With thousands of
    known pairs this is far tighter than surface ICP, whose error at high noise otherwise tilts every
    site (the bumps are sign-balanced, so they do not pull the fit). The noiseless stored places are
    fitted to the suspect, not the other way: noise in the points fitted from shrinks the
    least-squares scale (regression dilution; 1 % at noise 0.05 of the size, which moves far sites by
    bump heights)."""
    sm = s.samples
    R, k, t = similarity_fit(_sample_places(s)[sm.mask], X[sm.vertex[sm.mask]], mirror=True)
    return (R, k, t) if np.isfinite(k) and k > 1e-12 else None


def _refined(
    X: np.ndarray, s: RobustKeyData, back: Callable[[np.ndarray], np.ndarray]
) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray], bool]:
    """X (n, 3) mapped into the key's frame by ``_index_fit``, ``back`` (key's frame -> the suspect,
    through X) extended by that fit, and whether the fit mirrors."""
    fit = _index_fit(X, s)
    if fit is None:
        return X, back, False
    R, k, t = fit
    return (X - t) @ R / k, lambda P: back(k * P @ R.T + t), bool(np.linalg.det(R) < 0)


def _refine_by_index(X: np.ndarray, s: RobustKeyData) -> np.ndarray:
    """X (n, 3) in the key's frame by the similarity fit of its sample vertices (``_index_fit``)."""
    return _refined(X, s, _identity)[0]


def _in_key_frame(V: np.ndarray, s: RobustKeyData, key: WatermarkKey) -> bool:
    """True when site vertices sit exactly (float32 precision) at one of their two possible marked
    places, P +- A N: the marked mesh itself, one of its levels of detail, or a copy that kept part
    of it in place (a crop, a light simplification), in its own frame. IN_PLACE_SHARE of the sites
    is enough (a chance coincidence at 1e-6 of the size is impossible); registration would only blur
    such a copy (it is accurate to ~0.1 % only)."""
    use = np.flatnonzero(s.usable | s.centre_ok)
    if len(use) == 0:
        return False
    tol = 1e-6 * key.bbox_diagonal
    h, off = _centre_heights(V, s.origin[use], s.normal[use], 2.0 * s.amplitude)
    exact = (off <= tol) & (np.abs(np.abs(h) - s.amplitude) <= tol)
    return bool(exact.sum() >= max(3, IN_PLACE_SHARE * len(use)))
