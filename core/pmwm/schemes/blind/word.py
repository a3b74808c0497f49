"""The pass phrase and the word the blind scheme writes: payload, keyed check, scrambling, bin layout.

Everything secret derives from the pass phrase through scrypt with a fixed public salt
(``derive_secret``): the 64-hex-digit secret then seeds every keyed stream (``pmwm.key.keyed_bits``).

The word. ``PAYLOAD_BITS`` lists the payload lengths a word can have (32, 64, 96 or 224 bits: 4, 8,
12 or 28 bytes of text); behind the payload come ``CHECK_BITS`` = 32 check bits, a keyed hash of the
secret, the payload kind (text or bits) and the payload. The reader knows neither the length nor the
kind: it reads the length whose bins show the most mark energy (chosen without the pass phrase),
as either kind, and in each of the 2 readings up to 2^10 words that flip the most likely sets of
bits (``likely_flips``: the sets of least total reliability, a bit's reliability its score in units of
its bins' standard error; a Chase search, which corrects a few weak bits wherever they are, not only
among the 10 least reliable). Under the null (an unmarked mesh, or the wrong pass phrase) the expected
check bits of a candidate are fair coins independent of the bits read (a keyed hash of what was read), so
P(m or more of the 32 match) = P(Binomial(32, 1/2) >= m) exactly per candidate, and the p-value is the
union bound over every candidate of every frame read (``plan``: how many candidates each frame gets so that
a reading with all 32 right stays below 1e-6). The candidates depend on the bits and scores read only,
never on the check bits expected, so the bound holds whichever they are.

Why 32 check bits in the 64-bit benchmark word (32 payload + 32 check): with 24 (and no Chase
search) p < 1e-6 needs every bit of the word right, and one weak bit loses the payload; 32 check bits pay
for the 2^10 Chase candidates (docs/decisions/082-blind-carrier-and-word.md). A reading is
"marked" only with all its check bits right, so a payload reported as marked is the embedded one up
to a hash collision (2^-32 per candidate).
"""

from __future__ import annotations

import hashlib
import heapq
from typing import Optional

import numpy as np

from ...base import decode_text
from ...errors import PayloadError
from ...key import derive_seed, keyed_bits
from ...validate import parse_bits

PAYLOAD_BITS = (32, 64, 96, 224)
CHECK_BITS = 32
KINDS = ("bits", "text")
SALT = b"pmwm-blind-v1 public salt"  # fixed and public: the pass phrase is the only secret
SCRYPT = dict(n=2**14, r=8, p=1)  # ~16 MB, ~0.05 s per derivation


