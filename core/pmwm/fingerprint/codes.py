"""The codes and the decision rule of fingerprinting.

Codes. Each recipient gets a keyed, independent, uniform +-1 codeword over the asset's S sites
(spread-spectrum), drawn from the fingerprinting key's secret and the recipient's id: a copy marks
site s with the bump and swirl sign c[s].

Decision. The tracer reads one weighted soft value per site, x (S,) (the site's soft value over its
variance, 0 where unread: ``pmwm.schemes.robust.read_scores`` with one "bit" per site). Recipient j
scores T_j = <x, c_j> / |x|. For an innocent recipient c_j is independent of x and uniform, so T_j is a
Rademacher sum with unit-norm weights: mean 0, variance 1, and P(T_j >= t) <= exp(-t^2 / 2) for every
x (Hoeffding; no Gaussian approximation). That bound, corrected for the N recipients of the registry
(Bonferroni, p = min(1, N exp(-t^2/2))), is each recipient's p-value; recipients with p below the
threshold (1e-6, as ``pmwm verify``) are named. A copy read in the best of several poses (a mirror image,
a symmetric shape) pays for them as well: the p-values are multiplied by the poses the reader may try. The
chance that any innocent recipient is named in one trace is below the threshold, whatever the copy.

Averaging collusion. k copies averaged vertex by vertex give x ~ (c_1 + ... + c_k) / k (marking and
reading are linear in the signs), so each colluder scores about sqrt(S_read / k) instead of
sqrt(S_read): two copies name both, three at least one while sqrt(S_read / 3) stays above the
threshold (6.8 for 10,000 recipients at 1e-6).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import PayloadError
from ..key import derive_seed
from ..schemes.robust.read import pose_bound

__all__ = [
    "codeword",
    "codewords",
    "pack_codeword",
    "unpack_codewords",
    "check_recipient_id",
    "correlation_scores",
    "p_values",
    "Accusation",
    "accuse",
    "key_id",
]

RECIPIENT_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")


def key_id(secret: str) -> str:
    """A public identifier (16 hex digits) of a fingerprinting key, stored in its registries."""
    return hashlib.sha256(f"pmwm-fingerprint-id:{secret}".encode()).hexdigest()[:16]


def check_recipient_id(rid: str) -> str:
    """``rid`` when it is a valid recipient id (it names files: letters, digits, '.', '_', '-', at
    most 64, not starting with a dot or dash); a PayloadError otherwise."""
    if not isinstance(rid, str) or not RECIPIENT_ID.fullmatch(rid):
        raise PayloadError(
            f"recipient id {rid!r} is not valid: use 1-64 letters, digits, '.', '_' or '-', "
            "starting with a letter or digit"
        )
    return rid


def codeword(secret: str, recipient: str, n_sites: int) -> np.ndarray:
    """The recipient's keyed codeword (n_sites,) int8 of +-1."""
    bits = np.random.default_rng(derive_seed(secret, f"fingerprint-code:{recipient}")).integers(0, 2, n_sites)
    return (2 * bits - 1).astype(np.int8)


def codewords(secret: str, recipients, n_sites: int) -> np.ndarray:
    """The codewords (N, n_sites) int8 of the recipients, in order."""
    out = np.empty((len(recipients), n_sites), np.int8)
    for i, rid in enumerate(recipients):  # one keyed stream per recipient (N, not per vertex)
        out[i] = codeword(secret, rid, n_sites)
    return out


def pack_codeword(c: np.ndarray) -> str:
    """A +-1 codeword (S,) as hex (bit 1 = +1), as stored in the registry."""
    return np.packbits(np.asarray(c) > 0).tobytes().hex()


def unpack_codewords(texts, n_sites: int) -> np.ndarray:
    """Codewords (N, n_sites) int8 from their hex form; ValueError when one is malformed."""
    nbytes = (n_sites + 7) // 8
    raw = bytes.fromhex("".join(texts)) if texts else b""
    if len(raw) != nbytes * len(texts) or any(len(t) != 2 * nbytes for t in texts):
        raise ValueError(f"codewords are not {n_sites} bits each")
    bits = np.unpackbits(np.frombuffer(raw, np.uint8).reshape(len(texts), nbytes), axis=1)[:, :n_sites]
    return (2 * bits.astype(np.int8) - 1).astype(np.int8)


def correlation_scores(x: np.ndarray, C: np.ndarray) -> np.ndarray:
    """T (N,) float64: each codeword's normalised correlation with the weighted soft readings x (S,)
    (0 where unread); all 0 when nothing was read. C : (N, S) int8."""
    x = np.nan_to_num(np.asarray(x, np.float64))
    norm = float(np.sqrt(x @ x))
    if norm == 0 or len(C) == 0:
        return np.zeros(len(C))
    return np.asarray(C @ (x / norm), np.float64)


def p_values(T: np.ndarray, n_recipients: int) -> np.ndarray:
    """Each score's p-value corrected for ``n_recipients`` (Bonferroni over the Hoeffding bound
    exp(-T^2/2) of an innocent's score), in [0, 1]; 1 for T <= 0. T : (N,) float64."""
    T = np.asarray(T, np.float64)
    log_p = np.where(T > 0, -0.5 * T * T, 0.0) + math.log(max(n_recipients, 1))
    return np.minimum(1.0, np.exp(np.minimum(log_p, 0.0)))


@dataclass
class Accusation:
    """One recipient a copy is traced to: id, score (in null standard deviations), corrected p."""

    recipient: str
    score: float
    p_value: float


def accuse(
    x: np.ndarray, recipients: list, C: np.ndarray, p_threshold: float = 1e-6, poses: int = 1
) -> tuple[list[Accusation], np.ndarray, np.ndarray]:
    """The recipients named by readings x (S,) (best first), and every recipient's score and
    corrected p-value (N,). C : (N, S) int8 their codewords; ``poses``: the poses the readings were
    chosen from, paid for as well (``pose_bound``)."""
    T = correlation_scores(x, C)
    p = pose_bound(p_values(T, len(recipients)), poses)
    named = np.flatnonzero(p < p_threshold)
    named = named[np.argsort(-T[named], kind="stable")]
    return [Accusation(recipients[i], float(T[i]), float(p[i])) for i in named], T, p
