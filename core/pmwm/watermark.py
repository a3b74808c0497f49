"""Embedding and blind extraction: the paper's Algorithms 1 and 2 around the progressive mesh.

Embedding (Algorithm 1). Carriers are SOM-suitable vertices picked with the key.
Each carrier c absorbs its nearest valid neighbour NH1 by a half-edge collapse (the
first collapses of the progressive mesh) and is moved, per axis, to
``mu + s * sigma`` for bit 1 or ``mu - s * sigma`` for bit 0, with mu and sigma the
mean and standard deviation of its remaining neighbours (s = strength, 2 in the
paper). Carriers are never removed by the decimation, so they are in every level of
detail. The bits embedded are the payload XOR a keyed pseudo-random sequence, so an
unmarked shape's natural bias cannot read as a mark.

Extraction (Algorithm 2, eqs. 3-5). The paper's eqs. (4)-(5) both test against
``mu + alpha`` (garbled). We read a carrier c with neighbours N on the mesh at hand
(any level of detail, or a suspect copy) by the score
``s = sum over axes of (c_a - mu_a) / sigma_a`` and decide bit 1 when s > 0, bit 0
when s < 0 (alpha = 0); axes with sigma = 0 are left out. A carrier that cannot
be found or has no neighbours is an erasure; it is given a keyed coin-flip bit, so
that the false-positive probability below stays exact.

Precision. The marked mesh is rounded to float32 (a relative change below 6e-8, what
any float32 format does on export); the progressive mesh then stores float32 positions.

Verdict. With K of N bits matching, p = P(Binomial(N, 1/2) >= K); the mesh is
``marked`` when p < p_threshold (1e-6 by default).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence, Union

import numpy as np

from . import metrics
from .adjacency import Adjacency, build_adjacency, gather_rows
from .carriers import eligible_carriers, select_carriers
from .errors import MeshError, PayloadError
from .key import WatermarkKey, derive_seed, make_secret
from .progressive import ProgressiveMesh, build_progressive_mesh
from .register import nearest

Progress = Optional[Callable[[float, str], None]]
DEFAULT_BITS = 64
MAX_COORDINATE = 1e30  # marked meshes are float32 (max 3.4e38); quadrics square coordinates


@dataclass
class EmbedOptions:
    """Options of :func:`embed` (see docs/api.md)."""

    payload: Optional[str] = None
    bits: Optional[Union[str, Sequence[int]]] = None
    n_bits: int = DEFAULT_BITS
    strength: float = 2.0
    base_ratio: float = 0.03
    seed: Optional[int] = None
    scheme: str = "robust"  # "robust" (pmwm.robust, the default) or "paper" (Algorithms 1-2)


@dataclass
class EmbedResult:
    """The marked mesh, its progressive mesh and the key."""

    vertices: np.ndarray
    faces: np.ndarray
    pm: ProgressiveMesh
    key: WatermarkKey
    carriers: np.ndarray
    bits: np.ndarray
    vsnr_db: float
    rmse: float


@dataclass
class Verdict:
    """The answer of :func:`verify`."""

    marked: bool
    p_value: float
    bits: str
    payload: Optional[str]
    matches: int
    bit_errors: int
    correlation: float
    carriers_found: int
    carriers_total: int
    mode: str
    p_threshold: float = 1e-6
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "marked": self.marked,
            "p_value": self.p_value,
            "p_threshold": self.p_threshold,
            "bits": self.bits,
            "payload": self.payload,
            "matches": self.matches,
            "bit_errors": self.bit_errors,
            "correlation": self.correlation,
            "carriers_found": self.carriers_found,
            "carriers_total": self.carriers_total,
            "mode": self.mode,
        }


# --------------------------------------------------------------------------- payload


def payload_bits(options: EmbedOptions, secret: str) -> tuple[np.ndarray, str]:
    """The payload as bits and its kind: text (UTF-8, at least 64 bits), explicit bits, or random."""
    if options.payload is not None and options.bits is not None:
        raise PayloadError("give a text payload or explicit bits, not both")
    if options.payload is not None:
        data = options.payload.encode("utf-8")
        if not data:
            raise PayloadError("the payload text is empty; give some text or use --bits")
        data = data + b"\0" * max(0, DEFAULT_BITS // 8 - len(data))
        return np.unpackbits(np.frombuffer(data, np.uint8)), "text"
    if options.bits is not None:
        raw = options.bits
        if isinstance(raw, str):
            if not raw or set(raw) - {"0", "1"}:
                raise PayloadError("bits must be a non-empty string of 0 and 1, e.g. --bits 01101001")
            arr = np.frombuffer(raw.encode(), np.uint8) - ord("0")
        else:
            arr = np.asarray(raw).astype(np.int64).ravel()
            if len(arr) == 0 or np.any((arr != 0) & (arr != 1)):
                raise PayloadError("bits must be a non-empty sequence of 0 and 1")
        return arr.astype(np.uint8), "bits"
    if options.n_bits < 1:
        raise PayloadError("the number of bits must be at least 1")
    rng = np.random.default_rng(derive_seed(secret, "random-payload"))
    return rng.integers(0, 2, options.n_bits).astype(np.uint8), "random"


def decode_text(bits: np.ndarray) -> Optional[str]:
    """Text payload from bits (trailing NUL bytes dropped); None if not valid UTF-8."""
    if len(bits) % 8:
        return None
    data = np.packbits(np.asarray(bits, np.uint8)).tobytes().rstrip(b"\0")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


# --------------------------------------------------------------------------- embedding


def check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Validated float64 vertices and int64 triangle faces, or a MeshError."""
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces)
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"vertices must be an (n, 3) array, got shape {V.shape}")
    if F.size == 0 or len(V) == 0:
        raise MeshError("the mesh is empty (no vertices or no faces); nothing to watermark")
    if F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(f"faces must be an (m, 3) array of triangles, got shape {F.shape}; triangulate first")
    F = F.astype(np.int64)
    if F.min() < 0 or F.max() >= len(V):
        raise MeshError("a face refers to a vertex index outside the vertex array")
    if not np.all(np.isfinite(V)):
        raise MeshError("the mesh has NaN or infinite coordinates; repair it first")
    if np.abs(V).max() > MAX_COORDINATE:
        raise MeshError(f"coordinates reach {np.abs(V).max():.3g}, beyond float32 range for a marked mesh "
                        f"(limit {MAX_COORDINATE:g}); rescale the mesh first")
    return V, F


