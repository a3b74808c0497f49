"""``BlindDetail``: how the blind reader read a suspect (``Verdict.detail`` of the blind scheme).

The word read, the frames and the mesh it was read on say nothing of the payload unless the mark was
read: the word (payload + check bits) is kept only then.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from ...base import Verdict, VerdictDetail
from .config import READER


def mesh_read(mesh: str) -> str:
    """The mesh a verdict was read on (``BlindDetail.mesh``) in words: "" for the suspect itself."""
    if mesh == "suspect":
        return ""
    if mesh.startswith("smoothing:"):
        steps = int(mesh.split(":", 1)[1])
        if steps < 0:
            return f"read after {-steps} steps of Laplacian smoothing ({READER.denoise.lam:g} each) against noise"
        return f"read with {steps} steps of Laplacian smoothing ({READER.unsmooth.lam:g} each) undone"
    return f"read on the mesh it was subdivided from: {mesh} undone"


@dataclass(frozen=True)
class BlindDetail(VerdictDetail):
    """The blind reading kept (``pmwm.schemes.blind.decide``).

    payload_bits, check_bits: the word's shape (L + 32). mesh: "suspect", the subdivision steps undone
    ("loop", "sqrt3 + loop", ...) or "smoothing:k" (k steps of smoothing undone; k < 0: -k steps taken,
    a "denoised" frame). frame: its name ("own", "refined", "crop", "crop-2", ..., "denoised",
    "denoised-refined"), frame_index of ``frames`` read, reserve_frames of them read with the candidates
    the p-value's budget leaves; chase_bits, candidates: the Chase search (candidates per kind in the
    kept frame). payload_kind ("text" | "bits"), word (payload + check bits after the search) and
    word_read (the hard decisions before it): only when the mark was read, else None.
    """

    counted = "check bits"

    payload_bits: int
    check_bits: int
    mesh: str
    frame: str
    frame_index: int
    frames: int
    chase_bits: int
    reserve_frames: int
    candidates: int
    payload_kind: Optional[str] = None
    word: Optional[str] = None
    word_read: Optional[str] = None

    def headline_note(self, verdict: Verdict) -> str:
        if verdict.payload_confirmed:
            return f"{self.payload_bits}-bit payload read (blind)"
        return "no payload read (blind)"

    def notes(self) -> list[str]:
        read_on = mesh_read(self.mesh)
        return [read_on] if read_on else []

    def in_words(self) -> list[tuple[str, str]]:
        rows = [
            (
                "How it was read",
                "from the spread of the vertices' distances to the surface's centre, with "
                "the pass phrase alone (no key file)",
            )
        ]
        read_on = mesh_read(self.mesh)
        if read_on:
            rows.append(("Read on", read_on))
        return rows

    def numbers(self) -> list[tuple[str, str]]:
        return [
            ("word", f"{self.payload_bits} payload + {self.check_bits} check bits"),
            ("payload kind", self.payload_kind or "-"),
            ("mesh read", self.mesh),
            ("frame", f"{self.frame} ({self.frame_index + 1} of {self.frames})"),
            ("reserve frames", str(self.reserve_frames)),
            ("Chase bits", str(self.chase_bits)),
            ("candidates per kind", str(self.candidates)),
        ]
