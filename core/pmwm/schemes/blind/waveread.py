"""The reading of the keyed-waves carrier (``waves``): hypotheses, the lattice fit, decoding, the p-value.

A hypothesis is a sign choice of the solid's frame (``solid.sign_choices``, chosen without the pass phrase), a
mesh (the suspect, or the suspect with ``tau`` steps of smoothing undone, uniform Laplacian at lambda 0.5 or
MeshLab's cotangent Laplacian: z extrapolated to second order from one and two steps of the suspect's own
smoothing, ``UNDO_STEPS``), a public step (``waves.STEPS``) and a payload length (``LENGTHS``, whole bytes). The
lattice fit, mean cos(4 pi (z / Delta - d)) over the word's projections, is near 1 where the hypothesis is the
embedder's and near 0 elsewhere; it ranks them, and the best ``DECODED`` are decoded: the word is the payload
and its ``CHECK_BITS`` keyed check bits under a convolutional code (``pmwm.convcode``, rate ``RATE``), read with
soft decisions (1 - 4 |z / Delta - d - nearest integer|, the log-likelihood ratio of the bit up to a scale) by
the Viterbi decoder, and the check bits are compared for both payload kinds. The fit uses the key, so the
p-value pays for every hypothesis there was, decoded or not (``plan.waves_p_value``): their count times 2 kinds,
times P(Binomial(CHECK_BITS, 1/2) >= check bits matched).

The suspect as it is comes first, then its smoothing undone; a sign choice's readings end at the first
marked one. The algorithm: docs/schemes/blind.md; measurements: docs/decisions/141-keyed-waves-carrier.md
and docs/decisions/142-soft-decoded-word.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Optional

import numpy as np

from ... import metrics
from ...base import Verdict, VerdictDetail
from ...convcode import coded_length, decode, encode
from ...errors import MeshError
from ...smoothing import cotangent_step, mean_operator
from ...validate import check_mesh
from . import plan, waves, word
from .solid import Frame, sign_choices, solid_frame

__all__ = ["CHECK_BITS", "LENGTHS", "RATE", "UNDO_STEPS", "WavesDetail", "coded_bits", "hypotheses", "read", "word_of"]

CHECK_BITS = 64
CHECK_LABEL = "blind-waves-check"
LENGTHS = tuple(range(8, 97, 8))  # payload bits the carrier holds (text of 1 to 12 bytes)
UNDO_STEPS = tuple(0.5 * k for k in range(1, 25))  # steps the reader may undo (uniform: of lambda 0.5; MeshLab's)
UNDO_LAM = 0.5
UNDO_KINDS = ("uniform", "cotangent")
RATE = "2/3"  # the convolutional code's rate (``pmwm.convcode.PUNCTURE``)
DECODED = 16  # hypotheses decoded per set of meshes read (the best lattice fits)


def coded_bits(length: int) -> int:
    """The bits written for a payload of ``length`` bits: its coded word with the CHECK_BITS check bits."""
    return coded_length(length + CHECK_BITS, RATE)


def word_of(secret: str, kind: str, payload: np.ndarray) -> np.ndarray:
    """The word written, (``coded_bits(L)``,) uint8: the payload (L,) and its keyed check bits, coded."""
    check = word.check_bits(secret, kind, payload, CHECK_BITS, CHECK_LABEL)
    return encode(np.concatenate([payload, check]).astype(np.uint8), RATE)


def hypotheses(n_signs: int) -> int:
    """Every candidate word a reading weighs with ``n_signs`` sign choices (the union bound's count)."""
    meshes = 1 + len(UNDO_KINDS) * len(UNDO_STEPS)
    return n_signs * meshes * len(waves.STEPS) * len(LENGTHS) * len(word.KINDS)


@dataclass(frozen=True)
class WavesDetail(VerdictDetail):
    """How the keyed-waves reader read a suspect: payload_bits + check_bits, the sign choice of the frame
    (1-based, of ``signs`` tried), ``mesh`` ("suspect" or "uniform:tau" / "cotangent:tau", the smoothing
    undone), the step, the hypotheses paid for; payload_kind and word only when the mark was read."""

    counted = "check bits"

    payload_bits: int
    check_bits: int
    sign: int
    signs: int
    mesh: str
    step: float
    hypotheses: int
    payload_kind: Optional[str] = None
    word: Optional[str] = None

    def headline_note(self, verdict: Verdict) -> str:
        if verdict.payload_confirmed:
            return f"{self.payload_bits}-bit payload read (blind)"
        return "no payload read (blind)"

    def _undone(self) -> str:
        if self.mesh == "suspect":
            return ""
        kind, steps = self.mesh.split(":")
        if kind == "uniform":
            return f"read with {steps} steps of uniform Laplacian smoothing ({UNDO_LAM:g} each) undone"
        return f"read with {steps} steps of cotangent Laplacian smoothing (MeshLab's) undone"

    def notes(self) -> list[str]:
        return [self._undone()] if self._undone() else []

    def in_words(self) -> list[tuple[str, str]]:
        rows = [
            (
                "How it was read",
                "from keyed waves in the solid's shape, with the pass phrase alone (no key file)",
            )
        ]
        if self._undone():
            rows.append(("Read on", self._undone()))
        return rows

    def numbers(self) -> list[tuple[str, str]]:
        return [
            ("carrier", "keyed waves"),
            ("word", f"{self.payload_bits} payload + {self.check_bits} check bits"),
            ("code", f"convolutional, rate {RATE}, constraint length 7, soft Viterbi decoding"),
            ("payload kind", self.payload_kind or "-"),
            ("mesh read", self.mesh),
            ("frame signs", f"{self.sign} of {self.signs}"),
            ("step", f"{self.step:.3g}"),
            ("hypotheses", str(self.hypotheses)),
        ]


@dataclass
class _Reading:
    p_one: float
    matches: int
    length: int
    kind: str
    candidate: np.ndarray  # (L + CHECK_BITS,) the payload and check bits decoded
    score: np.ndarray  # (coded_bits(L),) the soft decisions, > 0 where the scrambled bit read is 1
    sign: int
    mesh: str
    step: float


def _smoothed(V: np.ndarray, F: np.ndarray) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(kind, the suspect after one step, after two steps) of each kind of smoothing the reader undoes: the
    uniform neighbour mean at ``UNDO_LAM``, and MeshLab's cotangent step (``smoothing.cotangent_step``)."""
    op = mean_operator(F, len(V))
    U1 = V + UNDO_LAM * (op @ V - V)
    C1 = cotangent_step(V, F)
    return [("uniform", U1, U1 + UNDO_LAM * (op @ U1 - U1)), ("cotangent", C1, cotangent_step(C1, F))]


def _undone(smoothed, F: np.ndarray, w: waves.Waves, frame: Frame, y0: np.ndarray) -> Iterator[tuple[str, np.ndarray]]:
    """(mesh, y (P,)) of the suspect with smoothing undone, to second order in the steps, in ``frame``, from
    the suspect's own smoothed copies ``smoothed`` (``_smoothed``)."""
    for kind, V1, V2 in smoothed:
        y1 = waves.solid_integrals(V1, F, w, solid_frame(V1, F).aligned(frame))
        y2 = waves.solid_integrals(V2, F, w, solid_frame(V2, F).aligned(frame))
        d1, d2 = y1 - y0, y2 - 2 * y1 + y0
        for tau in UNDO_STEPS:
            yield f"{kind}:{tau:g}", y0 - tau * d1 + tau * (tau + 1) / 2 * d2


def _decode(meshes, spreads, secret: str, sign: int) -> Optional[_Reading]:
    """The best reading among the DECODED best lattice fits over ``meshes`` [(mesh, y)] x steps x lengths."""
    fits = []
    for mesh, y in meshes:
        for L, spread in spreads.items():
            z = spread.vectors @ y
            for step in waves.STEPS:
                e = z / step - spread.dither
                fits.append((float(np.mean(np.cos(4 * np.pi * e))), mesh, L, step, e))
    fits.sort(key=lambda h: -h[0])
    best = None
    for L in LENGTHS:  # (the Viterbi decoder reads the fits of one length together)
        chosen = [f for f in fits[:DECODED] if f[2] == L]
        if not chosen:
            continue
        unscramble = 1.0 - 2.0 * spreads[L].scramble
        soft = np.array([1 - 4 * np.abs(f[4] - np.round(f[4])) for f in chosen])  # > 0: the scrambled bit is 0
        for (_, mesh, _, step, _), info, score in zip(chosen, decode(soft * unscramble, L + CHECK_BITS, RATE), soft):
            for kind in word.KINDS:
                check = word.check_bits(secret, kind, info[:L], CHECK_BITS, CHECK_LABEL)
                m = int(np.sum(info[L:] == check))
                p = metrics.binomial_tail(m, CHECK_BITS)
                if best is None or p < best.p_one:
                    best = _Reading(p, m, L, kind, info, -score, sign, mesh, step)
    return best


def read(vertices, faces, secret: str, p_threshold: float = 1e-6, signs: Optional[int] = None) -> Verdict:
    """The keyed-waves reading of a suspect, vertices (n, 3), faces (m, 3), with a secret
    (``word.derive_secret``): its verdict, p-value ``plan.waves_p_value`` (over every sign choice of
    ``solid.sign_choices``, though a marked reading stops early). ``signs``: try only the first so many
    sign choices (experiments' speed: a reading that can miss marks, never find more; the p-value still
    pays for all)."""
    V, F = check_mesh(vertices, faces)
    if len(F) == 0:
        raise MeshError("the suspect has no faces; the blind scheme reads a surface")
    w = waves.waves_of(secret)
    spreads = {L: waves.spread_of(secret, coded_bits(L)) for L in LENGTHS}
    try:
        base = solid_frame(V, F)
    except ValueError:
        return _verdict(None, 1, p_threshold)
    choices = sign_choices(base)
    n_hyp = hypotheses(len(choices))
    best = None
    smoothed: list = []  # (the suspect's smoothed copies: made once, when a sign choice first needs them)
    for si, signs_k in enumerate(choices[:signs] if signs else choices):
        frame = base.flipped(signs_k)
        y0 = waves.solid_integrals(V, F, w, frame)

        def undone():
            if not smoothed:
                smoothed.extend(_smoothed(V, F))
            return _undone(smoothed, F, w, frame, y0)

        for meshes in (lambda: [("suspect", y0)], undone):
            r = _decode(meshes(), spreads, secret, si)
            if r is not None and (best is None or r.p_one < best.p_one):
                best = r
            if best is not None and plan.waves_p_value(best.p_one, n_hyp) < p_threshold:
                return _verdict(best, len(choices), p_threshold)
    return _verdict(best, len(choices), p_threshold)


def _verdict(r: Optional[_Reading], n_signs: int, p_threshold: float) -> Verdict:
    n_hyp = hypotheses(n_signs)
    if r is None:  # (no solid: an open sheet has no frame)
        detail = WavesDetail(0, CHECK_BITS, 0, 0, "suspect", 0.0, n_hyp)
        return Verdict(False, 1.0, "", None, 0, CHECK_BITS, 0.0, 0, CHECK_BITS, "blind", p_threshold, False, detail)
    p = plan.waves_p_value(r.p_one, n_hyp)
    marked = bool(p < p_threshold)
    L = r.length
    payload = r.candidate[:L]
    detail = WavesDetail(
        L,
        CHECK_BITS,
        r.sign + 1,
        n_signs,
        r.mesh,
        r.step,
        n_hyp,
        r.kind if marked else None,
        "".join(map(str, r.candidate.tolist())) if marked else None,
    )
    return Verdict(
        marked=marked,
        p_value=p,
        bits="".join(map(str, payload.tolist())) if marked else "",
        payload=word.text_of(payload) if marked and r.kind == "text" else None,
        matches=r.matches,
        bit_errors=CHECK_BITS - r.matches,
        correlation=float(2 * r.matches / CHECK_BITS - 1),
        carriers_found=CHECK_BITS,
        carriers_total=CHECK_BITS,
        mode="blind",
        p_threshold=p_threshold,
        payload_confirmed=marked,
        detail=detail,
        scores=r.score,
        places=np.zeros((0, 3)),
        place_bits=np.zeros(0, np.int64),
    )
