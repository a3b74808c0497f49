"""The robust scheme's key data: a typed object, its one reader (``RobustKeyData.from_extra``, run
when the key file is read) and its one writer (``to_extra``, the JSON form under the key's
``extra``: site arrays as lists, samples as base64 little-endian float32/uint32/float16)."""

from __future__ import annotations

import base64
import binascii
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...errors import KeyFileError
from ...register import SurfaceFrame
from ...bch import BCHCode
from .fields import tangent_frames

EXTRA_VERSION = 3  # written when the payload has a code; keys without one are written as version 2
READ_VERSIONS = (2, 3)


class Samples:
    """Each site's samples, padded to (S sites, K): u, v, stored height h (S, K) float64, vertex index
    (S, K) int64, validity ``mask`` (S, K) bool, the vertex's own unit normal in the site frame as
    (n.t1, n.t2) ``normal_tt`` (S, K, 2) (None in keys without it); and ``centre`` (S,), the slot of
    the site's own vertex (u = v = 0), -1 where it is not a sample. Built from flat per-sample arrays
    in site order, ``counts`` (S,) samples per site."""

    def __init__(self, counts: np.ndarray, u, v, h, vertex, normal_tt: Optional[np.ndarray] = None):
        S, K = len(counts), max(int(counts.max(initial=0)), 1)
        site = np.repeat(np.arange(S), counts)
        slot = np.arange(len(site)) - np.repeat(np.cumsum(counts) - counts, counts)
        self.mask = np.zeros((S, K), bool)
        self.mask[site, slot] = True
        self.u, self.v, self.h = (np.zeros((S, K)) for _ in range(3))
        self.vertex = np.zeros((S, K), np.int64)
        for name, val in (("u", u), ("v", v), ("h", h), ("vertex", vertex)):
            getattr(self, name)[site, slot] = val
        self.normal_tt = None
        if normal_tt is not None:
            self.normal_tt = np.zeros((S, K, 2))
            self.normal_tt[site, slot] = normal_tt
        at_site = self.mask & (self.u == 0) & (self.v == 0)
        self.centre = np.where(at_site.any(axis=1), np.argmax(at_site, axis=1), -1)

    def flat(self, name: str) -> np.ndarray:
        """One per-sample array in the flat site order it was built from."""
        return getattr(self, name)[self.mask]


