"""Binary BCH codes: construction, systematic encoding and hard-decision decoding.

A shortened binary BCH code over GF(2^m): the coded word is the payload's k bits followed by the remainder
of payload(x) x^(n-k) divided by the generator g(x), the least common multiple of the minimal polynomials of
alpha, alpha^3, ..., alpha^(2t-1); its minimum distance is at least d = 2t + 1. A word's first bit is the
coefficient of the highest power. ``decode`` corrects up to t wrong bits (syndromes, Berlekamp-Massey,
Chien search) and says when it cannot. The robust scheme confirms its code against the key
(``schemes.robust.code``); the blind scheme decodes it (``schemes.blind.waveread``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Optional

import numpy as np

__all__ = ["PRIMITIVE", "CORRECTS", "BCHCode", "bch", "payload_code", "decode"]

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
CORRECTS = 4  # t: the errors a robust payload's code corrects (design distance 2t + 1)


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


@lru_cache(maxsize=8)
def _field(m: int) -> tuple[np.ndarray, np.ndarray]:
    """(exp (2 (2^m - 1),) alpha^i as bit vectors, log (2^m,) int64 (log[0] unused)) of GF(2^m)."""
    size = (1 << m) - 1
    exp = np.zeros(2 * size, np.int64)
    x = 1
    for i in range(size):
        exp[i] = exp[i + size] = x
        x <<= 1
        if x >> m:
            x ^= PRIMITIVE[m]
    log = np.zeros(size + 1, np.int64)
    log[exp[:size]] = np.arange(size)
    return exp, log


def decode(code: BCHCode, received: np.ndarray) -> Optional[np.ndarray]:
    """The codeword (n,) uint8 nearest to ``received`` (n,) uint8 when at most ``code.t`` bits are wrong,
    else None when the decoder sees that it cannot (more errors may also decode to another codeword)."""
    r = np.asarray(received, np.uint8)
    n, t, m = code.n, code.t, code.m
    exp, log = _field(m)
    size = (1 << m) - 1
    powers = (n - 1 - np.flatnonzero(r)).astype(np.int64)  # the set bits' powers of x
    j = np.arange(1, 2 * t + 1)
    S = (
        np.bitwise_xor.reduce(exp[(powers[None, :] * j[:, None]) % size], axis=1)
        if len(powers)
        else np.zeros(2 * t, np.int64)
    )
    if not S.any():
        return r.copy()

    def mul(a: int, b: int) -> int:
        return 0 if a == 0 or b == 0 else int(exp[log[a] + log[b]])

    # Berlekamp-Massey over GF(2^m): the error locator Lambda(x), lowest coefficient first
    lam, prev = [1], [1]
    L, shift, b = 0, 1, 1
    for k in range(2 * t):
        d = int(S[k])
        for i in range(1, L + 1):
            if i < len(lam):
                d ^= mul(lam[i], int(S[k - i]))
        if d == 0:
            shift += 1
            continue
        coef = mul(d, int(exp[(size - log[b]) % size]))
        nxt = lam + [0] * max(0, len(prev) + shift - len(lam))
        for i, c in enumerate(prev):
            nxt[i + shift] ^= mul(coef, c)
        if 2 * L <= k:
            prev, L, b, shift = lam, k + 1 - L, d, 1
        else:
            shift += 1
        lam = nxt
    while len(lam) > 1 and lam[-1] == 0:
        lam.pop()
    if L > t or len(lam) - 1 != L:
        return None
    # Chien search: an error at power p when Lambda(alpha^-p) = 0
    p = np.arange(n)
    val = np.zeros(n, np.int64)
    for i, c in enumerate(lam):
        if c:
            val ^= exp[(log[c] - p * i) % size]
    roots = np.flatnonzero(val == 0)
    if len(roots) != L:
        return None
    out = r.copy()
    out[n - 1 - roots] ^= 1
    return out