def mean_edge_length(V: np.ndarray, adj: Adjacency) -> float:
    e = adj.edges
    if len(e) == 0:
        return 0.0
    return float(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1).mean())


def _first_neighbours(V: np.ndarray, adj: Adjacency, carriers: np.ndarray) -> np.ndarray:
    """For each carrier, the neighbour it absorbs first (NH1): the nearest one whose
    half-edge collapse into the carrier keeps the mesh manifold; -1 if none."""
    out = np.full(len(carriers), -1, np.int64)
    bad = adj.boundary_vertex | adj.nonmanifold_vertex | adj.isolated_vertex
    val = adj.valence
    nf = np.diff(adj.vf_ptr)
    for i, c in enumerate(carriers):  # one iteration per carrier (tens), not per vertex
        ring = adj.ring(c)
        order = np.argsort(np.linalg.norm(V[ring] - V[c], axis=1), kind="stable")
        ring_c = set(ring.tolist())
        for u in ring[order]:
            if bad[u] or nf[u] < 3 or nf[u] + nf[c] - 4 > 64:
                continue
            common = [w for w in adj.ring(u) if w in ring_c]
            if len(common) == 2 and all(val[w] >= 4 for w in common):
                out[i] = u
                break
    return out


def _ring_stats(V: np.ndarray, adj: Adjacency, carriers: np.ndarray, exclude: np.ndarray):
    """Mean and standard deviation per axis of each carrier's neighbours minus ``exclude``."""
    rec = np.repeat(np.arange(len(carriers)), adj.valence[carriers])
    nb = gather_rows(adj.ring_ptr, adj.ring_idx, carriers)
    keep = nb != exclude[rec]
    return _grouped_stats(V[nb[keep]], rec[keep], len(carriers))


