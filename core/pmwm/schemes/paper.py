"""The paper's scheme (``scheme="paper"``): Algorithms 1 and 2 around the progressive mesh.

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

Finding the carriers. A copy with the marked mesh's faces (in the marked or the progressive
mesh's vertex numbering: the key holds a fingerprint of both) keeps the vertex order whatever noise,
smoothing or quantization moved its vertices: carriers are read by index. So are copies whose
carriers sit within a twentieth of the shape's size of their marked place (levels of detail of the
progressive mesh, which keep its numbering, also noisy ones; a vertex at a random index is that near
by chance only rarely, and the median over all carriers never). Any other copy (re-ordered, cropped,
re-exported) is searched by position: the vertex nearest each carrier's marked place, within one
mean edge length.

The verdict is ``pmwm.base.verdict_from_scores``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..adjacency import Adjacency, build_adjacency, gather_rows, unique_values
from ..base import (
    EmbedOptions,
    EmbedResult,
    Progress,
    Scheme,
    Verdict,
    VerdictDetail,
    finish_embed,
    mesh_key,
    no_progress,
    start_embed,
    verdict_from_scores,
)
from ..carriers import eligible_carriers, select_carriers
from ..errors import KeyFileError
from ..key import WatermarkKey, derive_seed, face_fingerprint, keyed_bits
from ..progressive import base_vertex_count, build_progressive_mesh
from ..spatial import nearest
from ..validate import check_mesh

NAME = "paper"
DEFAULT_STRENGTH = 2.0
INDEX_SHARE = 0.05  # carriers within this share of the bbox diagonal of their places: read by index


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


def embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
    """Watermark a triangle mesh with the paper's scheme (module docstring).

    vertices : (n, 3) float64, faces : (m, 3) int64. See ``pmwm.embed`` and docs/api.md."""
    job = start_embed(vertices, faces, options, progress, NAME, DEFAULT_STRENGTH)
    V, F, secret, bits, report = job.vertices, job.faces, job.secret, job.bits, job.report
    report(0.0, "analysing the mesh")
    adj = build_adjacency(F, len(V))
    eligible = eligible_carriers(V, adj, seed=derive_seed(secret, "som"))
    carriers = select_carriers(V, adj, eligible, len(bits), seed=derive_seed(secret, "carriers"))
    report(0.1, f"{len(carriers)} carriers chosen")

    w = bits ^ keyed_bits(secret, "scramble", len(bits))
    nh1 = _first_neighbours(V, adj, carriers)
    mu, sigma, _ = _ring_stats(V, adj, carriers, nh1)
    sign = np.where(w == 1, 1.0, -1.0)[:, None]
    # The marked mesh is stored in float32, as Blender, PLY, STL and glTF store it, so
    # that the progressive mesh reproduces it exactly at 24 bytes per record.
    marked = V.copy()
    marked[carriers] = mu + job.strength * sigma * sign
    marked = marked.astype(np.float32).astype(np.float64)

    forced = np.stack([nh1, carriers], axis=1)[nh1 >= 0]
    protected = np.zeros(len(V), bool)
    protected[carriers] = True
    base = base_vertex_count(job.options.base_ratio, len(V))

    def pm_progress(f: float, msg: str) -> None:
        report(0.15 + 0.8 * f, msg)

    pm, _ = build_progressive_mesh(
        marked, F, base_vertices=base, protected=protected, forced=forced, progress=pm_progress, adjacency=adj
    )
    return finish_embed(job, marked, pm, carriers, mesh_key(job, NAME, marked, adj, carriers))


# --------------------------------------------------------------------------- extraction

_FOUND_IN_WORDS = {
    "faces fingerprint": "the copy has the marked mesh's faces: each carrier read at its own vertex",
    "near their places": "the carriers sit near their marked places: each read at its own vertex",
    "nearest vertex": "the copy was re-ordered or re-meshed: each carrier read at the vertex nearest its place",
}


@dataclass(frozen=True)
class PaperDetail(VerdictDetail):
    """How the paper's reader found the carriers (``locate_carriers``): "faces fingerprint", "near their
    places" (both by index) or "nearest vertex" (by position)."""

    carriers: str

    def in_words(self) -> list[tuple[str, str]]:
        return [("How the carriers were found", _FOUND_IN_WORDS.get(self.carriers, self.carriers))]

    def numbers(self) -> list[tuple[str, str]]:
        return [("carriers found by", self.carriers)]