def likely_flips(reliability: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` sets of bits whose flipping is most likely, as masks (count, N) uint8: the sets of
    least total ``reliability`` (N,) >= 0 (the magnitudes of the bits' scores: a bit read near zero is
    as likely wrong as right), lightest first; row 0 flips nothing. A best-first walk over the bits
    sorted by reliability: each set's successors add the next bit after its last one, or move its last
    one on; every set is reached once, in order of weight (ties: the sorted order decides).

    Chase's search flips every subset of the C least reliable bits; these are as many candidates, so
    the p-value's union bound is the same, but a lone error on the 11th or 12th least reliable bit is
    more likely than one on 6 of the 10 together, and is tried."""
    r = np.clip(np.nan_to_num(np.asarray(reliability, dtype=np.float64), nan=0.0), 0.0, 1e300)  # (sums stay finite)
    order = np.argsort(r, kind="stable")
    w = r[order].tolist()
    out = np.zeros((count, len(r)), np.uint8)
    heap = [(w[0], (0,))] if len(w) and count > 1 else []
    k = 1
    while heap and k < count:
        cost, bits = heapq.heappop(heap)
        out[k, order[list(bits)]] = 1
        k += 1
        last = bits[-1]
        if last + 1 < len(w):
            heapq.heappush(heap, (cost + w[last + 1], bits + (last + 1,)))
            heapq.heappush(heap, (cost - w[last] + w[last + 1], bits[:-1] + (last + 1,)))
    return out[:k]


def derive_secret(passphrase: str) -> str:
    """The scheme's secret (64 hex digits) from the pass phrase (scrypt, public salt)."""
    check_passphrase(passphrase)
    raw = hashlib.scrypt(passphrase.encode("utf-8"), salt=SALT, dklen=32, maxmem=64 * 1024 * 1024, **SCRYPT)
    return raw.hex()


def check_passphrase(passphrase: str) -> None:
    """PayloadError unless ``passphrase`` is a non-empty text (``derive_secret``'s check, for a caller that
    derives the secret later)."""
    if not isinstance(passphrase, str) or not passphrase:
        raise PayloadError("the blind scheme needs a non-empty pass phrase")


def payload_of(
    payload: Optional[str],
    bits,
    n_bits: int,
    random_bits,
    lengths: tuple[int, ...] = PAYLOAD_BITS,
    who: str = "the blind scheme",
) -> tuple[np.ndarray, str]:
    """The payload (L,) uint8 with L in ``lengths`` (the carrier's, ascending multiples of 8) and its kind
    ("text" or "bits"); ``who`` names the carrier in the errors.

    Text is UTF-8 padded with NUL bytes to the shortest length that holds it; explicit bits must
    have one of the lengths; a random payload has ``n_bits`` bits, drawn by ``random_bits(n)``."""
    if payload is not None and bits is not None:
        raise PayloadError("give a text payload or explicit bits, not both")
    sizes = ", ".join(map(str, lengths))
    if payload is not None:
        data = payload.encode("utf-8")
        if not data:
            raise PayloadError("the payload text is empty; give some text or use --bits")
        n = next((L for L in lengths if L >= 8 * len(data)), None)
        if n is None:
            raise PayloadError(f"{who} can hold at most {lengths[-1] // 8} bytes of text; this payload has {len(data)}")
        data = data + b"\0" * (n // 8 - len(data))
        return np.unpackbits(np.frombuffer(data, np.uint8)), "text"
    if bits is not None:
        b = parse_bits(bits)
        if len(b) not in lengths:
            raise PayloadError(f"{who} can carry {sizes} payload bits; got {len(b)}")
        return b, "bits"
    if n_bits not in lengths:
        raise PayloadError(f"{who} can carry {sizes} payload bits; asked for {n_bits}")
    return np.asarray(random_bits(n_bits), np.uint8), "bits"


def check_bits(
    secret: str, kind: str, payload: np.ndarray, n_check: int = CHECK_BITS, label: str = "blind-check"
) -> np.ndarray:
    """The keyed check of a payload (L,) uint8 of a kind, (n_check,) uint8, or of each of the payloads
    (k, L), (k, n_check): the first bits of SHA-256(secret, label, kind, payload) (a MAC; n_check a multiple
    of 8, at most 256; each carrier its own ``label``). hashlib directly, the key's part hashed once (the
    reader computes thousands of these per suspect)."""
    rows = np.atleast_2d(np.asarray(payload, dtype=np.uint8))
    head = hashlib.sha256(f"{secret}:{label}:{kind}:".encode())
    tail = rows.shape[1].to_bytes(2, "little")
    tags = bytearray()
    for row in np.packbits(rows, axis=1):
        h = head.copy()
        h.update(row.tobytes() + tail)
        tags += h.digest()[: n_check // 8]
    bits = np.unpackbits(np.frombuffer(bytes(tags), np.uint8)).reshape(len(rows), n_check)
    return bits if np.ndim(payload) == 2 else bits[0]


def layout(secret: str, n_word: int, n_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the word goes: bin -> word bit (n_bins,) int64 (a keyed permutation, each bit on
    n_bins // n_word bins) and the keyed scrambling (n_word,) uint8."""
    rng = np.random.default_rng(derive_seed(secret, f"blind-layout:{n_word}:{n_bins}"))
    bit_of_bin = rng.permutation(np.arange(n_bins) % n_word)
    return bit_of_bin, keyed_bits(secret, f"blind-scramble:{n_word}", n_word)


def word_of(secret: str, kind: str, payload: np.ndarray) -> np.ndarray:
    """The word written (L + CHECK_BITS,) uint8: payload then check."""
    return np.concatenate([payload, check_bits(secret, kind, payload)]).astype(np.uint8)


def text_of(bits: np.ndarray) -> Optional[str]:
    """The text of a payload read as text (trailing NULs dropped), None if not UTF-8."""
    return decode_text(bits)