def _grouped_stats(P: np.ndarray, rec: np.ndarray, k: int):
    cnt = np.bincount(rec, minlength=k).astype(np.float64)
    safe = np.maximum(cnt, 1)[:, None]
    s = np.stack([np.bincount(rec, weights=P[:, a], minlength=k) for a in range(3)], axis=1)
    mu = s / safe
    d = P - mu[rec]
    var = np.stack([np.bincount(rec, weights=d[:, a] ** 2, minlength=k) for a in range(3)], axis=1) / safe
    return mu, np.sqrt(var), cnt


def check_options(opts: EmbedOptions) -> EmbedOptions:
    """``opts`` when its scheme, strength and base ratio make sense, else PayloadError."""
    if opts.scheme not in ("robust", "paper"):
        raise PayloadError(f"unknown scheme {opts.scheme!r}; use 'robust' or 'paper'")
    if not (opts.strength > 0 and np.isfinite(opts.strength)):
        raise PayloadError(f"strength must be a positive number, got {opts.strength}")
    if not (0 < opts.base_ratio <= 1):
        raise PayloadError(f"base ratio must be in (0, 1], got {opts.base_ratio}")
    return opts


def embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
    """Watermark a triangle mesh; see the module docstring and docs/api.md."""
    opts = check_options(options or EmbedOptions())
    if opts.scheme == "robust":
        from .robust import robust_embed

        return robust_embed(vertices, faces, opts, progress=progress)
    V, F = check_mesh(vertices, faces)
    report = progress or (lambda f, m: None)
    secret = make_secret(opts.seed)
    bits, kind = payload_bits(opts, secret)
    report(0.0, "analysing the mesh")
    adj = build_adjacency(F, len(V))
    eligible = eligible_carriers(V, adj, seed=derive_seed(secret, "som"))
    carriers = select_carriers(V, adj, eligible, len(bits), seed=derive_seed(secret, "carriers"))
    report(0.1, f"{len(carriers)} carriers chosen")

    key_stub = WatermarkKey(
        secret=secret, bits=bits, payload_kind=kind, strength=float(opts.strength),
        carrier_index=carriers, carrier_pm_index=carriers, carrier_position=V[carriers],
        n_vertices=len(V), n_faces=len(F), mean_edge=1.0, bbox_diagonal=1.0,
    )
    w = bits ^ key_stub.stream("scramble", len(bits))
    nh1 = _first_neighbours(V, adj, carriers)
    mu, sigma, _ = _ring_stats(V, adj, carriers, nh1)
    sign = np.where(w == 1, 1.0, -1.0)[:, None]
    # The marked mesh is stored in float32, as Blender, PLY, STL and glTF store it, so
    # that the progressive mesh reproduces it exactly at 24 bytes per record.
    marked = V.copy()
    marked[carriers] = mu + opts.strength * sigma * sign
    marked = marked.astype(np.float32).astype(np.float64)

    forced = np.stack([nh1, carriers], axis=1)[nh1 >= 0]
    protected = np.zeros(len(V), bool)
    protected[carriers] = True
    base = max(int(round(opts.base_ratio * len(V))), 4)

    def pm_progress(f: float, msg: str) -> None:
        report(0.15 + 0.8 * f, msg)

    pm, _ = build_progressive_mesh(marked, F, base_vertices=base, protected=protected, forced=forced,
                                   progress=pm_progress, adjacency=adj)
    pm_of = np.empty(len(V), np.int64)
    pm_of[pm.vertex_order] = np.arange(len(V))
    key = WatermarkKey(
        secret=secret,
        bits=bits,
        payload_kind=kind,
        strength=float(opts.strength),
        carrier_index=carriers,
        carrier_pm_index=pm_of[carriers],
        carrier_position=marked[carriers].copy(),
        n_vertices=len(V),
        n_faces=len(F),
        mean_edge=mean_edge_length(marked, adj),
        bbox_diagonal=float(np.linalg.norm(V.max(0) - V.min(0))),
    )
    report(1.0, "done")
    return EmbedResult(
        vertices=marked,
        faces=F,
        pm=pm,
        key=key,
        carriers=carriers,
        bits=bits,
        vsnr_db=metrics.vsnr(V, marked),
        rmse=metrics.vertex_rmse(V, marked),
    )


# --------------------------------------------------------------------------- extraction


