"""A prototype blind carrier: keyed patches, keyed projections, rational dither modulation (experiment code).

Not a scheme: ``benchmarks/blind_carrier_experiment.py`` measures it against the pass-phrase scheme's
histogram carrier (docs/decisions/140-secure-blind-carrier-prototype.md). Everything secret derives from
the pass phrase (SHA-256 -> numpy Generator); nothing derived from the mesh is stored.

Frame (no key): the surface's area centroid, its second-moment axes (exact triangle integrals, largest
first) and its RMS radius as the unit; the embedder fixes the axes' signs by the third moments, the
reader tries all 8 sign choices (mirrors included) and pays 8 in the p-value.

Sites: keyed unit directions from the centroid; a site is the outermost hit of that ray on the surface
(a function of the surface, not of its sampling); sites whose ray meets the patch at a grazing angle are
left out (their hit jumps). A patch is the surface within ``radius`` of the site, weighted by vertex area, a
smooth window (1 - (d/r)^2)^2 and the agreement of the vertex normal with the patch normal; its tangent frame
is the patch normal and a keyed axis projected on the tangent plane.

Cells: per patch ``patterns`` keyed plane waves psi(u, v) = cos(2 pi f w.(u, v) + phi) in the tangent
coordinates (u, v in patch radii, f = ``cycles`` per radius), each made orthogonal (area weighted) to the
quadric height field 1, u, v, u^2, uv, v^2; a cell's value z is the weighted projection of the heights on
its pattern. Each bit owns M = sites * patterns / bits cells (a keyed assignment) with keyed signs:
Z = sum(s z) / sqrt(M); A = sqrt(mean(z^2) + floor^2) is the cells' own amplitude, so R = Z / A does
not change when an attack scales the band (smoothing) uniformly (rational dither modulation). R is
quantised with step ``step`` and a keyed dither: bit 0 on integers, bit 1 on half-integers. The embedder
chooses its step from the public list ``steps`` (the largest within the MRMS budget); the reader tries all.

Embedding moves vertices along their normals by the cells' windowed patterns; overlapping cells are not
orthogonal, so the coefficients come from a least-energy solve through the cells' cross gains, and the whole
mesh (frame, sites, cells) is read again ``rounds`` times. Word: payload bits and keyed check bits; the p-value
is a union bound over sign choices, steps and the Chase candidates of the reading.
"""

from __future__ import annotations

import hashlib
import itertools
from dataclasses import dataclass, replace

import numpy as np

from pmwm.features import face_cross, vertex_areas, vertex_normals
from pmwm.metrics import binomial_tail
from pmwm.spatial import pairs_within

SIGNS = np.array(list(itertools.product((1.0, -1.0), repeat=3)))  # (8, 3) the reader's sign choices


@dataclass(frozen=True)
class CarrierOptions:
    sites: int = 256
    patterns: int = 4
    radius: float = 0.3  # patch radius in RMS radii
    cycles: float = 1.5  # pattern cycles per patch radius
    step: float = 1.75  # QIM step on R = Z / A (the embedder's)
    # the steps an embedder may choose; the reader tries all
    steps: tuple[float, ...] = (1.75, 1.25, 0.875, 0.625, 0.4375)
    floor: float = 1e-3  # amplitude floor, canonical units (RMS radius 1)
    payload_bits: int = 32
    check_bits: int = 32
    rounds: int = 4
    compensation: float = 1.0  # distortion compensation: share of the way to the lattice point moved
    min_agree: float = 0.2  # normal agreement below which a vertex weighs nothing
    min_incidence: float = 0.3  # a site counts when its ray meets the patch at a cosine above this

    @property
    def bits(self) -> int:
        return self.payload_bits + self.check_bits


def keyed_rng(phrase: str, label: str) -> np.random.Generator:
    """A generator drawn from the pass phrase for one purpose."""
    return np.random.default_rng(int.from_bytes(hashlib.sha256(f"{phrase}\x00{label}".encode()).digest(), "little"))