def _pack(a: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def _unpack(text, dtype: str, shape: tuple) -> np.ndarray:
    raw = base64.b64decode(str(text).encode("ascii"), validate=True)
    a = np.frombuffer(raw, dtype=dtype)
    if a.size != int(np.prod(shape)):
        raise ValueError("sample data of the wrong size")
    return a.reshape(shape).astype(np.float64 if dtype[1] == "f" else np.int64)


@dataclass
class RobustKeyData:
    """Per site (S sites): the payload bit it carries ``bit`` (S,) int64, its chip (+-1) ``chip``
    (S,) float64, which readings were clean on the marked mesh (``usable``: by position;
    ``centre_ok``: at the site vertex; ``swirl_ok``: the swirl by index; ``index_ok``: by index;
    (S,) bool), its place ``origin`` and unit ``normal`` (S, 3) float64; the bump radius, amplitude
    and swirl amplitude; the samples; the registration frame (None only inside the embedder); the
    payload's error-correcting ``code`` (None: the sites carry the payload bits themselves; then ``bit``
    indexes the payload, else the codeword). ``t1``, ``t2`` (S, 3): the tangent frame, derived from the
    normals."""

    bit: np.ndarray
    chip: np.ndarray
    usable: np.ndarray
    centre_ok: np.ndarray
    swirl_ok: np.ndarray
    index_ok: np.ndarray
    origin: np.ndarray
    normal: np.ndarray
    radius: float
    amplitude: float
    swirl: float
    samples: Samples
    frame: Optional[SurfaceFrame]
    code: Optional[BCHCode] = None
    t1: np.ndarray = field(init=False, repr=False)
    t2: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.t1, self.t2 = tangent_frames(self.normal)

    def to_extra(self) -> dict:
        """The JSON form stored under the key's ``extra``."""
        sm = self.samples
        out = {
            "robust_version": EXTRA_VERSION if self.code is not None else 2,
            "radius": self.radius,
            "amplitude": self.amplitude,
            "swirl": self.swirl,
            "site_bit": self.bit.tolist(),
            "site_chip": self.chip.astype(int).tolist(),
            "site_usable": self.usable.astype(int).tolist(),
            "site_centre_ok": self.centre_ok.astype(int).tolist(),
            "site_swirl_ok": self.swirl_ok.astype(int).tolist(),
            "site_index_ok": self.index_ok.astype(int).tolist(),
            "site_origin": self.origin.tolist(),  # full precision: the centre sample's line passes through the vertex
            "site_normal": self.normal.tolist(),
            "sample_count": sm.mask.sum(axis=1).tolist(),
            "samples": _pack(np.stack([sm.flat("u"), sm.flat("v"), sm.flat("h")], axis=1), "<f4"),
            "sample_vertex": _pack(sm.flat("vertex"), "<u4"),
        }
        if sm.normal_tt is not None:
            out["sample_normal"] = _pack(sm.normal_tt[sm.mask], "<f2")
        if self.frame is not None:
            out["frame"] = self.frame.to_json()
        if self.code is not None:
            out["code"] = self.code.to_json()
        return out

    def coded_length(self, n_bits: int) -> int:
        """The bits the sites carry for a payload of ``n_bits``: the codeword's, or the payload's."""
        return n_bits if self.code is None else self.code.n

    @classmethod
    def from_extra(cls, x, n_bits: int, n_vertices: int) -> "RobustKeyData":
        """The data of a key's ``extra`` (a key of ``n_bits`` bits for a mesh of ``n_vertices``),
        checked; a KeyFileError naming the problem when it is damaged or of another format."""
        version = x.get("robust_version") if isinstance(x, dict) else None
        if version not in READ_VERSIONS:
            raise KeyFileError(
                f"this robust key has format {version!r}, this pmwm reads formats 2 and 3 "
                "(the first robust scheme's keys are not read any more); re-embed with this version"
            )
        try:
            site = {
                "bit": np.asarray(x["site_bit"], np.int64),
                "chip": np.asarray(x["site_chip"], np.float64),
                "usable": np.asarray(x["site_usable"], bool),
                "centre_ok": np.asarray(x["site_centre_ok"], bool),
                "swirl_ok": np.asarray(x.get("site_swirl_ok", np.zeros(len(x["site_bit"]))), bool),
                "index_ok": np.asarray(x.get("site_index_ok", x["site_usable"]), bool),
                "origin": np.asarray(x["site_origin"], np.float64).reshape(-1, 3),
                "normal": np.asarray(x["site_normal"], np.float64).reshape(-1, 3),
            }
            radius, amplitude, swirl = float(x["radius"]), float(x["amplitude"]), float(x.get("swirl", 0.0))
            counts = np.asarray(x["sample_count"], np.int64)
            total = int(counts.sum())
            if np.ndim(counts) != 1 or len(counts) != len(site["bit"]) or counts.min(initial=0) < 0:
                raise ValueError("sample counts")
            uvh = _unpack(x["samples"], "<f4", (total, 3))
            vertex = _unpack(x["sample_vertex"], "<u4", (total,))
            normal_tt = _unpack(x["sample_normal"], "<f2", (total, 2)) if "sample_normal" in x else None
            frame = SurfaceFrame.from_json(x["frame"])
            code = BCHCode.from_json(x["code"]) if version == 3 else None
            if code is not None and code.k != n_bits:
                raise ValueError("the payload code is for another payload length")
            if not all(np.isfinite(site[k]).all() for k in ("origin", "normal", "chip")):
                raise ValueError("site places, normals or chips are not finite numbers")
            if not (np.isfinite(uvh).all() and radius > 0 and amplitude > 0 and np.isfinite(swirl)) or (
                normal_tt is not None and not (np.abs(normal_tt) <= 1.0).all()
            ):
                raise ValueError("sample values")
        except (KeyError, TypeError, ValueError, OverflowError, AttributeError, binascii.Error) as exc:
            raise KeyFileError(f"the robust key lacks or garbles its site data ({exc}); it is damaged") from None
        n = len(site["bit"]) if np.ndim(site["bit"]) == 1 else 0
        if (
            n == 0
            or any(np.ndim(site[k]) == 0 or len(site[k]) != n for k in site)
            or site["bit"].min() < 0
            or site["bit"].max() >= (n_bits if code is None else code.n)
            or vertex.max(initial=0) >= n_vertices
        ):
            raise KeyFileError("the robust key's site data are inconsistent; it is damaged")
        samples = Samples(counts, uvh[:, 0], uvh[:, 1], uvh[:, 2], vertex, normal_tt)
        return cls(**site, radius=radius, amplitude=amplitude, swirl=swirl, samples=samples, frame=frame, code=code)