def locate_carriers(V: np.ndarray, F: np.ndarray, key: WatermarkKey) -> tuple[np.ndarray, str, str]:
    """Index of each carrier in V (-1 when not found), how it was found ("index" or "position") and
    why ("faces fingerprint", "near their places", "nearest vertex"; module docstring).

    V : (n, 3) float64, F : (m, 3) int64 of the suspect.
    """
    n = len(V)
    tol = key.mean_edge
    if key.faces_fingerprint and n == key.n_vertices:
        fp = face_fingerprint(F)
        for idx, known in (
            (key.carrier_index, key.faces_fingerprint),
            (key.carrier_pm_index, key.pm_faces_fingerprint),
        ):
            if fp == known:
                return idx.copy(), "index", "faces fingerprint"
    best = None
    for idx in (key.carrier_index, key.carrier_pm_index):
        inside = idx < n
        if inside.mean() < 0.5:
            continue
        d = np.linalg.norm(V[np.where(inside, idx, 0)] - key.carrier_position, axis=1)
        med = float(np.median(np.where(inside, d, np.inf)))
        if med <= max(0.25 * tol, INDEX_SHARE * key.bbox_diagonal) and (best is None or med < best[0]):
            best = (med, np.where(inside, idx, -1))
    if best is not None:
        return best[1], "index", "near their places"
    found = np.full(key.n_bits, -1, np.int64)
    near, d2 = nearest(V, key.carrier_position)
    ok = d2 <= tol * tol
    found[ok] = near[ok]
    return found, "position", "nearest vertex"


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
    pair = unique_values(rec2 * len(V) + nb)
    rec_u, nb_u = pair // len(V), pair % len(V)
    mu, sigma, cnt = _grouped_stats(V[nb_u], rec_u, k)
    c = V[np.where(good, idx, 0)]
    scale = np.abs(mu).max() + sigma.max() if k else 1.0
    usable = sigma > 1e-12 * max(scale, 1e-300)
    z = np.where(usable, (c - mu) / np.where(usable, sigma, 1.0), 0.0)
    score = z.sum(axis=1)
    score[~good | (cnt < 2)] = 0.0
    return score


def verify(vertices, faces, key: WatermarkKey, p_threshold: float = 1e-6, progress: Progress = None) -> Verdict:
    """Read the paper's mark from a suspect mesh (module docstring) with the key; ``progress(fraction,
    message)`` at its two stages (finding the carriers, reading them) and at the end.

    vertices : (n, 3) float64, faces : (m, 3) int64, any order and resolution."""
    report = progress or no_progress
    report(0.0, "finding the carriers")
    V, F = check_mesh(vertices, faces)
    idx, mode, how = locate_carriers(V, F, key)
    report(0.5, "reading the carriers")
    verdict = verdict_from_scores(carrier_scores(V, F, idx), key, mode, p_threshold, PaperDetail(how))
    found = np.flatnonzero(idx >= 0)
    verdict.places, verdict.place_bits = V[idx[found]].copy(), found
    report(1.0, "read")
    return verdict


def load_key_data(key: WatermarkKey) -> None:
    """The paper's key holds no data beyond its carriers: check there is one per bit."""
    if len(key.carrier_index) != key.n_bits:
        raise KeyFileError(
            f"this paper-scheme key has {len(key.carrier_index)} carriers for {key.n_bits} bits; it is damaged"
        )
    return None


SCHEME = Scheme(
    NAME,
    DEFAULT_STRENGTH,
    embed,
    verify,
    load_key_data,
    "the paper's Algorithms 1-2: one carrier vertex per bit, read against its 1-ring",
)
