"""A robust watermarking scheme on the progressive mesh (key.scheme == "robust").

Why. The paper's scheme reads each bit from one vertex against its 1-ring: any change of
connectivity (simplification, subdivision, re-export that re-orders) or a rotation loses it.
Here every bit is spread over several *sites*, each a smooth bump read geometrically, after
registering the suspect to the marked mesh.

Embedding.
- Sites: SOM-suitable vertices (``pmwm.carriers``) picked by seeded farthest-point sampling,
  ``sites_per_bit`` per payload bit, assigned to bits so that each bit's sites are spread around the
  shape (pairs of roughly opposite sites): a plane cutting off half the mesh leaves most bits a site.
- Each site c with unit normal n (smoothed over its disc) gets a bump along n: vertex v at distance d
  < r moves by s * A * (1 - (d/r)^2)^2 * n, with s = +-1 its chip (keyed, balanced within the bit)
  times the bit sign (payload XOR keyed sequence, as in the paper scheme). r is ``radius_edges`` mean
  edge lengths; A is ``strength`` * ``AMPLITUDE_PER_STRENGTH`` mean edge lengths.
- Stencil: the site vertex and ``RING`` vertices near distance 1.3 r at keyed angles (outside the
  bump). All stencil vertices are protected in the progressive mesh, so they exist, unmoved, at
  every level of detail from the base mesh up.

Reading (on the registered suspect, ``pmwm.register``). Heights along n are measured where the
lines through the stencil points (in the site's tangent plane, stored in the key) cross the
suspect surface. The site value is the centre height minus the ring's plane at the centre. On any
level of detail the lines pass through the protected vertices themselves, so the value is the full
mesh's value exactly. The key stores each site's value on the unmarked mesh (a number per site,
not the mesh), so the soft value is (value - stored) / (expected shift): +-1 when intact, whatever
the shape's natural curvature there; no distortion is spent on overriding the shape.
Where a line crosses the surface more than once, the crossing nearest the expected height is
used (module function ``soft_values``). A bit is the sign of the chip-weighted sum of its sites'
soft values, each clipped to +-SOFT_CLIP (soft-decision decoding of a repetition code; the clip
keeps one garbled site from outvoting the others); a bit with no readable site is an erasure and
gets a keyed coin flip, so the binomial p-value of ``watermark._verdict`` stays exact.

Not blind in the strict sense: the key holds, per site, a few numbers about the unmarked and
the marked surface there, and 3,000 samples of the marked surface for registration (a key of
~0.6 MB for 64 bits); never the mesh itself.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from . import metrics
from .adjacency import build_adjacency
from .carriers import eligible_carriers, select_carriers
from .errors import KeyFileError, PayloadError
from .key import WatermarkKey, derive_seed, make_secret
from .progressive import build_progressive_mesh
from .register import register, surface_frame
from .watermark import (EmbedOptions, EmbedResult, Progress, Verdict, _verdict, check_mesh,
                        mean_edge_length, payload_bits)

SITES_PER_BIT = 6
RADIUS_EDGES = 2.5  # bump radius in mean edge lengths
AMPLITUDE_PER_STRENGTH = 0.1  # bump amplitude per unit of strength, in mean edge lengths
RING = 3  # ring stencil points per site
RING_DISTANCE = 1.3  # ring stencil distance / r
SOFT_CLIP = 1.5  # soft values are clipped to +-SOFT_CLIP before a bit's sites are summed
REF_POINTS = 3000  # registration samples stored in the key
SCHEME = "robust"
EXTRA_VERSION = 1


# --------------------------------------------------------------------------- geometry helpers


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (zero for isolated vertices)."""
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    vn = np.stack([np.bincount(F.ravel(), weights=np.repeat(fn[:, a], 3), minlength=len(V))
                   for a in range(3)], axis=1)
    return vn / np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]