@dataclass(frozen=True)
class Layout:
    """The keyed choices of one phrase. K sites, J patterns, B bits."""

    directions: np.ndarray  # (K, 3) unit ray directions
    axes: np.ndarray  # (K, 3) unit keyed tangent references
    waves: np.ndarray  # (K, J, 2) unit wave directions in (u, v)
    phases: np.ndarray  # (K, J)
    cell_bit: np.ndarray  # (K * J,) the bit each cell carries
    cell_sign: np.ndarray  # (K * J,) +-1
    dither: np.ndarray  # (B,) in [0, 1)


def layout(phrase: str, o: CarrierOptions) -> Layout:
    rng = keyed_rng(phrase, "keyed-patches layout")
    K, J, B = o.sites, o.patterns, o.bits
    d = rng.standard_normal((K, 3))
    a = rng.standard_normal((K, 3))
    ang = rng.uniform(0, np.pi, (K, J))
    cells = K * J
    if cells % B:
        raise ValueError(f"sites * patterns ({cells}) must be a multiple of the word's {B} bits")
    return Layout(
        directions=d / np.linalg.norm(d, axis=1)[:, None],
        axes=a / np.linalg.norm(a, axis=1)[:, None],
        waves=np.stack([np.cos(ang), np.sin(ang)], axis=-1),
        phases=rng.uniform(0, 2 * np.pi, (K, J)),
        cell_bit=rng.permutation(cells) % B,
        cell_sign=rng.choice([-1.0, 1.0], cells),
        dither=rng.uniform(0, 1, B),
    )


# ----------------------------------------------------------------------------------------------
# frame and sites


@dataclass(frozen=True)
class Frame:
    centre: np.ndarray  # (3,)
    axes: np.ndarray  # (3, 3) rows: unit axes, largest second moment first
    scale: float  # RMS radius
    moments: np.ndarray  # (3,) second moments along the axes (scale^2 units)

    def to_canonical(self, V: np.ndarray, signs: np.ndarray) -> np.ndarray:
        return ((V - self.centre) @ self.axes.T) * signs / self.scale

    def to_world_delta(self, dX: np.ndarray, signs: np.ndarray) -> np.ndarray:
        return (dX * signs * self.scale) @ self.axes


