"""Binary BCH codes: construction and systematic encoding.

A shortened binary BCH code over GF(2^m): the coded word is the payload's k bits followed by the remainder
of payload(x) x^(n-k) divided by the generator g(x), the least common multiple of the minimal polynomials of
alpha, alpha^3, ..., alpha^(2t-1); its minimum distance is at least d = 2t + 1. A word's first bit is the
coefficient of the highest power. The robust scheme confirms its code against the key
(``schemes.robust.code``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Optional

import numpy as np

__all__ = ["PRIMITIVE", "CORRECTS", "BCHCode", "bch", "payload_code"]

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