def tangent_frames(N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents per unit normal, a deterministic function of the normal."""
    helper = np.eye(3)[np.argmin(np.abs(N), axis=1)]
    t1 = np.cross(N, helper)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(N, t1)


def _pairs_within(P: np.ndarray, Q: np.ndarray, radius, budget: int = 1 << 23):
    """(i, j, distance) for every point P[i] and Q[j] closer than radius (scalar or per P)."""
    rad = np.broadcast_to(np.asarray(radius, np.float64), (len(P),))
    qq = np.einsum("ij,ij->i", Q, Q)
    out_i, out_j, out_d = [], [], []
    step = max(1, budget // max(len(Q), 1))
    for s in range(0, len(P), step):
        p = P[s:s + step]
        d2 = qq[None, :] - 2.0 * p @ Q.T + np.einsum("ij,ij->i", p, p)[:, None]
        i, j = np.nonzero(d2 < (rad[s:s + step] ** 2)[:, None])
        out_i.append(i + s)
        out_j.append(j)
        out_d.append(np.sqrt(np.maximum(d2[i, j], 0.0)))
    return np.concatenate(out_i), np.concatenate(out_j), np.concatenate(out_d)


def _min_spacing(P: np.ndarray, chunk: int = 1024) -> float:
    """Smallest distance between two distinct points of P (inf for fewer than two)."""
    best = np.inf
    for s in range(0, len(P), chunk):
        d2 = ((P[s:s + chunk, None, :] - P[None, :, :]) ** 2).sum(axis=2)
        d2[np.arange(len(d2)), np.arange(s, s + len(d2))] = np.inf
        best = min(best, float(d2.min()))
    return float(np.sqrt(best))


def heights(V, F, origin, normal, t1, t2, uv, reach: float, expect: Optional[np.ndarray] = None) -> np.ndarray:
    """Height along ``normal`` of the surface over each stencil point (S, K) (NaN: no surface).

    Stencil point k of site s is the line origin[s] + u t1[s] + v t2[s] + h normal[s]; every
    triangle within ``reach`` of the site is projected into the site frame and the crossing with
    the smallest |h| is kept (either face orientation, so flipped copies still read). With
    ``expect`` (S, K, 2), the crossing nearest to either expected height is kept instead.
    """
    S, K = uv.shape[:2]
    out = np.full((S, K), np.nan)
    F = np.asarray(F, np.int64)
    if len(F) == 0 or S == 0:
        return out
    tri = V[F]
    cen = tri.mean(axis=1)
    rad = np.sqrt(((tri - cen[:, None, :]) ** 2).sum(axis=2).max(axis=1))
    # site-face pairs: the face's bounding sphere meets the ball of radius reach around the site
    si, fi, d = _pairs_within(origin, cen, reach + rad.max())
    keep = d < reach + rad[fi]
    si, fi = si[keep], fi[keep]
    if len(si) == 0:
        return out
    rel = tri[fi] - origin[si][:, None, :]  # (p, 3, 3)
    x = np.einsum("pvj,pj->pv", rel, t1[si])
    y = np.einsum("pvj,pj->pv", rel, t2[si])
    z = np.einsum("pvj,pj->pv", rel, normal[si])
    det = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    ok = np.abs(det) > 1e-30
    si, x, y, z, det = si[ok], x[ok], y[ok], z[ok], det[ok]
    P = len(si)
    pk = np.repeat(np.arange(P), K)
    kk = np.tile(np.arange(K), P)
    qu, qv = uv[si[pk], kk, 0], uv[si[pk], kk, 1]
    dx, dy = qu - x[pk, 0], qv - y[pk, 0]
    l1 = (dx * (y[pk, 2] - y[pk, 0]) - dy * (x[pk, 2] - x[pk, 0])) / det[pk]
    l2 = ((x[pk, 1] - x[pk, 0]) * dy - (y[pk, 1] - y[pk, 0]) * dx) / det[pk]
    l0 = 1.0 - l1 - l2
    tol = -1e-7  # a line through a vertex must hit one of its faces despite rounding
    inside = (l0 >= tol) & (l1 >= tol) & (l2 >= tol)
    pk, kk = pk[inside], kk[inside]
    h = l0[inside] * z[pk, 0] + l1[inside] * z[pk, 1] + l2[inside] * z[pk, 2]
    slot = si[pk] * K + kk
    if len(slot) == 0:
        return out
    # a line may cross the surface more than once (folds, thin parts, coarse levels of detail):
    # take the front-facing crossing (face normal along the site normal) nearest the site, and a
    # back-facing one only where there is none (copies whose faces were flipped)
    back = det[pk] < 0
    if expect is None:
        order = np.lexsort((np.abs(h), back, slot))
    else:
        e = expect.reshape(S * K, 2)[slot]
        order = np.lexsort((back, np.minimum(np.abs(h - e[:, 0]), np.abs(h - e[:, 1])), slot))
    slot, h = slot[order], h[order]
    first = np.r_[True, slot[1:] != slot[:-1]]
    out.ravel()[slot[first]] = h[first]
    return out


def site_values(Hs: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Centre height minus the ring's least-squares plane under the centre, per site (NaN if unreadable)."""
    ring_uv = uv[:, 1:, :]
    A = np.concatenate([np.ones(ring_uv.shape[:2] + (1,)), ring_uv], axis=2)  # (S, K, 3)
    # plane value at (0, 0) = first coefficient = e0^T (A^T A)^-1 A^T h_ring
    AtA = np.einsum("ski,skj->sij", A, A)
    scale = np.einsum("sii->s", AtA)
    bad = ~(np.abs(np.linalg.det(AtA)) > 1e-9 * np.maximum(scale, 1e-300) ** 3)  # ring on a line
    AtA[bad] = np.eye(3)
    coef = np.linalg.solve(AtA, np.einsum("ski,sk->si", A, np.nan_to_num(Hs[:, 1:]))[..., None])[..., 0]
    val = Hs[:, 0] - (coef[:, 0] + coef[:, 1] * uv[:, 0, 0] + coef[:, 2] * uv[:, 0, 1])
    return np.where(np.isnan(Hs).any(axis=1) | bad, np.nan, val)


# --------------------------------------------------------------------------- embedding


def _assign_bits(P: np.ndarray, n_bits: int, per_bit: int, seed: int) -> np.ndarray:
    """Bit index of each site: pairs of roughly opposite sites (about the centroid) go to the
    same bit, pairs are dealt to bits in a keyed order, so each bit has sites on both sides."""
    n = len(P)
    rng = np.random.default_rng(seed)
    u = P - P.mean(axis=0)
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-300)[:, None]
    free = np.ones(n, bool)
    pairs = []
    for i in rng.permutation(n):  # one iteration per site (hundreds), not per vertex
        if not free[i]:
            continue
        free[i] = False
        cand = np.flatnonzero(free)
        if len(cand) == 0:
            pairs.append([i])
            break
        j = cand[np.argmin(u[cand] @ u[i])]
        free[j] = False
        pairs.append([i, j])
    bit = np.empty(n, np.int64)
    slots = np.repeat(np.arange(n_bits), per_bit)  # per_bit is even, so pairs fill the slots
    pos = 0
    for pair in (pairs[k] for k in rng.permutation(len(pairs))):
        for i in pair:
            bit[i] = slots[pos]
            pos += 1
    return bit


