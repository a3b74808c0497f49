"""``BlindKeyData``: what the in-memory key of a blind embedding records (nothing from the mesh).

The blind scheme writes no key file: the pass phrase is all the reader needs. ``pmwm.embed`` still
returns a ``WatermarkKey`` (the common result type; it holds the secret derived from the pass phrase,
never the pass phrase), whose ``data`` is this record of the word's shape and the strength.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ...errors import KeyFileError
from .word import CHECK_BITS, PAYLOAD_BITS


@dataclass(frozen=True)
class BlindKeyData:
    payload_bits: int  # L, one of PAYLOAD_BITS
    check_bits: int  # CHECK_BITS
    alpha: float  # margin of the bin mean

    def to_extra(self) -> dict:
        return asdict(self)

    @classmethod
    def from_extra(cls, d: dict) -> "BlindKeyData":
        try:
            out = cls(int(d["payload_bits"]), int(d["check_bits"]), float(d["alpha"]))
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise KeyFileError(f"the blind key lacks or garbles its data ({exc}); it is damaged") from None
        if out.payload_bits not in PAYLOAD_BITS or out.check_bits != CHECK_BITS or not 0 < out.alpha < 0.5:
            raise KeyFileError("the blind key's word or strength is out of range; it is damaged")
        return out