def frame(V: np.ndarray, F: np.ndarray) -> tuple[Frame, np.ndarray]:
    """The key-free frame and the embedder's sign choice (third moments positive). Exact triangle integrals:
    area, centroid, second moments (a triangle's integral of x x^T is A/12 (sum v v^T + s s^T), s = a+b+c)."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    total = area.sum()
    centre = (area[:, None] * (a + b + c) / 3.0).sum(0) / total
    a, b, c = a - centre, b - centre, c - centre
    s = a + b + c
    M = np.einsum("f,fi,fj->ij", area / 12.0, s, s)
    for p in (a, b, c):
        M += np.einsum("f,fi,fj->ij", area / 12.0, p, p)
    M /= total
    w, E = np.linalg.eigh(M)
    order = np.argsort(w)[::-1]
    w, E = w[order], E[:, order].T
    scale = float(np.sqrt(w.sum()))
    fr = Frame(centre=centre, axes=E, scale=scale, moments=w / scale**2)
    # third moments from the vertices' areas (only their signs are used)
    X = (V - centre) @ E.T
    va = vertex_areas(V, F)
    third = (va[:, None] * X**3).sum(0)
    signs = np.where(third >= 0, 1.0, -1.0)
    return fr, signs


def outermost_hits(X: np.ndarray, F: np.ndarray, U: np.ndarray) -> np.ndarray:
    """(K, 3) the outermost intersection of each ray t * U[k] (t > 0) with the triangles, NaN where none.
    Candidates: triangles whose bounding sphere the ray can cross (by the direction of their centre, a
    KD-tree on the unit sphere; triangles close to the origin always); then Moller-Trumbore on those."""
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    C = (a + b + c) / 3.0
    rad = np.sqrt(np.maximum(np.maximum(((a - C) ** 2).sum(1), ((b - C) ** 2).sum(1)), ((c - C) ** 2).sum(1)))
    dist = np.linalg.norm(C, axis=1)
    near = dist <= 4.0 * rad
    alpha = np.where(near, np.inf, 2.0 * np.arcsin(np.minimum(1.0, rad / np.where(near, 1.0, dist))))  # chord
    far = np.flatnonzero(~near)
    reach = float(alpha[far].max()) if len(far) else 0.0
    kk, jj, dd = pairs_within(U, C[far] / dist[far, None], reach * 1.0001)
    keep = dd <= alpha[far][jj] * 1.0001
    rr = np.concatenate([kk[keep], np.repeat(np.arange(len(U)), near.sum())])
    ff = np.concatenate([far[jj[keep]], np.tile(np.flatnonzero(near), len(U))])
    e1, e2 = b[ff] - a[ff], c[ff] - a[ff]
    u = U[rr]
    p = np.cross(u, e2)
    det = (e1 * p).sum(1)
    ok = np.abs(det) > 1e-30
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = -a[ff]  # ray origin 0
    bu = (tv * p).sum(1) * inv
    q = np.cross(tv, e1)
    bv = (u * q).sum(1) * inv
    tt = (e2 * q).sum(1) * inv
    hit = ok & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (tt > 0)
    best = np.full(len(U), -np.inf)
    np.maximum.at(best, rr[hit], tt[hit])
    out = np.full((len(U), 3), np.nan)
    found = np.isfinite(best)
    out[found] = best[found, None] * U[found]
    return out


# ----------------------------------------------------------------------------------------------
# cells


@dataclass
class Cells:
    """One reading of every cell in one frame."""

    z: np.ndarray  # (K, J) projections (canonical units)
    valid: np.ndarray  # (K,) patches with surface
    # per (site, vertex) pair, for the embedder
    k: np.ndarray  # (P,)
    i: np.ndarray  # (P,)
    shape: np.ndarray  # (P, J) window * normal weight * psi_perp: a cell's displacement per unit
    direction: np.ndarray  # (P, 3) unit displacement direction (the vertex normal, outward for the patch)
    gain: np.ndarray  # (K, J) change of z per unit of a cell's displacement
    proj: np.ndarray  # (P, J) a cell's weight on a pair's height: z = sum over its pairs of proj * h
    normal: np.ndarray  # (P, 3) the pair's patch normal (h = (x - site) . normal)
    area: np.ndarray  # (n,) vertex areas


def read_cells(X: np.ndarray, F: np.ndarray, lay: Layout, o: CarrierOptions) -> Cells:
    K, J = lay.phases.shape
    area = vertex_areas(X, F)
    normals = vertex_normals(X, F, face_cross(X, F))
    sites = outermost_hits(X, F, lay.directions)
    found = np.isfinite(sites[:, 0])
    sk = np.flatnonzero(found)
    kk, ii, d = pairs_within(sites[sk], X, o.radius)
    kk = sk[kk]
    win = (1.0 - (d / o.radius) ** 2) ** 2
    wa = win * area[ii]
    n0 = np.stack([np.bincount(kk, weights=wa * normals[ii, c], minlength=K) for c in range(3)], axis=1)
    flip = np.where((n0 * lay.directions).sum(1) >= 0, 1.0, -1.0)
    n0 = n0 * flip[:, None]
    n0 /= np.maximum(np.linalg.norm(n0, axis=1), 1e-300)[:, None]
    agree = (normals[ii] * n0[kk]).sum(1) * flip[kk]
    nw = np.clip((agree - o.min_agree) / 0.5, 0.0, 1.0)
    shape_w = win * nw
    w = shape_w * area[ii]
    W = np.bincount(kk, weights=w, minlength=K)
    valid = found & (W > 0) & ((n0 * lay.directions).sum(1) > o.min_incidence)  # grazing rays' sites jump
    t1 = lay.axes - (lay.axes * n0).sum(1)[:, None] * n0
    t1 /= np.maximum(np.linalg.norm(t1, axis=1), 1e-300)[:, None]
    t2 = np.cross(n0, t1)
    rel = X[ii] - sites[kk]
    u = (rel * t1[kk]).sum(1) / o.radius
    v = (rel * t2[kk]).sum(1) / o.radius
    h = (rel * n0[kk]).sum(1)
    B = np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], axis=1)  # (P, 6)
    along = lay.waves[kk, :, 0] * u[:, None] + lay.waves[kk, :, 1] * v[:, None]  # (P, J)
    psi = np.cos(2 * np.pi * o.cycles * along + lay.phases[kk])
    G = np.zeros((K, 6, 6))
    for p, q in zip(*np.triu_indices(6)):
        G[:, p, q] = G[:, q, p] = np.bincount(kk, weights=w * B[:, p] * B[:, q], minlength=K)
    Bp = np.zeros((K, 6, J))
    for p in range(6):
        for j in range(J):
            Bp[:, p, j] = np.bincount(kk, weights=w * B[:, p] * psi[:, j], minlength=K)
    G += np.eye(6)[None] * (1e-9 + 1e-9 * np.trace(G, axis1=1, axis2=2))[:, None, None]
    beta = np.linalg.solve(G, Bp)  # (K, 6, J)
    perp = psi - np.einsum("pa,paj->pj", B, beta[kk])
    Ws = np.where(W > 0, W, 1.0)
    z = np.stack([np.bincount(kk, weights=w * h * perp[:, j], minlength=K) for j in range(J)], axis=1) / Ws[:, None]
    shape = shape_w[:, None] * perp
    gain = (
        np.stack([np.bincount(kk, weights=w * perp[:, j] * shape[:, j] * agree, minlength=K) for j in range(J)], axis=1)
        / Ws[:, None]
    )
    direction = normals[ii] * flip[kk, None]
    z[~valid] = 0.0
    proj = w[:, None] * perp / Ws[kk, None]
    return Cells(
        z=z, valid=valid, k=kk, i=ii, shape=shape, direction=direction, gain=gain, proj=proj, normal=n0[kk], area=area
    )


def cross_gains(cells: Cells, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(G, e): G (K*J, K*J) the change of every cell's z per unit coefficient of every cell's displacement
    field (linearised: weights, sites and frames held), e (K*J,) each field's energy (area-weighted squared
    displacement). Overlapping patches' patterns are not orthogonal: the embedder solves with G."""
    from scipy import sparse

    P, J = cells.proj.shape
    K = cells.z.shape[0]
    rows = (cells.k[:, None] * J + np.arange(J)[None, :]).ravel()  # (P*J,) cell of each (pair, pattern)
    cols_v = np.repeat(cells.i, J)
    Pm = sparse.csr_matrix((K * J, 3 * n))
    Dm = sparse.csr_matrix((3 * n, K * J))
    for a in range(3):
        Pm = Pm + sparse.csr_matrix(
            ((cells.proj * cells.normal[:, a : a + 1]).ravel(), (rows, 3 * cols_v + a)), shape=(K * J, 3 * n)
        )
        Dm = Dm + sparse.csr_matrix(
            ((cells.shape * cells.direction[:, a : a + 1]).ravel(), (3 * cols_v + a, rows)), shape=(3 * n, K * J)
        )
    G = (Pm @ Dm).toarray()
    e = np.bincount(rows, weights=(cells.shape**2 * cells.area[cells.i, None]).ravel(), minlength=K * J)
    return G, e