def robust_embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None,
                 sites_per_bit: int = SITES_PER_BIT, radius_edges: float = RADIUS_EDGES) -> EmbedResult:
    """Watermark a mesh with the robust scheme (module docstring); same options/result as ``embed``."""
    opts = options or EmbedOptions()
    if not (opts.strength > 0 and np.isfinite(opts.strength)):
        raise PayloadError(f"strength must be a positive number, got {opts.strength}")
    if not (0 < opts.base_ratio <= 1):
        raise PayloadError(f"base ratio must be in (0, 1], got {opts.base_ratio}")
    per_bit = max(2, 2 * (int(sites_per_bit) // 2))
    V, F = check_mesh(vertices, faces)
    report = progress or (lambda f, m: None)
    secret = make_secret(opts.seed)
    bits, kind = payload_bits(opts, secret)
    nb = len(bits)
    report(0.0, "analysing the mesh")
    adj = build_adjacency(F, len(V))
    eligible = eligible_carriers(V, adj, seed=derive_seed(secret, "som"))
    while True:  # fewer sites per bit on small meshes, down to 2
        try:
            sites = select_carriers(V, adj, eligible, nb * per_bit, seed=derive_seed(secret, "robust-sites"))
            break
        except PayloadError:
            if per_bit <= 2:
                raise
            per_bit -= 2
    report(0.1, f"{len(sites)} sites chosen")
    edge = mean_edge_length(V, adj)
    P = V[sites]
    # bumps and rings must not overlap: r + RING_DISTANCE * r below the closest site spacing
    dmin = _min_spacing(P)
    # (on small meshes they may overlap a little; the stored per-site shift then includes the
    # neighbours' share, and sites whose shift is not clearly their own sign are left out)
    r = max(min(radius_edges * edge, 0.95 * dmin / (1.0 + RING_DISTANCE + 0.3)), min(1.5, radius_edges) * edge)
    A = opts.strength * AMPLITUDE_PER_STRENGTH * edge

    vn = vertex_normals(V, F)
    si, vi, d = _pairs_within(P, V, np.full(len(P), (RING_DISTANCE + 0.3) * r))
    # site normal: mean vertex normal over the disc (same side as the site's own normal)
    facing = np.einsum("ij,ij->i", vn[vi], vn[sites][si]) > 0.3
    disc = facing & (d < r)
    N = np.stack([np.bincount(si[disc], weights=vn[vi[disc], a], minlength=len(P)) for a in range(3)], 1)
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    t1, t2 = tangent_frames(N)

    # keyed bit assignment, chips and signs
    key_stub = WatermarkKey(secret=secret, bits=bits, payload_kind=kind, strength=float(opts.strength),
                            carrier_index=sites[:nb], carrier_pm_index=sites[:nb], carrier_position=P[:nb],
                            n_vertices=len(V), n_faces=len(F), mean_edge=1.0, bbox_diagonal=1.0)
    w = bits ^ key_stub.stream("scramble", nb)
    bit_of = _assign_bits(P, nb, per_bit, derive_seed(secret, "robust-assign"))
    rng = np.random.default_rng(derive_seed(secret, "robust-chips"))
    order = np.lexsort((rng.random(len(P)), bit_of))  # each bit's sites in a keyed order
    rank = np.arange(len(P)) - np.searchsorted(bit_of[order], bit_of[order])
    chip = np.empty(len(P))
    chip[order] = np.where(rank % 2 == 0, 1.0, -1.0)  # balanced: a global bias cancels in a bit
    sign = chip * np.where(w[bit_of] == 1, 1.0, -1.0)

    # ring stencil vertices: nearest to RING_DISTANCE * r at keyed angles, outside the bump
    rel = V[vi] - P[si]
    phi = np.arctan2(np.einsum("ij,ij->i", rel, t2[si]), np.einsum("ij,ij->i", rel, t1[si]))
    theta0 = np.random.default_rng(derive_seed(secret, "robust-angles")).uniform(0, 2 * np.pi, len(P))
    # ring vertices where the surface is a height field over the site's tangent plane, so the
    # stencil lines cross it once, cleanly, at every level of detail
    ring_ok = (np.einsum("ij,ij->i", vn[vi], N[si]) > 0.8) & (d > 1.05 * r)
    ring = np.full((len(P), RING), -1, np.int64)
    for k in range(RING):  # RING (3) iterations
        target = theta0 + 2 * np.pi * k / RING
        dphi = np.abs(np.angle(np.exp(1j * (phi - target[si]))))
        score = dphi + np.abs(d / r - RING_DISTANCE)
        score[~ring_ok] = np.inf
        o = np.lexsort((score, si))
        first = o[np.r_[True, si[o][1:] != si[o][:-1]]]
        good = np.isfinite(score[first])
        ring[si[first][good], k] = vi[first][good]
    usable = (ring >= 0).all(axis=1)

    # the bumps
    bump = disc & usable[si]
    wgt = (1.0 - (d[bump] / r) ** 2) ** 2
    D = np.zeros_like(V)
    np.add.at(D, vi[bump], (sign[si[bump]] * A * wgt)[:, None] * N[si[bump]])
    marked = (V + D).astype(np.float32).astype(np.float64)

    # stencils in each site's tangent frame, from the marked positions
    stencil = np.concatenate([sites[:, None], np.where(ring >= 0, ring, sites[:, None])], axis=1)
    relm = marked[stencil] - P[:, None, :]
    uv = np.stack([np.einsum("skj,sj->sk", relm, t1), np.einsum("skj,sj->sk", relm, t2)], axis=2)
    # (the centre's own uv is ~0 but kept exact: the line must pass through the vertex itself)
    reach = (RING_DISTANCE + 0.5) * r
    # read at the stencil vertices' own crossings (a line may also cross other parts nearby)
    Hu = np.einsum("skj,sj->sk", V[stencil] - P[:, None, :], N)[..., None]
    Hm = np.einsum("skj,sj->sk", relm, N)[..., None]
    ref = site_values(heights(V, F, P, N, t1, t2, uv, reach, expect=np.concatenate([Hu, Hu], 2)), uv)
    H_marked = heights(marked, F, P, N, t1, t2, uv, reach, expect=np.concatenate([Hm, Hm], 2))
    after = site_values(H_marked, uv)
    gain = (after - ref) * sign  # the shift each site was given, ~A
    usable &= np.isfinite(ref) & np.isfinite(after) & (gain > 0.25 * A)
    report(0.2, "sites marked")

    protected = np.zeros(len(V), bool)
    protected[stencil[usable].ravel()] = True
    base = max(int(round(opts.base_ratio * len(V))), 4)

    def pm_progress(f: float, msg: str) -> None:
        report(0.25 + 0.7 * f, msg)

    pm, _ = build_progressive_mesh(marked, F, base_vertices=base, protected=protected,
                                   progress=pm_progress, adjacency=adj)
    pm_of = np.empty(len(V), np.int64)
    pm_of[pm.vertex_order] = np.arange(len(V))
    first_site = np.array([np.flatnonzero(bit_of == b)[0] for b in range(nb)])
    extra = {
        "robust_version": EXTRA_VERSION,
        "radius": r,
        "amplitude": A,
        "reach": reach,
        "site_bit": bit_of.tolist(),
        "site_chip": chip.astype(int).tolist(),
        "site_usable": usable.astype(int).tolist(),
        # full precision: the stencil lines must pass exactly through the protected vertices
        "site_origin": P.tolist(),
        "site_normal": N.tolist(),
        "site_uv": uv.tolist(),
        "site_ref": np.nan_to_num(ref).tolist(),
        "site_gain": np.where(usable, gain, 0.0).tolist(),
        "site_ring_height": np.nan_to_num(H_marked[:, 1:]).tolist(),
        "frame": surface_frame(marked, F, REF_POINTS, derive_seed(secret, "robust-frame") % (2**31)),
    }
    key = WatermarkKey(
        secret=secret, bits=bits, payload_kind=kind, strength=float(opts.strength),
        carrier_index=sites[first_site], carrier_pm_index=pm_of[sites[first_site]],
        carrier_position=marked[sites[first_site]].copy(), n_vertices=len(V), n_faces=len(F),
        mean_edge=mean_edge_length(marked, adj), bbox_diagonal=float(np.linalg.norm(V.max(0) - V.min(0))),
        scheme=SCHEME, extra=extra,
    )
    report(1.0, "done")
    return EmbedResult(vertices=marked, faces=F, pm=pm, key=key, carriers=sites, bits=bits,
                       vsnr_db=metrics.vsnr(V, marked), rmse=metrics.vertex_rmse(V, marked))


# --------------------------------------------------------------------------- reading


def _site_arrays(key: WatermarkKey) -> dict:
    x = key.extra
    try:
        out = {
            "bit": np.asarray(x["site_bit"], np.int64),
            "chip": np.asarray(x["site_chip"], np.float64),
            "usable": np.asarray(x["site_usable"], bool),
            "origin": np.asarray(x["site_origin"], np.float64).reshape(-1, 3),
            "normal": np.asarray(x["site_normal"], np.float64).reshape(-1, 3),
            "ref": np.asarray(x["site_ref"], np.float64),
            "ring_h": np.asarray(x["site_ring_height"], np.float64).reshape(len(x["site_bit"]), -1),
            "gain": np.asarray(x["site_gain"], np.float64),
            "reach": float(x["reach"]),
            "frame": x["frame"],
        }
        out["uv"] = np.asarray(x["site_uv"], np.float64).reshape(len(out["bit"]), -1, 2)
        fr = out["frame"]
        shapes = {"points": (-1, 3), "normals": (-1, 3), "centroid": (3,), "axes": (3, 3)}
        out["frame"] = {k: np.asarray(fr[k], np.float64).reshape(shp) for k, shp in shapes.items()}
        out["frame"]["scale"] = float(fr["scale"])
        if not all(np.all(np.isfinite(v)) for v in out["frame"].values()) or out["frame"]["scale"] <= 0 \
                or len(out["frame"]["points"]) != len(out["frame"]["normals"]) or len(out["frame"]["points"]) < 3:
            raise ValueError("registration frame")
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise KeyFileError(f"the robust key lacks or garbles its site data ({exc}); it is damaged") from None
    n = len(out["bit"])
    if n == 0 or any(len(out[k]) != n for k in ("chip", "usable", "origin", "normal", "ref", "gain")) \
            or out["bit"].min() < 0 or out["bit"].max() >= key.n_bits:
        raise KeyFileError("the robust key's site data are inconsistent; it is damaged")
    return out


def soft_values(V: np.ndarray, F: np.ndarray, key: WatermarkKey) -> np.ndarray:
    """Soft value per site (~ +-1 when intact, NaN when unreadable) on a mesh in the key's frame.

    Where a stencil line crosses the surface several times (thin parts, or a coarse level of
    detail folding over a dent), the crossing nearest to the expected height is taken: for the
    ring, its marked height stored in the key (outside the bumps, so it says nothing of the bits);
    for the centre, either possible marked height (ring plane + stored value +- shift), which is
    symmetric in the sign and so cannot bias a bit.
    """
    s = _site_arrays(key)
    t1, t2 = tangent_frames(s["normal"])
    uv = s["uv"]
    ring_h = s["ring_h"][:, :, None]
    ring = heights(V, F, s["origin"], s["normal"], t1, t2, uv[:, 1:], s["reach"],
                   expect=np.concatenate([ring_h, ring_h], axis=2))
    plane0 = -site_values(np.concatenate([np.zeros((len(uv), 1)), ring], axis=1), uv)
    centre = (plane0 + s["ref"])[:, None] + np.stack([s["gain"], -s["gain"]], axis=1)
    expect = np.nan_to_num(centre)[:, None, :]
    H0 = heights(V, F, s["origin"], s["normal"], t1, t2, uv[:, :1], s["reach"], expect=expect)
    val = site_values(np.concatenate([H0, ring], axis=1), uv)
    soft = (val - s["ref"]) / np.where(s["gain"] > 0, s["gain"], 1.0)
    return np.where(s["usable"], soft, np.nan)


def bit_scores(soft: np.ndarray, key: WatermarkKey) -> np.ndarray:
    """Chip-weighted sum of each bit's readable sites' soft values (0 when none is readable)."""
    s = _site_arrays(key)
    ok = np.isfinite(soft)
    # clipped: an intact site reads +-1; a site whose stencil line met another part of the shape
    # (a cropped copy, a thin part) can read anything, and must not outvote the bit's other sites
    clipped = np.clip(soft, -SOFT_CLIP, SOFT_CLIP)
    return np.bincount(s["bit"][ok], weights=(s["chip"] * clipped)[ok], minlength=key.n_bits)


def robust_verify(vertices, faces, key: WatermarkKey, p_threshold: float = 1e-6) -> Verdict:
    """Read the robust mark from a suspect mesh (any order, pose, resolution), with the key."""
    if key.scheme != SCHEME:
        raise KeyFileError(f"this key is for the {key.scheme!r} scheme, not {SCHEME!r}; use pmwm.verify")
    V, F = check_mesh(vertices, faces)
    s = _site_arrays(key)
    if _in_key_frame(V, s, key):
        X, extra = V, {"registration": "none (already in the key's frame)"}
        mode = "aligned"
    else:
        X, info = register(V, F, s["frame"])
        extra = {"registration": info.init, "residual": info.residual, "scale": info.scale}
        mode = "registered"
    soft = soft_values(X, F, key)
    verdict = _verdict(bit_scores(soft, key), key, mode, p_threshold)
    verdict.extra = {**extra, "sites_read": int(np.isfinite(soft).sum()), "sites_total": int(len(soft))}
    return verdict


def _in_key_frame(V: np.ndarray, s: dict, key: WatermarkKey) -> bool:
    """True when most site centres sit exactly (float32 precision) on a suspect vertex at one of
    their two possible marked positions: the marked mesh itself or one of its levels of detail,
    in its own frame. Registration would only blur it then (it is accurate to ~0.1 % only)."""
    from .register import _nearest

    use = np.flatnonzero(s["usable"])[:64]
    if len(use) == 0:
        return False
    o, g, n = s["origin"][use], s["gain"][use, None], s["normal"][use]
    _, d2 = _nearest(V, np.concatenate([o + g * n, o - g * n]))
    dist = np.sqrt(np.minimum(d2[: len(use)], d2[len(use):]))
    return bool(np.mean(dist <= 1e-6 * key.bbox_diagonal) > 0.5)
