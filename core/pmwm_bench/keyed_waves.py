"""A prototype blind carrier: keyed directions among the solid's low spatial frequencies (experiment code).

Not a scheme: ``benchmarks/blind_waves_experiment.py`` measures it on meshes nobody tuned it on, against
attacks and against an attacker without the pass phrase (docs/decisions/141-keyed-waves-prototype.md).
Everything secret derives from the pass phrase (SHA-256 -> numpy Generator); nothing of the mesh is stored.

Frame (no key): the solid's centroid, its second-moment axes (exact tetrahedron integrals from the surface's
area centroid, so an open surface with small holes still has one) and its RMS radius as the unit; the axes'
signs follow the surface's third moments. The reader tries the 8 sign choices (mirrors included), the
embedder's first, and pays all 8.

Carrier: ``n_basis`` keyed plane waves psi_j(x) = cos(2 pi f_j u_j . x + phi_j) in that frame, frequencies
f_j drawn uniformly in a ball shell of ``band`` cycles per RMS radius. For each wave the volume integral
y_j = integral over the solid of psi_j = surface integral of G_j . n, G_j = u_j sin(...) / (2 pi f_j)
(divergence theorem; 3-point quadrature per face). It is a property of the solid, not of its sampling:
remeshing, simplification and subdivision move it little, and moving the surface by delta along its normals
moves it by the surface integral of psi_j delta. A word bit k reads z_k = s_k . y (a keyed unit spread
vector s_k), quantised with a step Delta and a keyed dither: bit 0 on integers, bit 1 on half-integers
(dither modulation). The embedder moves the vertices along their normals by the least-energy field in the
span of the waves that sets every z_k on its bit's lattice (solve through the Gram matrix of the spread
waves on the surface), three rounds of reading everything again.

Reading: for each sign choice, the suspect as it is and with smoothing undone (uniform and cotangent
Laplacian steps, ``UNDO_STEPS``, extrapolated to second order from one and two steps of the suspect's own
smoothing), for each public step: the lattice fit mean(cos(4 pi e)) (key-dependent, so every hypothesis
is paid for) ranks the hypotheses; the best few are decoded (Chase flips of the least reliable bits) and
checked by ``CHECK_BITS`` keyed check bits. p = hypotheses x Chase candidates x P(Binomial(64, 1/2) >= m).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from pmwm import metrics
from pmwm.schemes.blind.word import likely_flips
from pmwm.smoothing import mean_operator

CHECK_BITS = 64
BAND = (0.3, 3.0)  # cycles per RMS radius
N_BASIS = 384
STEPS = tuple(2e-3 * 2 ** (i / 2) for i in range(8))  # public quantisation steps (normalised units)
UNDO_STEPS = tuple(np.arange(0.5, 12.01, 0.5))  # smoothing steps (lambda 0.5) the reader may undo
CHASE = 6  # 2^6 candidates per decoded hypothesis
DECODED = 4  # hypotheses decoded per reading (the best lattice fits)
BUDGET = 0.03  # % of the bbox diagonal (MRMS)
QUAD = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
SIGNS = np.array([[1, 1, 1], [-1, 1, 1], [1, -1, 1], [1, 1, -1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1], [-1, -1, -1]])


def _rng(secret: str, label: str) -> np.random.Generator:
    return np.random.default_rng(int.from_bytes(hashlib.sha256(f"{secret}:{label}".encode()).digest()[:8], "little"))


@dataclass(frozen=True)
class Frame:
    """centre (3,), axes (3, 3) columns largest spread first, scale (the solid's RMS radius)."""

    centre: np.ndarray
    axes: np.ndarray
    scale: float

    def local(self, V: np.ndarray) -> np.ndarray:
        return (V - self.centre) @ self.axes / self.scale

    def flipped(self, signs: np.ndarray) -> "Frame":
        return Frame(self.centre, self.axes * signs, self.scale)


def solid_frame(V: np.ndarray, F: np.ndarray) -> Frame:
    """The solid's frame of a surface, vertices (n, 3), faces (m, 3): tetrahedra from the area centroid."""
    T = V[F]
    n2 = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    area = 0.5 * np.linalg.norm(n2, axis=1)
    o = (area[:, None] * T.mean(1)).sum(0) / area.sum()
    a, b, c = T[:, 0] - o, T[:, 1] - o, T[:, 2] - o
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    vol = det.sum() / 6
    s = a + b + c
    cen = (s / 4 * det[:, None]).sum(0) / 6 / vol
    second = np.einsum("n,ni,nj->ij", det, a, a) + np.einsum("n,ni,nj->ij", det, b, b)
    second += np.einsum("n,ni,nj->ij", det, c, c) + np.einsum("n,ni,nj->ij", det, s, s)
    C = second / 120 / vol - np.outer(cen, cen)
    w, R = np.linalg.eigh(C)
    R = R[:, ::-1]
    cen = cen + o
    third = (area[:, None] * ((T.mean(1) - cen) @ R) ** 3).sum(0)
    return Frame(cen, R * np.where(third < 0, -1.0, 1.0), float(np.sqrt(max(w.sum(), 1e-300))))


@dataclass(frozen=True)
class Basis:
    """The keyed waves of a secret: directions u (P, 3), frequencies f (P,), phases (P,), spread vectors
    (K, P) unit rows, dithers (K,), scramble (K,) uint8."""

    u: np.ndarray
    f: np.ndarray
    phase: np.ndarray
    spread: np.ndarray
    dither: np.ndarray
    scramble: np.ndarray

    @property
    def omega(self) -> np.ndarray:
        return (2 * np.pi * self.f[:, None] * self.u).T  # (3, P)


def basis(secret: str, n_word: int, n_basis: int = N_BASIS, band=BAND) -> Basis:
    r = _rng(secret, "keyed-waves")
    u = r.normal(size=(n_basis, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    f = r.uniform(band[0] ** 3, band[1] ** 3, n_basis) ** (1 / 3)
    phase = r.uniform(0, 2 * np.pi, n_basis)
    S = r.normal(size=(n_word, n_basis))
    S /= np.linalg.norm(S, axis=1)[:, None]
    d = r.uniform(0, 1, n_word)
    scramble = _rng(secret, f"keyed-waves-scramble:{n_word}").integers(0, 2, n_word).astype(np.uint8)
    return Basis(u, f, phase, S, d, scramble)


def integrals(Y: np.ndarray, F: np.ndarray, B: Basis) -> np.ndarray:
    """y (P,): the volume integral of each wave over the solid bounded by the surface Y (n, 3), F. The waves
    are evaluated in float32 (their sums are float64, by a matrix product)."""
    T = Y[F]
    n2 = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    un = (n2 @ B.u.T).astype(np.float32)  # (m, P): 2 area (n . u)
    y = np.zeros(len(B.f))
    W = B.omega.astype(np.float32)
    ph = B.phase.astype(np.float32)
    for q in QUAD:
        P = (q[0] * T[:, 0] + q[1] * T[:, 1] + q[2] * T[:, 2]).astype(np.float32)
        arg = P @ W
        arg += ph
        np.sin(arg, out=arg)
        arg *= un
        y += arg.sum(0, dtype=np.float64)
    return y / (2 * np.pi * B.f) / 6


def projections(V: np.ndarray, F: np.ndarray, B: Basis, frame: Frame) -> np.ndarray:
    return B.spread @ integrals(frame.local(V), F, B)


def word_of(secret: str, payload: np.ndarray) -> np.ndarray:
    return np.concatenate([payload, check_bits(secret, payload)]).astype(np.uint8)


def check_bits(secret: str, payload: np.ndarray) -> np.ndarray:
    rows = np.atleast_2d(np.asarray(payload, np.uint8))
    out = np.zeros((len(rows), CHECK_BITS), np.uint8)
    for i, row in enumerate(np.packbits(rows, axis=1)):
        h = hashlib.sha256(f"{secret}:keyed-waves-check:{rows.shape[1]}:".encode() + row.tobytes()).digest()
        out[i] = np.unpackbits(np.frombuffer(h[: CHECK_BITS // 8], np.uint8))
    return out if np.ndim(payload) == 2 else out[0]


def _vertex_normals_areas(Y: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    T = Y[F]
    n2 = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]) / 6
    vA = np.zeros_like(Y)
    for i in range(3):
        np.add.at(vA, F[:, i], n2)
    a = np.linalg.norm(vA, axis=1)
    return vA / np.maximum(a, 1e-300)[:, None], a


def mark(V: np.ndarray, F: np.ndarray, B: Basis, bits: np.ndarray, step: float, rounds: int = 3) -> np.ndarray:
    """The vertices (n, 3) moved along their normals so that z_k sits on bit k's lattice (bits (K,))."""
    V = np.array(V, np.float64)
    K = len(bits)
    S = B.spread[:K]
    for _ in range(rounds):
        fr = solid_frame(V, F)
        Y = fr.local(V)
        e = (S @ integrals(Y, F, B)) / step - B.dither[:K] - bits / 2
        t = -(e - np.round(e)) * step
        N, a = _vertex_normals_areas(Y, F)
        Psi = np.cos(Y @ B.omega + B.phase)  # (n, P)
        SP = Psi @ S.T  # (n, K): the spread waves on the surface
        G = SP.T @ (a[:, None] * SP)
        delta = SP @ np.linalg.solve(G + 1e-12 * np.trace(G) / K * np.eye(K), t)
        V = V + fr.scale * delta[:, None] * (N @ fr.axes.T)
    return V


def embed(V, F, secret: str, payload: np.ndarray, budget: float = BUDGET, samples: int = 5000):
    """(marked vertices, step, MRMS %): the largest public step whose MRMS stays within ``budget`` % and
    whose marked copy reads back its payload; (None, None, mrms of the smallest) when none does."""
    w = word_of(secret, payload)
    B = basis(secret, len(w))
    bits = w ^ B.scramble
    probe = STEPS[len(STEPS) // 2]
    marked = {probe: mark(V, F, B, bits, probe)}
    mrms = {probe: metrics.displaced_surface_distance(V, marked[probe], F, samples, seed=0)[0]}
    guess = probe * budget / max(mrms[probe], 1e-300)  # (the MRMS grows about linearly with the step)
    last = mrms[probe]
    for step in [s for s in sorted(STEPS, reverse=True) if s <= 1.1 * guess]:
        if step not in marked:
            marked[step] = mark(V, F, B, bits, step)
            mrms[step] = metrics.displaced_surface_distance(V, marked[step], F, samples, seed=0)[0]
        last = mrms[step]
        if mrms[step] > budget:
            continue
        Vm = marked[step]
        r = read(Vm.astype(np.float32).astype(np.float64), F, secret, lengths=(len(payload),), signs=1)
        if r.marked and np.array_equal(r.payload, payload):
            return Vm, step, mrms[step]
    return None, None, last


def _cot_operator(V: np.ndarray, F: np.ndarray):
    """Row-normalised cotangent weights (n, n) (clamped at 0), scipy CSR."""
    from scipy.sparse import coo_matrix

    rows, cols, ws = [], [], []
    for i in range(3):
        a, b, c = F[:, i], F[:, (i + 1) % 3], F[:, (i + 2) % 3]
        e1, e2 = V[b] - V[a], V[c] - V[a]
        cot = np.einsum("ij,ij->i", e1, e2) / np.maximum(np.linalg.norm(np.cross(e1, e2), axis=1), 1e-300)
        cot = np.clip(cot, 0, 1e3)
        rows += [b, c]
        cols += [c, b]
        ws += [cot, cot]
    M = coo_matrix((np.concatenate(ws), (np.concatenate(rows), np.concatenate(cols))), shape=(len(V), len(V))).tocsr()
    s = np.asarray(M.sum(1)).ravel()
    s[s == 0] = 1
    from scipy.sparse import diags

    return diags(1 / s) @ M


@dataclass
class Reading:
    marked: bool
    p_value: float
    payload: np.ndarray | None
    matches: int
    hypotheses: int
    sign: int
    undo: str
    step: float


def _aligned(frame: Frame, like: Frame) -> Frame:
    """``frame`` with each axis signed as ``like``'s nearest axis (a smoothed copy read in the same choice)."""
    return frame.flipped(np.where(np.diag(frame.axes.T @ like.axes) < 0, -1.0, 1.0))


def _undone(V, F, B, fr, z0):
    """(label, z) of the suspect with smoothing undone: uniform and cotangent steps, second order."""
    for kind in ("uniform", "cotangent"):
        op = mean_operator(F, len(V)) if kind == "uniform" else _cot_operator(V, F)
        V1 = V + 0.5 * (op @ V - V)
        V2 = V1 + 0.5 * (op @ V1 - V1)
        z1 = projections(V1, F, B, _aligned(solid_frame(V1, F), fr))
        z2 = projections(V2, F, B, _aligned(solid_frame(V2, F), fr))
        d1, d2 = z1 - z0, z2 - 2 * z1 + z0
        for tau in UNDO_STEPS:
            yield f"{kind}:{tau:g}", z0 - tau * d1 + tau * (tau + 1) / 2 * d2


def _decode(cands, B, secret, L, union, sign):
    """The best Reading among the DECODED best lattice fits of ``cands`` [(label, z)]."""
    hyps = []
    for label, z in cands:
        for step in STEPS:
            e = z / step - B.dither
            hyps.append((float(np.mean(np.cos(4 * np.pi * e))), label, step, np.cos(2 * np.pi * e)))
    hyps.sort(key=lambda h: -h[0])
    best = None
    for fit, label, step, score in hyps[:DECODED]:
        got = (score < 0).astype(np.uint8)
        words = (got[None] ^ likely_flips(np.abs(score), 2**CHASE)) ^ B.scramble
        m = (words[:, L:] == check_bits(secret, words[:, :L])).sum(1)
        i = int(np.argmax(m))
        p = min(1.0, union * metrics.binomial_tail(int(m[i]), CHECK_BITS))
        if best is None or p < best.p_value:
            best = Reading(False, p, words[i, :L].copy(), int(m[i]), 0, sign, label, step)
    return best


def read(V, F, secret: str, lengths=(64,), alpha: float = 1e-6, signs: int = len(SIGNS)) -> Reading:
    """The blind reading of a suspect, vertices (n, 3), faces (m, 3), for payloads of ``lengths`` bits.
    The p-value pays for all 8 sign choices; ``signs`` < 8 tries only the first (the embedder's is first):
    a reading that can only miss marks, never find more (experiments' speed)."""
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    base = solid_frame(V, F)
    n_hyp = len(SIGNS) * len(STEPS) * (1 + 2 * len(UNDO_STEPS)) * len(lengths)
    union = n_hyp * 2**CHASE
    best = None
    for si in range(signs):
        fr = base.flipped(SIGNS[si])
        for L in lengths:
            B = basis(secret, L + CHECK_BITS)
            z0 = projections(V, F, B, fr)
            for cands in ([("none", z0)], list(_undone(V, F, B, fr, z0))):
                r = _decode(cands, B, secret, L, union, si)
                if best is None or r.p_value < best.p_value:
                    best = r
                if best.p_value < alpha:
                    best.marked, best.hypotheses = True, n_hyp
                    return best
    best.payload, best.hypotheses = None, n_hyp
    return best
