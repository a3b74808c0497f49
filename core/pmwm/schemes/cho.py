"""Cho, Prost and Jung 2007 (IEEE TSP 55(1)) as schemes "cho1" and "cho2": blind watermarking by the
distribution of vertex norms.

The paper pmwm implements compares itself with this method; the benchmark protocol's published
anchor is also Cho's. Both methods (DESIGN.md section 6, last paragraph):

- rho_i = |v_i - c| about the vertex mean c; N equal-width bins over [rho_min, rho_max], one bit per
  bin; inside bin n the norms are normalised to r in [0, 1].
- Method I: r -> r**k. Bit 1 needs the bin mean > 1/2 + alpha (k < 1), bit 0 needs < 1/2 - alpha
  (k > 1). Decoder: bin mean > 1/2.
- Method II: s = 2r - 1 in [-1, 1], s -> sign(s) |s|**k. Bit 1 needs the second moment E[s^2]
  > 1/3 + alpha, bit 0 < 1/3 - alpha (the uniform distribution has 1/3; we use the moment about 0,
  which Cho calls the variance since the bin mean is ~0, and which is monotone in k). Decoder:
  E[s^2] > 1/3.
- k is stepped by ``strength_step`` from 1 until the bin condition holds. We find the same smallest
  step count by bisection (the statistics are monotone in k), vectorised over all bins at once.
- Only the norms change (vertices move radially). r = 0 and r = 1 are fixed points of both maps, so
  the rho_min and rho_max vertices never move and the decoder's range is preserved.

The decoder is blind: it recomputes c, rho_min and rho_max from the suspect mesh, which makes it
invariant to similarity transforms and vertex/face reordering. The key records rho_min/rho_max at
embedding only as a diagnostic (e.g. the scale of a suspect copy). ``strength`` is alpha (0.05 by
default). As in pmwm's other schemes, the bits embedded are the payload XOR a keyed sequence (so an
unmarked mesh reads as chance and the binomial p-value is exact) and the marked mesh is float32. Moving
vertices shifts the vertex mean slightly; the embedder checks its own output with the decoder and, for any
bin that the shift pushed across the threshold, re-embeds with a larger margin (up to a few rounds).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np

from ..adjacency import build_adjacency
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
from ..errors import KeyFileError, MeshError, PayloadError
from ..key import WatermarkKey, keyed_bits
from ..progressive import base_vertex_count, build_progressive_mesh
from ..validate import check_mesh

DEFAULT_ALPHA = 0.05
STRENGTH_STEP = 0.001  # the grid of the exponent k (Cho's step)


@dataclass(frozen=True)
class ChoKeyData:
    """What the Cho decoder needs (method) plus the embedding parameters, for the record."""

    method: str  # "I" or "II"
    alpha: float
    rho_min: float  # at embedding, diagnostic only: detection recomputes it
    rho_max: float
    strength_step: float = STRENGTH_STEP

    def to_extra(self) -> dict:
        return asdict(self)

    @classmethod
    def from_extra(cls, d: dict) -> "ChoKeyData":
        try:
            out = cls(
                method=str(d["method"]),
                alpha=float(d["alpha"]),
                rho_min=float(d["rho_min"]),
                rho_max=float(d["rho_max"]),
                strength_step=float(d.get("strength_step", STRENGTH_STEP)),
            )
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise KeyFileError(f"the Cho key lacks or garbles its data ({exc}); it is damaged") from None
        if out.method not in _THRESHOLD or not 0 < out.alpha < _THRESHOLD[out.method]:
            raise KeyFileError("the Cho key's method or alpha is out of range; it is damaged")
        return out


_THRESHOLD = {"I": 0.5, "II": 1.0 / 3.0}
_STATISTIC = {"I": "mean", "II": "variance"}


@dataclass(frozen=True)
class ChoDetail(VerdictDetail):
    """How Cho's reader read a suspect: the method ("I": each bin's mean, "II": its variance), the
    bins (one per bit) and how many of them held no vertex (erasures)."""

    method: str
    bins: int
    empty_bins: int

    def in_words(self) -> list[tuple[str, str]]:
        return [
            (
                "How it was read",
                f"from the spread of the vertices' distances to their centre, over the whole "
                f"surface (Cho et al. 2007, method {self.method})",
            ),
            ("Parts read", f"{self.bins - self.empty_bins} of the {self.bins} distance ranges that carry the mark"),
        ]

    def numbers(self) -> list[tuple[str, str]]:
        return [
            ("method", f"{self.method} (bin {_STATISTIC[self.method]})"),
            ("bins read", f"{self.bins - self.empty_bins}/{self.bins}"),
        ]


@dataclass
class _Bins:
    centre: np.ndarray
    rho: np.ndarray
    unit: np.ndarray
    bin: np.ndarray  # (n,) bin of each vertex
    lo: np.ndarray  # (N,) lower edge of each bin
    width: float
    r: np.ndarray  # (n,) normalised norm in [0, 1]
    count: np.ndarray  # (N,) vertices per bin
    rho_min: float
    rho_max: float


def _bins(v: np.ndarray, n_bits: int, centre: np.ndarray | None = None) -> _Bins:
    c = v.mean(axis=0) if centre is None else centre
    d = v - c
    rho = np.linalg.norm(d, axis=1)
    unit = np.divide(d, rho[:, None], out=np.zeros_like(d), where=rho[:, None] > 0)
    rmin, rmax = float(rho.min()), float(rho.max())
    width = (rmax - rmin) / n_bits
    if width <= 0:
        raise MeshError("all vertices are at the same distance from their mean; Cho's method needs a range")
    b = np.clip(np.floor((rho - rmin) / width).astype(np.int64), 0, n_bits - 1)
    lo = rmin + width * np.arange(n_bits)
    r = np.clip((rho - lo[b]) / width, 0.0, 1.0)
    count = np.bincount(b, minlength=n_bits)
    return _Bins(c, rho, unit, b, lo, width, r, count, rmin, rmax)


def _transform(r: np.ndarray, k: np.ndarray, method: str) -> np.ndarray:
    """Method I: r**k in [0, 1]; method II: sign(s)|s|**k with s = 2r - 1 in [-1, 1]."""
    if method == "I":
        return r**k
    s = 2.0 * r - 1.0
    return np.sign(s) * np.abs(s) ** k


def _statistic(values: np.ndarray, b: np.ndarray, count: np.ndarray, method: str) -> np.ndarray:
    x = values if method == "I" else values**2
    s = np.bincount(b, weights=x, minlength=len(count))
    return np.divide(s, count, out=np.full(len(count), np.nan), where=count > 0)


def _solve_k(bins: _Bins, bits: np.ndarray, targets: np.ndarray, method: str, step: float) -> np.ndarray:
    """Per bin, the k nearest 1 on the grid 1 -+ j*step meeting its target (bisection on j)."""
    one = bits == 1
    j_max = np.where(one, int(np.floor((1.0 - step) / step)), int(round(100.0 / step)))
    lo = np.zeros(len(bits), dtype=np.int64)
    hi = j_max.astype(np.int64)

    def k_of(j: np.ndarray) -> np.ndarray:
        return np.where(one, 1.0 - j * step, 1.0 + j * step)

    def satisfied(j: np.ndarray) -> np.ndarray:
        stat = _statistic(_transform(bins.r, k_of(j)[bins.bin], method), bins.bin, bins.count, method)
        return np.where(one, stat > targets, stat < targets)

    while np.any(lo < hi):
        mid = (lo + hi) // 2
        ok = satisfied(mid)
        hi = np.where(ok & (lo < hi), mid, hi)
        lo = np.where(~ok & (lo < hi), mid + 1, lo)
    return k_of(lo)


def _embed_bits(
    v: np.ndarray, b: np.ndarray, method: str, alpha: float, strength_step: float
) -> tuple[np.ndarray, _Bins]:
    """Marked vertices (n, 3) float64 (float32-exact) carrying ``b`` (N,) uint8, one bit per norm bin,
    and the bins of the input. PayloadError when a bin holds no vertex (too many bits for the mesh)."""
    n_bits = len(b)
    if not 0 < alpha < _THRESHOLD[method]:
        raise PayloadError(f"Cho's strength (alpha) must be in (0, {_THRESHOLD[method]:.3f}), got {alpha}")
    bins = _bins(v, n_bits)
    if (bins.count == 0).any():
        empty = int(np.flatnonzero(bins.count == 0)[0])
        raise PayloadError(f"norm bin {empty} of {n_bits} holds no vertex; embed fewer bits")
    thr = _THRESHOLD[method]
    margin = np.full(n_bits, float(alpha))
    marked = v
    for _ in range(6):
        targets = np.where(b == 1, thr + margin, thr - margin)
        k = _solve_k(bins, b, targets, method, strength_step)
        mapped = _transform(bins.r, k[bins.bin], method)
        r_new = mapped if method == "I" else 0.5 * (mapped + 1.0)
        rho_new = bins.lo[bins.bin] + bins.width * r_new
        moved = r_new != bins.r  # r = 0 and r = 1 (the extremes) stay bit-exact
        marked = np.where(moved[:, None], bins.centre + bins.unit * rho_new[:, None], v)
        marked = marked.astype(np.float32).astype(np.float64)  # as every marked mesh is stored
        wrong = (_statistics(marked, n_bits, method) > thr) != (b == 1)
        if not wrong.any():
            break
        margin = np.where(wrong, margin + 0.5 * alpha, margin)  # the centre shift ate the margin
    return marked, bins


def _statistics(v: np.ndarray, n_bits: int, method: str) -> np.ndarray:
    """Each norm bin's statistic (N,) float64 (NaN for an empty bin): the bin mean of r (method I)
    or of s^2 (method II)."""
    bins = _bins(v, n_bits)
    values = bins.r if method == "I" else 2.0 * bins.r - 1.0
    return _statistic(values, bins.bin, bins.count, method)


def _embed(method: str, name: str):
    def embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
        """Watermark a mesh with Cho's method (module docstring); vertices : (n, 3) float64, faces :
        (m, 3) int64 (kept as they are). The progressive mesh, if asked for, is built on the marked mesh."""
        job = start_embed(vertices, faces, options, progress, name, DEFAULT_ALPHA)
        V, F = job.vertices, job.faces
        job.report(0.0, "marking the norm distribution")
        w = job.bits ^ keyed_bits(job.secret, "scramble", len(job.bits))
        marked, bins = _embed_bits(V, w, method, job.strength, STRENGTH_STEP)
        adj = build_adjacency(F, len(V))
        base = base_vertex_count(job.options.base_ratio, len(V))
        pm = None
        if job.options.progressive:
            pm, _ = build_progressive_mesh(
                marked, F, base_vertices=base, adjacency=adj, progress=lambda f, m: job.report(0.1 + 0.85 * f, m)
            )
        data = ChoKeyData(method, job.strength, bins.rho_min, bins.rho_max, STRENGTH_STEP)
        none = np.zeros(0, np.int64)
        return finish_embed(job, marked, pm, none, mesh_key(job, name, marked, adj, none, data))

    return embed


def _verify(method: str):
    def verify(vertices, faces, key: WatermarkKey, p_threshold: float = 1e-6, progress: Progress = None) -> Verdict:
        """Blind reading of Cho's method: every bin's statistic against its threshold, from the
        suspect alone (any order, pose or scale); an empty bin is an erasure. ``progress(fraction,
        message)`` at the start and the end (one short stage)."""
        report = progress or no_progress
        report(0.0, "reading the bins")
        V, _ = check_mesh(vertices, faces)
        if len(V) < 2:
            raise MeshError("the suspect has fewer than two vertices; Cho's method reads a distribution")
        stat = _statistics(V, key.n_bits, method)
        score = np.nan_to_num(stat - _THRESHOLD[method], nan=0.0)
        detail = ChoDetail(method, key.n_bits, int(np.isnan(stat).sum()))
        verdict = verdict_from_scores(score, key, "blind", p_threshold, detail)
        report(1.0, "read")
        return verdict

    return verify


def load_key_data(key: WatermarkKey) -> ChoKeyData:
    """The Cho data of a key, checked against the key's scheme name."""
    data = ChoKeyData.from_extra(key.extra if isinstance(key.extra, dict) else {})
    if {"I": "cho1", "II": "cho2"}[data.method] != key.scheme:
        raise KeyFileError(f"this key says scheme {key.scheme!r} but holds Cho method {data.method}; it is damaged")
    return data


CHO1 = Scheme(
    "cho1",
    DEFAULT_ALPHA,
    _embed("I", "cho1"),
    _verify("I"),
    load_key_data,
    "Cho et al. 2007, method I: the mean of each vertex-norm bin",
)
CHO2 = Scheme(
    "cho2",
    DEFAULT_ALPHA,
    _embed("II", "cho2"),
    _verify("II"),
    load_key_data,
    "Cho et al. 2007, method II: the variance of each vertex-norm bin",
)
