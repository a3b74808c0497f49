"""The robust payload's error-correcting code and its confirmation.

Code. A shortened binary BCH code over GF(2^m), systematic: the coded word is the payload's k bits
followed by the remainder of payload(x) x^(n-k) divided by the generator g(x), the least common multiple
of the minimal polynomials of alpha, alpha^3, ..., alpha^(2t-1). Its minimum distance is at least d = 2t + 1.
A high-rate code on purpose: each coded bit has less energy than an uncoded payload bit at the same
distortion, and a rate-1/2 code then reads worse than no code wherever the bit errors exceed a few per
cent (``docs/decisions/110-payload-code.md``); t = 4 costs 28 bits on a 64-bit payload.

Confirmation. The key holds the payload, so it holds the codeword c (+-1 per coded bit). A reading x
(sign = the coded bit read, |x| its reliability, 0 = erased) confirms c when, with the reliabilities
a_i in [0, 1] (1 for every bit read, or |x_i| over the median |x|, capped at 1),
sum_i a_i sign(x_i) c_i > n - d: no other codeword can pass that test on the same reading (for two
codewords c, c', the sum for c plus the sum for c' is at most 2 (n - d), since they differ in at least
d places; Forney's generalised minimum distance criterion). With a_i = 1 that is 2 errors + erasures < d,
what a bounded-distance decoder corrects; with the soft reliabilities, weak wrong bits cost little. A
confirmed payload is the one a decoder would have given; an unconfirmed one is never shown as the payload.
A key without a code confirms its payload only when every bit was read, right.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ...bch import BCHCode
from ...key import WatermarkKey


def coded_bits(bits: np.ndarray, code: Optional[BCHCode]) -> np.ndarray:
    """What the marks carry for payload bits (k,) uint8: their codeword, or the bits themselves without a
    code, (n,) uint8."""
    return np.asarray(bits, np.uint8).copy() if code is None else code.encode(bits)


def confirm_with(scores: np.ndarray, key: WatermarkKey, code: Optional[BCHCode]) -> tuple[np.ndarray, bool, int]:
    """``pmwm.schemes.robust.confirm`` for the key's ``code`` (None: no code): the payload a reading gives,
    whether it is confirmed as the key's, and how many coded bits the code corrected (read wrong or not read).
    scores (n,) float64: one per coded bit (sign = the scrambled
    bit read, magnitude = its reliability, 0 = erased), or bits (n,) uint8 already descrambled.

    Returns (payload bits (k,) uint8: the key's when confirmed, else the bits as read, never to be shown
    as the payload; confirmed; corrected)."""
    c = coded_bits(key.bits, code)
    x = np.asarray(scores)
    if x.dtype == np.uint8:  # hard bits, descrambled: full reliability each
        agree = np.where(x == c, 1.0, -1.0)
        hard = x
    else:
        x = np.asarray(x, np.float64)
        read = (x > 0).astype(np.uint8) ^ key.stream("scramble", len(c))
        hard = np.where(x == 0, 0, read).astype(np.uint8)
        agree = np.where(x == 0, 0.0, np.where(read == c, 1.0, -1.0))
    wrong = int(np.count_nonzero(agree <= 0))
    if code is None:
        ok = wrong == 0
        return (c if ok else hard[: key.n_bits]), ok, 0
    n, d = len(c), code.distance
    reliable = np.abs(agree)
    if x.dtype != np.uint8:
        mag = np.abs(x)
        ref = _median(mag[mag > 0]) if np.any(mag > 0) else 1.0
        reliable = np.minimum(1.0, mag / ref)
    ok = bool(agree.sum() > n - d or (reliable * agree).sum() > n - d)
    return (key.bits.copy() if ok else hard[: code.k]), ok, (wrong if ok else 0)


def _median(x: np.ndarray) -> float:
    """np.median of x (k,) float64, k >= 1, by partition: np.median imports numpy.ma, which a command-line
    verify otherwise never loads."""
    k = len(x)
    part = np.partition(x, [(k - 1) // 2, k // 2])
    return float(0.5 * (part[(k - 1) // 2] + part[k // 2]))