# ----------------------------------------------------------------------------------------------
# bits


@dataclass
class BitReading:
    R: np.ndarray  # (B,) normalised projections
    A: np.ndarray  # (B,) amplitudes
    bits: np.ndarray  # (B,) uint8
    margin: np.ndarray  # (B,) distance to the decision boundary in lattice units, 0 .. 0.25 (0.25: on a point)
    count: np.ndarray  # (B,) valid cells per bit


def read_bits(cells: Cells, lay: Layout, o: CarrierOptions) -> BitReading:
    B = o.bits
    z = cells.z.ravel()
    ok = np.repeat(cells.valid, cells.z.shape[1]).astype(float)
    cnt = np.bincount(lay.cell_bit, weights=ok, minlength=B)
    c = np.maximum(cnt, 1.0)
    Z = np.bincount(lay.cell_bit, weights=lay.cell_sign * z * ok, minlength=B) / np.sqrt(c)
    A = np.sqrt(np.bincount(lay.cell_bit, weights=z * z * ok, minlength=B) / c + o.floor**2)
    R = Z / A
    q = 2.0 * (R / o.step - lay.dither)
    r = np.rint(q)
    bits = (r.astype(np.int64) % 2).astype(np.uint8)
    margin = 0.5 - np.abs(q - r)  # in half-steps: 0.5 on a lattice point, 0 on the boundary
    return BitReading(R=R, A=A, bits=bits, margin=margin * 0.5, count=cnt)


