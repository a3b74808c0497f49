"""The robust scheme's fields on the surface: the site frame, the bump profile, the swirl, what
marking moved each sample vertex (templates), and where a line through a sample crosses a surface.

Shapes: S sites, K samples per site (padded); u, v : (S, K) tangent-plane offsets in the site frame.
"""

from __future__ import annotations

import numpy as np

from ...adjacency import unique_values
from ...features import squared_norms
from ...spatial import pairs_within

SWIRL_PEAK = 0.2862  # max of (rho / r) (1 - (rho / r)^2)^2: the swirl field peaks at 1
OUTER = 1.6  # samples reach OUTER * r from the site (the annulus beyond r is not moved)


def tangent_frames(N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents per unit normal N (k, 3), a deterministic function of the normal; NaN for a
    zero normal (a site whose disc's normals cancel: its readings are NaN, and it is left out)."""
    helper = np.eye(3)[np.argmin(np.abs(N), axis=1)]
    t1 = np.cross(N, helper)
    with np.errstate(invalid="ignore"):
        t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(N, t1)


def profile(u: np.ndarray, v: np.ndarray, r: float) -> np.ndarray:
    """The bump's shape at tangent-plane offset (u, v): (1 - (d/r)^2)^2 inside r, 0 outside."""
    q = np.minimum((u * u + v * v) / (r * r), 1.0)
    return (1.0 - q) ** 2


def swirl(u: np.ndarray, v: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """The in-surface field at (u, v), (t1, t2) components: a rotation about the site, zero at the
    site and beyond r, peaking at 1 (orthogonal to a shift and to a shrink of the neighbourhood)."""
    w = profile(u, v, r) / (r * SWIRL_PEAK)
    return -v * w, u * w


def index_templates(sm, r: float, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """What marking moved each sample vertex, per unit of bump amplitude: along the site normal
    (S, K) and in the site's tangent plane, (t1, t2) components (S, K, 2), per unit of swirl. The
    swirl is embedded off each vertex's own normal, so on a curved patch part of it runs along the
    site normal; ``ratio`` is swirl / bump amplitude. Without stored normals: the plain fields. (A
    site left without a swirl has too few samples to read one, and its swirl's normal part is
    negligible: its bump still reads its sign to 1e-5 on the marked Venus head.)"""
    p = profile(sm.u, sm.v, r)
    gu, gv = swirl(sm.u, sm.v, r)
    if sm.normal_tt is not None:
        a, b = sm.normal_tt[..., 0], sm.normal_tt[..., 1]
        k = gu * a + gv * b  # the field's part along the vertex normal, removed by the embedder
        p = p - ratio * k * np.sqrt(np.maximum(1.0 - a * a - b * b, 0.0))
        gu, gv = gu - k * a, gv - k * b
    return p * sm.mask, np.stack([gu, gv], axis=2) * sm.mask[..., None]


def heights(V, F, origin, normal, t1, t2, uv, reach: float, expect: np.ndarray) -> np.ndarray:
    """Height along ``normal`` of the surface over each sample point (S, K) (NaN: no surface).

    Sample k of site s is the line origin[s] + u t1[s] + v t2[s] + h normal[s]; every triangle
    within ``reach`` of the site is projected into the site frame, and of the crossings the one
    nearest to either expected height ``expect`` (S, K, 2) is kept (either face orientation, so
    flipped copies still read). Padding samples have u, v far outside any face. A site whose lines would
    each meet MAX_FACES_PER_LINE candidate faces (a crumpled copy) gets none.
    """
    S, K = uv.shape[:2]
    out = np.full((S, K), np.nan)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    if len(F) == 0 or S == 0:
        return out
    tri = np.take(V, F, axis=0)  # (np.take: as V[F], faster)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cen = (a + b + c) / 3.0  # (reductions over axes of 3 are slow in numpy: corner by corner)
    rad = np.sqrt(np.maximum(np.maximum(squared_norms(a - cen), squared_norms(b - cen)), squared_norms(c - cen)))
    # site-face pairs: the face's bounding sphere meets the ball of radius reach around the site
    fi, si, _ = pairs_within(cen, origin, reach + rad, by_j=True)  # by site, then face
    # the samples in order of (site, u): the samples inside a face projected into its site's frame
    # are in the run of that order between the face's smallest and largest u (sites ``band`` apart)
    band = 3.0 * (reach + 2.0 * float(rad.max()))
    key = (np.arange(S)[:, None] * band + uv[..., 0]).ravel()
    by_u = np.argsort(key, kind="stable")
    key = key[by_u]
    expect = expect.reshape(S * K, 2)
    found, held = [], 0
    for c in _site_chunks(si, PAIR_CHUNK):
        for got in _crossings(
            np.take(tri, fi[c], axis=0) - origin[si[c]][:, None, :], si[c], t1, t2, normal, uv, key, by_u, band, reach
        ):
            found.append(got)
            held += len(got[0])
            if held > CROSSINGS_HELD:  # a crumpled copy crosses each line many times: keep the nearest so far
                found = [_nearest_crossings(*(np.concatenate(x) for x in zip(*found)), expect)]
                held = len(found[0][0])
    if not found:
        return out
    slot, h, _ = _nearest_crossings(*(np.concatenate(x) for x in zip(*found)), expect)
    out.ravel()[slot] = h
    return out


PAIR_CHUNK = 1 << 16  # (site, face) pairs projected at once: bounds the memory of ``heights``
CROSSINGS_HELD = 1 << 22  # crossings held before all but the nearest of each line are dropped


def _nearest_crossings(
    slot: np.ndarray, h: np.ndarray, back: np.ndarray, expect: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of the crossings (slot, height, back-facing) (k,) of the sample lines, each line's nearest to either
    of its expected heights ``expect`` (S * K, 2), a front-facing one before a back-facing one at the same
    distance, the first of equals: (slot, height, back) by slot. Why: a line may cross the surface more than
    once (folds, thin parts, coarse levels of detail, copies whose faces were flipped). Taken from any
    leading part of the crossings, then from those and the rest, it keeps the same crossings as from all."""
    e = np.take(expect, slot, axis=0)
    order = np.lexsort((back, np.minimum(np.abs(h - e[:, 0]), np.abs(h - e[:, 1])), slot))
    slot, h, back = slot[order], h[order], back[order]
    first = np.r_[True, slot[1:] != slot[:-1]] if len(slot) else np.zeros(0, bool)
    return slot[first], h[first], back[first]


def _site_chunks(si: np.ndarray, size: int) -> list[slice]:
    """Runs of about ``size`` of the pairs, sorted by site si (p,), each holding whole sites (a site with
    more pairs is a run of its own)."""
    cut = unique_values(np.r_[np.searchsorted(si, np.take(si, np.arange(0, len(si), size))), len(si)])
    return [slice(a, b) for a, b in zip(cut[:-1], cut[1:])]


def _crossings(rel, si, t1, t2, normal, uv, key, by_u, band: float, reach: float):
    """Where the sample lines of pairs' sites cross the pairs' faces: (slot = site * K + sample,
    height, back-facing), in the order of the pairs, yielded for runs of pairs. rel (p, 3, 3): the
    faces' corners about their site; si (p,): the site; key, by_u: the samples sorted by site, then u
    (``heights``)."""
    x = np.einsum("pvj,pj->pv", rel, np.take(t1, si, axis=0))  # (np.take: as t1[si], faster)
    y = np.einsum("pvj,pj->pv", rel, np.take(t2, si, axis=0))
    z = np.einsum("pvj,pj->pv", rel, np.take(normal, si, axis=0))
    det = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    ok = np.abs(det) > 1e-30 * reach * reach  # a face of no area seen along the line (any unit of length)
    si, x, y, z, det = si[ok], x[ok], y[ok], z[ok], det[ok]
    # candidates: the samples whose u is within the face's u range (widened far beyond the
    # tolerance below, so that no crossing is missed)
    lo_u = np.minimum(np.minimum(x[:, 0], x[:, 1]), x[:, 2])
    hi_u = np.maximum(np.maximum(x[:, 0], x[:, 1]), x[:, 2])
    margin = 1e-6 * (hi_u - lo_u) + 1e-9 * reach + 1e-14 * (si + 1) * band  # (+ the keys' rounding)
    lo = np.searchsorted(key, si * band + lo_u - margin, "left")
    n = np.searchsorted(key, si * band + hi_u + margin, "right") - lo
    # a site whose lines would each be tested against MAX_FACES_PER_LINE faces or more is not read (its
    # heights stay NaN): a crumpled copy, whose faces span many samples (an 11,000-vertex mesh with noise
    # of a tenth of its size: 10,000-12,000 per line, half an hour of work; at most 65 measured on the
    # bunny and Igea marked, Loop-subdivided or 90 % simplified)
    crowded = np.bincount(si, weights=n, minlength=uv.shape[0]) >= MAX_FACES_PER_LINE * uv.shape[1]
    if crowded.any():
        keep = np.flatnonzero(~np.take(crowded, si))
        si, x, y, z, det, lo, n = (np.take(a, keep, axis=0) for a in (si, x, y, z, det, lo, n))
    # the pairs in runs of at most about CANDIDATE_CHUNK candidates (a crumpled copy's faces span many
    # samples each: 86 million candidates in one chunk of pairs, 24 GB, on that mesh); the same crossings
    # in the same order
    start = np.cumsum(n) - n
    run = start // CANDIDATE_CHUNK
    cut = np.flatnonzero(np.r_[True, run[1:] != run[:-1], True])
    for a, b in zip(cut[:-1], cut[1:]):
        yield _inside(x[a:b], y[a:b], z[a:b], det[a:b], si[a:b], lo[a:b], n[a:b], uv, by_u)


CANDIDATE_CHUNK = 1 << 20  # (pair, sample) candidates tested at once: bounds the memory of ``heights``
MAX_FACES_PER_LINE = 1000  # a site whose sample lines meet this many candidate faces each is not read


def _inside(x, y, z, det, si, lo, n, uv, by_u):
    """The crossings of the pairs' faces (their corners x, y, z (p, 3) in the site frames, det (p,)) with the
    sample lines of their sites si (p,) among each pair's n (p,) candidates from ``lo`` (p,) in ``by_u``:
    (slot, height, back-facing), in the order of the pairs (``_crossings``)."""
    K = uv.shape[1]
    pk = np.repeat(np.arange(len(si)), n)
    kk = np.take(by_u, np.arange(len(pk)) - np.repeat(np.cumsum(n) - n - lo, n)) % K
    q = np.take(uv.reshape(-1, 2), np.take(si, pk) * K + kk, axis=0)  # (np.take: as uv[si[pk], kk])
    xp, yp, dp = np.take(x, pk, axis=0), np.take(y, pk, axis=0), np.take(det, pk)
    dx, dy = q[:, 0] - xp[:, 0], q[:, 1] - yp[:, 0]
    l1 = (dx * (yp[:, 2] - yp[:, 0]) - dy * (xp[:, 2] - xp[:, 0])) / dp
    l2 = ((xp[:, 1] - xp[:, 0]) * dy - (yp[:, 1] - yp[:, 0]) * dx) / dp
    l0 = 1.0 - l1 - l2
    tol = -1e-7  # a line through a vertex must hit one of its faces despite rounding
    inside = (l0 >= tol) & (l1 >= tol) & (l2 >= tol)
    pk, kk = pk[inside], kk[inside]
    h = l0[inside] * z[pk, 0] + l1[inside] * z[pk, 1] + l2[inside] * z[pk, 2]
    return si[pk] * K + kk, h, det[pk] < 0