def locate_carriers(V: np.ndarray, key: WatermarkKey) -> tuple[np.ndarray, str]:
    """Index of each carrier in V (-1 when not found) and how it was found.

    "index": V keeps the marked mesh's order or the progressive mesh's order (any
    level of detail); "position": the nearest vertex to the stored position, within
    one mean edge length (re-ordered, cropped or re-exported copies).
    """
    n = len(V)
    tol = key.mean_edge
    best = None
    for idx in (key.carrier_index, key.carrier_pm_index):
        inside = idx < n
        if inside.mean() < 0.5:
            continue
        d = np.linalg.norm(V[np.where(inside, idx, 0)] - key.carrier_position, axis=1)
        med = float(np.median(np.where(inside, d, np.inf)))
        if med <= 0.25 * tol and (best is None or med < best[0]):
            best = (med, np.where(inside, idx, -1))
    if best is not None:
        return best[1], "index"
    found = np.full(key.n_bits, -1, np.int64)
    near, d2 = nearest(V, key.carrier_position)
    ok = d2 <= tol * tol
    found[ok] = near[ok]
    return found, "position"


def carrier_scores(V: np.ndarray, F: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Score of each located carrier against its 1-ring (0 where it cannot be read)."""
    k = len(idx)
    slot = np.full(len(V), -1, np.int64)
    good = idx >= 0
    slot[idx[good]] = np.flatnonzero(good)
    s = slot[F]
    rows, cols = np.nonzero(s >= 0)
    rec = s[rows, cols]
    nb = np.concatenate([F[rows, (cols + 1) % 3], F[rows, (cols + 2) % 3]])
    rec2 = np.concatenate([rec, rec])
    pair = np.unique(rec2 * len(V) + nb)
    rec_u, nb_u = pair // len(V), pair % len(V)
    mu, sigma, cnt = _grouped_stats(V[nb_u], rec_u, k)
    c = V[np.where(good, idx, 0)]
    scale = np.abs(mu).max() + sigma.max() if k else 1.0
    usable = sigma > 1e-12 * max(scale, 1e-300)
    z = np.where(usable, (c - mu) / np.where(usable, sigma, 1.0), 0.0)
    score = z.sum(axis=1)
    score[~good | (cnt < 2)] = 0.0
    return score


def verify(vertices, faces, key: WatermarkKey, p_threshold: float = 1e-6) -> Verdict:
    """Read the mark from a plain mesh (any order, possibly attacked) with the key."""
    if key.scheme == "robust":
        from .robust import robust_verify

        return robust_verify(vertices, faces, key, p_threshold)
    V, F = check_mesh(vertices, faces)
    idx, mode = locate_carriers(V, key)
    score = carrier_scores(V, F, idx)
    return _verdict(score, key, mode, p_threshold)


def verify_pm(pm: ProgressiveMesh, key: WatermarkKey, records: Optional[int] = None,
              p_threshold: float = 1e-6) -> Verdict:
    """Read the mark from a progressive mesh at a level of detail (default: full)."""
    V, F = pm.decode(records=records)
    return verify(V, F, key, p_threshold)


def _verdict(score: np.ndarray, key: WatermarkKey, mode: str, p_threshold: float) -> Verdict:
    n = key.n_bits
    erased = score == 0
    w = (score > 0).astype(np.uint8)
    coin = key.stream("erasure", n)
    w[erased] = coin[erased]
    bits = w ^ key.stream("scramble", n)
    matches = int(np.sum(bits == key.bits))
    p = metrics.binomial_tail(matches, n)
    payload = decode_text(bits) if key.payload_kind == "text" else None
    return Verdict(
        marked=bool(p < p_threshold),
        p_value=float(p),
        bits="".join(map(str, bits.tolist())),
        payload=payload,
        matches=matches,
        bit_errors=n - matches,
        correlation=float(metrics.correlation(key.bits, bits)),
        carriers_found=int(np.sum(~erased)),
        carriers_total=n,
        mode=mode,
        p_threshold=p_threshold,
    )


def ber_per_level(pm: ProgressiveMesh, key: WatermarkKey) -> list[tuple[int, int, float]]:
    """(records, vertices, BER) at the base mesh and at the end of every level."""
    out = []
    for k in [0, *pm.level_records.tolist()]:
        v = verify_pm(pm, key, records=k)
        out.append((k, pm.n_base_vertices + k, v.bit_errors / v.carriers_total))
    return out