def word(phrase: str, payload: np.ndarray, o: CarrierOptions) -> np.ndarray:
    """payload bits + keyed check bits (a hash of the phrase and the payload)."""
    p = np.asarray(payload, np.uint8)
    digest = hashlib.sha256(phrase.encode() + b"\x00check\x00" + np.packbits(p).tobytes()).digest()
    check = np.unpackbits(np.frombuffer(digest, np.uint8))[: o.check_bits]
    return np.concatenate([p, check]).astype(np.uint8)


def payload_of(phrase: str, o: CarrierOptions, label: str = "payload") -> np.ndarray:
    return keyed_rng(phrase, label).integers(0, 2, o.payload_bits).astype(np.uint8)


# ----------------------------------------------------------------------------------------------
# embed and read


def embed(V: np.ndarray, F: np.ndarray, phrase: str, payload: np.ndarray, o: CarrierOptions) -> tuple[np.ndarray, dict]:
    """The marked vertices (n, 3) and a log (rounds' bit errors)."""
    lay = layout(phrase, o)
    target = word(phrase, payload, o)
    Vm = np.asarray(V, np.float64).copy()
    log = {"errors": []}
    for rnd in range(o.rounds):
        fr, signs = frame(Vm, F)
        X = fr.to_canonical(Vm, signs)
        cells = read_cells(X, F, lay, o)
        rd = read_bits(cells, lay, o)
        log["errors"].append(int((rd.bits != target).sum()))
        if rnd == 0:  # the goal of each bit: the way from the host's R towards its bit's nearest lattice point
            goal = rd.R + o.compensation * (R_to_target(rd.R, target, lay.dither, o.step) - rd.R)
        dR = goal - rd.R
        dZ = dR * rd.A
        # least energy: the coefficients of all cells' fields that move every bit's Z by dZ (through the cross
        # gains of overlapping cells), minimising the fields' energy
        G, e = cross_gains(cells, len(Vm))
        cvalid = np.repeat(cells.valid, o.patterns)
        S = np.zeros((o.bits, len(e)))
        S[lay.cell_bit, np.arange(len(e))] = lay.cell_sign * cvalid / np.sqrt(np.maximum(rd.count, 1.0))[lay.cell_bit]
        H = S @ G[:, cvalid]  # (B, valid cells)
        inv_e = 1.0 / np.maximum(e[cvalid], 1e-12 * e.max())
        Hw = H * inv_e[None, :]
        c_valid = Hw.T @ np.linalg.solve(Hw @ H.T + 1e-12 * np.trace(Hw @ H.T) * np.eye(o.bits), dZ)
        coef = np.zeros(len(e))
        coef[cvalid] = c_valid
        coef = coef.reshape(o.sites, o.patterns)
        amp = (cells.shape * coef[cells.k]).sum(1)  # (P,)
        dX = np.stack(
            [np.bincount(cells.i, weights=amp * cells.direction[:, c], minlength=len(Vm)) for c in range(3)], 1
        )
        Vm = Vm + fr.to_world_delta(dX, signs)
    fr, signs = frame(Vm, F)
    rd = read_bits(read_cells(fr.to_canonical(Vm, signs), F, lay, o), lay, o)
    log["errors"].append(int((rd.bits != target).sum()))
    return Vm, log


