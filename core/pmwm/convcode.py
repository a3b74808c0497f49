"""A binary convolutional code with soft-decision Viterbi decoding.

The code is the standard rate-1/2 code of constraint length 7 (generators 171 and 133 in octal, free
distance 10): each input bit shifts into a 6-bit state and emits two coded bits, the parities of the
state and the bit under each generator. The word is terminated with ``MEMORY`` zero bits, so the coded
word of k bits has 2 (k + MEMORY) bits and the decoder knows the path starts and ends in state 0. A rate
above 1/2 sends only some of them (``PUNCTURE``: the standard patterns of this code for 2/3 and 3/4); the
decoder scores the bits not sent as 0, no evidence either way (``coded_length``: the bits sent).

``decode`` takes soft decisions: a score per coded bit, positive for 0 and negative for 1, in proportion
to the log-likelihood ratio (for a quantisation-index channel, 1 - 4 |distance to the bit-0 lattice| in
steps is that ratio up to a scale). It returns the most likely input bits (the Viterbi path), for several
score vectors at once. Soft decisions are why this code and not an algebraic one: near the threshold, a
hard-decision BCH code of the same redundancy fails on words this decoder reads.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["MEMORY", "GENERATORS", "coded_length", "encode", "decode"]

MEMORY = 6  # the constraint length minus 1: the state's bits, and the zero bits that end a word
GENERATORS = (0o171, 0o133)


#: puncturing patterns (rows: generators, columns: input bits of a period; 1 = the coded bit is sent)
PUNCTURE = {
    "1/2": np.ones((2, 1), bool),
    "2/3": np.array([[1, 1], [1, 0]], bool),
    "3/4": np.array([[1, 0, 1], [1, 1, 0]], bool),
}


def _kept(k: int, rate: str) -> np.ndarray:
    """(2 (k + MEMORY),) bool: the mother code's coded bits a word of ``k`` input bits sends at ``rate``."""
    P = PUNCTURE[rate]
    steps = k + MEMORY
    return P[:, np.arange(steps) % P.shape[1]].T.ravel()


def coded_length(k: int, rate: str = "1/2") -> int:
    """The coded bits of a word of ``k`` input bits."""
    return int(_kept(k, rate).sum())


def _parity(x: np.ndarray) -> np.ndarray:
    """The parity (0 or 1) of each integer's bits, x (...) int."""
    x = x.copy()
    out = np.zeros_like(x)
    while x.any():
        out ^= x & 1
        x >>= 1
    return out


@lru_cache(maxsize=None)
def _trellis() -> tuple[np.ndarray, np.ndarray]:
    """(outputs (2^MEMORY, 2, len(GENERATORS)) uint8: the coded bits leaving state s on input b,
    next (2^MEMORY, 2) int: the state that follows). State = the last MEMORY input bits, newest highest."""
    s = np.arange(2**MEMORY)[:, None]
    b = np.arange(2)[None, :]
    register = (b << MEMORY) | s  # (the newest bit at the top, as the generators' octal digits read)
    out = np.stack([_parity(register & g) for g in GENERATORS], axis=-1).astype(np.uint8)
    return out, register >> 1


def encode(bits: np.ndarray, rate: str = "1/2") -> np.ndarray:
    """The coded word (``coded_length(k, rate)``,) uint8 of input bits (k,) uint8, ended by MEMORY zero bits."""
    out, nxt = _trellis()
    state = 0
    coded = []
    for b in np.concatenate([np.asarray(bits, np.uint8), np.zeros(MEMORY, np.uint8)]):
        coded.append(out[state, b])
        state = nxt[state, b]
    return np.concatenate(coded).astype(np.uint8)[_kept(len(bits), rate)]


def decode(scores: np.ndarray, k: int, rate: str = "1/2") -> np.ndarray:
    """The most likely input bits (h, k) uint8 of the soft scores (h, ``coded_length(k, rate)``) of h words (or
    of one, (n,), giving (k,)): score > 0 says 0, < 0 says 1, magnitudes in proportion to the log-likelihood
    ratio. Raises ValueError when the scores are not as many as a word of k bits at ``rate`` sends."""
    sent = np.atleast_2d(np.asarray(scores, np.float64))
    kept = _kept(k, rate)
    if sent.shape[1] != kept.sum():
        raise ValueError(f"a word of {k} bits at rate {rate} has {kept.sum()} coded bits; got {sent.shape[1]}")
    h = len(sent)
    S = np.zeros((h, len(kept)))
    S[:, kept] = sent  # (a bit not sent scores 0: no evidence either way)
    r = len(GENERATORS)
    steps = k + MEMORY
    out, _ = _trellis()
    n_states = 2**MEMORY
    sign = 1.0 - 2.0 * out  # (states, 2, r): +1 where the coded bit is 0
    # predecessors of each state: state t = (b << (MEMORY-1)) | (p >> 1); p = ((t << 1) & mask) | low bit
    t = np.arange(n_states)
    prev = np.stack([((t << 1) & (n_states - 1)) | low for low in (0, 1)], axis=1)  # (states, 2)
    bit_in = t >> (MEMORY - 1)  # the input bit that leads into state t
    branch_sign = sign[prev, bit_in[:, None]]  # (states, 2 predecessors, r)
    metric = np.full((h, n_states), -np.inf)
    metric[:, 0] = 0.0
    choice = np.zeros((steps, h, n_states), np.uint8)
    for i in range(steps):
        gain = np.einsum("hr,spr->hsp", S[:, r * i : r * i + r], branch_sign)  # (h, states, 2)
        cand = metric[:, prev] + gain
        c = np.argmax(cand, axis=2)
        choice[i] = c
        metric = np.take_along_axis(cand, c[..., None], axis=2)[..., 0]
    state = np.zeros(h, np.int64)  # (the word ends in state 0)
    bits = np.zeros((h, steps), np.uint8)
    rows = np.arange(h)
    for i in range(steps - 1, -1, -1):
        bits[:, i] = state >> (MEMORY - 1)
        state = prev[state, choice[i, rows, state]]
    got = bits[:, : steps - MEMORY]
    return got[0] if np.ndim(scores) == 1 else got
