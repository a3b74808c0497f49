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

from dataclasses import dataclass
from functools import lru_cache
from typing import Optional

import numpy as np

from ...key import WatermarkKey

# primitive polynomials of GF(2^m), bit i = coefficient of x^i
PRIMITIVE = {
    5: 0b100101,
    6: 0b1000011,
    7: 0b10001001,
    8: 0b100011101,
    9: 0b1000010001,
    10: 0b10000001001,
    11: 0b100000000101,
    12: 0b1000001010011,
    13: 0b10000000011011,
}
CORRECTS = 4  # t: the errors a payload's code corrects (design distance 2t + 1)


@dataclass(frozen=True)
class BCHCode:
    """A shortened binary BCH code of ``k`` payload bits over GF(2^m) correcting ``t`` errors;
    ``generator`` (r + 1,) uint8 the coefficients of g(x), lowest first (r = n - k parity bits)."""

    m: int
    t: int
    k: int
    generator: np.ndarray

    @property
    def n(self) -> int:
        return self.k + len(self.generator) - 1

    @property
    def distance(self) -> int:
        """The code's design distance: a lower bound of its minimum distance."""
        return 2 * self.t + 1

    @property
    def name(self) -> str:
        return f"BCH({self.n}, {self.k}), corrects {self.t}"

    def encode(self, bits: np.ndarray) -> np.ndarray:
        """The codeword (n,) uint8 of payload bits (k,) uint8: the bits, then the parity."""
        g = self.generator.astype(bool)
        r = len(g) - 1
        reg = np.zeros(r, bool)  # the remainder, highest power first
        gh = g[::-1][1:]  # g's coefficients below x^r, highest first
        for b in np.asarray(bits, bool):  # k steps of an r-bit shift register (k: the payload's bits)
            fb = b ^ reg[0]
            reg = np.r_[reg[1:], False]
            if fb:
                reg ^= gh
        return np.r_[np.asarray(bits, np.uint8), reg.astype(np.uint8)]

    def to_json(self) -> dict:
        return {"name": "bch", "m": self.m, "t": self.t, "k": self.k}

    @classmethod
    def from_json(cls, d: dict) -> "BCHCode":
        """The code a key names; ValueError when it is not one this pmwm knows."""
        if not isinstance(d, dict) or d.get("name") != "bch":
            raise ValueError(f"unknown payload code {d!r}")
        m, t, k = int(d["m"]), int(d["t"]), int(d["k"])
        if m not in PRIMITIVE or not 1 <= t <= 16 or not 1 <= k:
            raise ValueError("payload code parameters")
        code = bch(m, t, k)
        if code.n > (1 << m) - 1:
            raise ValueError("payload code longer than its field allows")
        return code


def payload_code(k: int, t: int = CORRECTS) -> Optional[BCHCode]:
    """The code for a payload of ``k`` bits: the smallest field whose BCH code of ``t`` corrections holds
    it; None when none does (longer than 8,000 bits)."""
    for m in sorted(PRIMITIVE):
        code = bch(m, t, k)
        if code.n <= (1 << m) - 1:
            return code
    return None


@lru_cache(maxsize=32)
def bch(m: int, t: int, k: int) -> BCHCode:
    """The BCH code of GF(2^m), t corrections, shortened to k payload bits."""
    size = (1 << m) - 1
    exp = np.zeros(2 * size, np.int64)  # alpha^i as a bit vector
    x = 1
    for i in range(size):  # the field's table: 2^m - 1 steps (at most 8,191)
        exp[i] = exp[i + size] = x
        x <<= 1
        if x >> m:
            x ^= PRIMITIVE[m]
    g = np.array([1], np.uint8)
    done: set = set()
    for i in range(1, 2 * t, 2):
        if i % size in done:
            continue
        orbit, e = [], i % size  # the conjugates alpha^(i 2^j)
        while e not in orbit:
            orbit.append(e)
            e = 2 * e % size
        done.update(orbit)
        poly = [1]  # the minimal polynomial prod (x - alpha^e), coefficients in GF(2^m), lowest first
        for e in orbit:
            nxt = [0] * (len(poly) + 1)
            for j, c in enumerate(poly):
                nxt[j + 1] ^= c
                if c:
                    nxt[j] ^= _mul(c, int(exp[e]), exp, size)
            poly = nxt
        g = _poly_mul_gf2(g, np.array(poly, np.uint8))  # its coefficients are 0 or 1
    return BCHCode(m=m, t=t, k=k, generator=g)


def _mul(a: int, b: int, exp: np.ndarray, size: int) -> int:
    """a * b in GF(2^m) (bit vectors), by the exponent table."""
    log = {int(v): i for i, v in enumerate(exp[:size])}
    return int(exp[log[a] + log[b]])


def _poly_mul_gf2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The product of two polynomials over GF(2) (coefficients lowest first)."""
    return (np.convolve(a.astype(np.int64), b.astype(np.int64)) % 2).astype(np.uint8)


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