def R_to_target(R: np.ndarray, bits: np.ndarray, dither: np.ndarray, step: float) -> np.ndarray:
    """The point of bit b's lattice (step * (k + b/2 + dither)) nearest to R."""
    off = step * (dither + 0.5 * bits)
    return off + step * np.rint((R - off) / step)


@dataclass
class Reading:
    p_value: float  # union bound over the 8 sign choices and the Chase candidates
    bits: np.ndarray  # the word of the best candidate of the best frame
    raw: np.ndarray  # the word read in that frame before the Chase search
    check_matches: int
    signs: np.ndarray
    margins: np.ndarray


def read(V: np.ndarray, F: np.ndarray, phrase: str, o: CarrierOptions, chase: int = 6) -> Reading:
    """Blind read: every sign choice and every step of ``o.steps``; in each, the 2^chase words that flip subsets
    of the ``chase`` least reliable bits; p = 8 * len(steps) * 2^chase * P(Binomial(check_bits, 1/2) >= matches)
    of the best candidate (the candidates depend on the bits and margins read only, so the union bound holds)."""
    lay = layout(phrase, o)
    V = np.asarray(V, np.float64)
    fr, own = frame(V, F)
    flips = np.array(list(itertools.product((0, 1), repeat=chase)), np.uint8)  # (2^chase, chase)
    best = None
    # the embedder's sign convention first; stopping once every check bit matches only shrinks the set of
    # readings tried, so the bound over all 8 still holds
    for signs in sorted(SIGNS, key=lambda s: 0 if (s == own).all() else 1):
        if best is not None and best[0] == o.check_bits:
            break
        cells = read_cells(fr.to_canonical(V, signs), F, lay, o)
        for step in o.steps:
            rd = read_bits(cells, lay, replace(o, step=step))
            weak = np.argsort(rd.margin, kind="stable")[:chase]
            cands = np.repeat(rd.bits[None], len(flips), 0)
            cands[:, weak] ^= flips
            for cand in cands:
                expected = word(phrase, cand[: o.payload_bits], o)[o.payload_bits :]
                m = int((expected == cand[o.payload_bits :]).sum())
                if best is None or m > best[0]:
                    best = (m, cand, rd, signs)
    m, cand, rd, signs = best
    p = min(1.0, len(SIGNS) * len(o.steps) * len(flips) * binomial_tail(m, o.check_bits))
    return Reading(p_value=p, bits=cand, raw=rd.bits, check_matches=m, signs=signs, margins=rd.margin)


def embed_within(
    V: np.ndarray, F: np.ndarray, phrase: str, payload: np.ndarray, o: CarrierOptions, budget: float = 0.03
) -> tuple[np.ndarray, dict]:
    """``embed`` at the largest step of ``o.steps`` whose MRMS (% of the bbox diagonal,
    ``pmwm.metrics.displaced_surface_distance``, seed 1) is within ``budget`` and whose own read-back has every
    bit right; the unmarked vertices and ``refused`` in the log when none is. The MRMS grows about linearly
    with the step, so steps predicted above the budget by the first embed are skipped."""
    from pmwm.metrics import displaced_surface_distance

    tried = []
    scale = None
    for step in sorted(o.steps, reverse=True):
        if scale is not None and scale * step > budget:
            continue
        Vm, log = embed(V, F, phrase, payload, replace(o, step=step))
        mrms = float(displaced_surface_distance(V, Vm, F, seed=1)[0])
        scale = mrms / step if scale is None else scale
        tried.append({"step": step, "mrms": mrms, "errors": log["errors"][-1]})
        if mrms <= budget and log["errors"][-1] == 0:
            return Vm, {**log, "mrms": mrms, "step": step, "tried": tried}
    return np.asarray(V, np.float64).copy(), {"refused": True, "mrms": 0.0, "step": None, "tried": tried}
