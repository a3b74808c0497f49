"""Cho, Prost and Jung 2007 (IEEE TSP 55(1)): blind watermarking by the distribution of vertex norms.

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
embedding only as a diagnostic (e.g. the scale of a suspect copy). Moving vertices shifts the vertex
mean slightly; the embedder checks its own output with the decoder and, for any bin that the shift
pushed across the threshold, re-embeds with a larger margin (up to a few rounds).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .errors import KeyFileError, MeshError, PayloadError, ParameterError

_THRESHOLD = {"I": 0.5, "II": 1.0 / 3.0}


@dataclass(frozen=True)
class ChoKey:
    """What the Cho decoder needs (method, n_bits) plus the embedding parameters, for the record."""

    method: str  # "I" or "II"
    n_bits: int
    alpha: float
    rho_min: float  # at embedding, diagnostic only: detection recomputes it
    rho_max: float
    strength_step: float = 0.001

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ChoKey":
        try:
            return cls(
                method=str(d["method"]),
                n_bits=int(d["n_bits"]),
                alpha=float(d["alpha"]),
                rho_min=float(d["rho_min"]),
                rho_max=float(d["rho_max"]),
                strength_step=float(d.get("strength_step", 0.001)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise KeyFileError(f"not a Cho key ({exc}); pass the key returned by cho_embed") from exc


def _check_method(method: str) -> str:
    m = str(method).upper()
    if m not in _THRESHOLD:
        raise ParameterError(f"unknown Cho method {method!r}; use 'I' or 'II'")
    return m


def _as_bit_array(bits) -> np.ndarray:
    if isinstance(bits, str):
        if not bits or set(bits) - {"0", "1"}:
            raise PayloadError("bits must be a non-empty string of '0'/'1'; e.g. '0110'")
        return np.frombuffer(bits.encode(), dtype=np.uint8) - ord("0")
    arr = np.asarray(bits).ravel()
    if arr.size == 0 or not np.isin(arr, (0, 1)).all():
        raise PayloadError("bits must be a non-empty sequence of 0/1; e.g. [0, 1, 1, 0]")
    return arr.astype(np.uint8)


def _vertices(vertices) -> np.ndarray:
    v = np.array(vertices, dtype=np.float64, copy=True)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise MeshError(f"vertices must be a non-empty (n, 3) array, got shape {v.shape}")
    return v


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


def cho_embed(
    vertices, faces, bits, method: str = "I", alpha: float = 0.05, strength_step: float = 0.001
) -> tuple[np.ndarray, ChoKey]:
    """Embed ``bits`` (one per norm bin) with Cho's method I or II; returns (marked vertices, key).

    ``faces`` is unused (the method works on vertex positions only) but kept for a uniform
    signature. PayloadError when a bin holds no vertex (too many bits for the mesh).
    """
    method = _check_method(method)
    v = _vertices(vertices)
    b = _as_bit_array(bits)
    n_bits = len(b)
    if not 0 < alpha < _THRESHOLD[method]:
        raise ParameterError(f"alpha must be in (0, {_THRESHOLD[method]:.3f}), got {alpha}")
    if not 0 < strength_step < 1:
        raise ParameterError(f"strength_step must be in (0, 1), got {strength_step}")
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
        wrong = _decode(marked, n_bits, method) != b
        if not wrong.any():
            break
        margin = np.where(wrong, margin + 0.5 * alpha, margin)  # the centre shift ate the margin
    key = ChoKey(method, n_bits, float(alpha), bins.rho_min, bins.rho_max, float(strength_step))
    return marked, key


def _decode(v: np.ndarray, n_bits: int, method: str) -> np.ndarray:
    bins = _bins(v, n_bits)
    values = bins.r if method == "I" else 2.0 * bins.r - 1.0
    stat = _statistic(values, bins.bin, bins.count, method)
    return (np.nan_to_num(stat, nan=-1.0) > _THRESHOLD[method]).astype(np.uint8)


def cho_extract(vertices, faces, key: ChoKey) -> np.ndarray:
    """Blind decoding: (n_bits,) uint8 bits; an empty bin reads as 0. ``faces`` is unused."""
    if isinstance(key, dict):
        key = ChoKey.from_dict(key)
    return _decode(_vertices(vertices), int(key.n_bits), _check_method(key.method))


@dataclass(frozen=True)
class ChoMethod:
    """Uniform adapter for the bench: ``embed(v, f, bits, seed)`` and ``extract(v, f, key)``."""

    method: str = "I"
    alpha: float = 0.05
    strength_step: float = 0.001

    @property
    def name(self) -> str:
        return f"Cho {self.method}"

    def embed(self, vertices, faces, bits, seed: int | None = None) -> tuple[np.ndarray, ChoKey]:
        """Cho's method is keyless: ``seed`` is accepted for a uniform interface and ignored."""
        return cho_embed(vertices, faces, bits, self.method, self.alpha, self.strength_step)

    def extract(self, vertices, faces, key: ChoKey) -> np.ndarray:
        return cho_extract(vertices, faces, key)


def cho_method(name: str = "I", alpha: float = 0.05, strength_step: float = 0.001) -> ChoMethod:
    """``cho_method("I")`` / ``("II")`` (also "cho-i", "cho2", ...) -> adapter object."""
    key = str(name).upper().replace("CHO", "").strip(" -_")
    key = {"1": "I", "2": "II"}.get(key, key)
    return ChoMethod(_check_method(key), float(alpha), float(strength_step))


__all__ = ["ChoKey", "ChoMethod", "cho_embed", "cho_extract", "cho_method"]
