"""The robust embed's check of its own output: a mark whose payload does not read back, confirmed, is never
handed back.

Before the embedder returns, it reads the marked mesh with the key it is about to return, with the scheme's own
reader, from the light copies of ``pmwm.readback`` (the mesh as written, a re-export in another pose and vertex
order, which takes the registration path, and a copy with a small noise), and asks each for MARKED with the
payload confirmed. On a small mesh a bit's few sites may all be spoilt by their neighbours' bumps, or find no
protected ring: a registered copy then reads that bit as an erasure (a keyed coin flip), and a payload without
a code is unconfirmed half the time. A larger strength does not help (the spoilt sites stay spoilt); another
layout does. So the sites are dealt to the bits again (``embed.lay_out``, ``layout.assign_bits``), each bit then
given a site that reads: first, without reading anything, while some bit has no site a registered copy can read
(at most ``RELAYOUTS`` times); then, when a copy does not read, in a layout drawn from the secret with the
attempt's number, the sites of the bits that copy misread no longer counted on, up to ``ATTEMPTS`` readings in
all. If none reads back, the embed refuses with a PayloadError of one line (the copy that failed, what to try),
so the command line and the add-on report it and write nothing.

Every choice comes from the secret: the same secret and mesh give the same marking, the same copies and the
same verdict.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...base import KeyOf, Verdict
from ...errors import PayloadError
from ...key import WatermarkKey
from ...readback import light_copies
from .code import coded_bits
from .read import key_data

__all__ = ["ATTEMPTS", "Marking", "ensure", "failed_copy", "misread_sites"]

ATTEMPTS = 4  # layouts of the same sites read back before the embed refuses
RELAYOUTS = 3  # layouts dealt again, without reading, while a bit has no site that reads


@dataclass
class Marking:
    """One marking of the mesh: its marked vertices (n, 3) float64 (float32-exact), its key as a function of the
    progressive mesh (``pmwm.base.mesh_key``; ``key``: the key made without one, which the robust reader reads
    as it will read the key file), and ``unread`` (S,) bool the sites a registered copy does not read (the sites
    the layout of a next attempt should not count on)."""

    vertices: np.ndarray
    key_of: KeyOf
    unread: np.ndarray
    key: WatermarkKey = field(init=False)

    def __post_init__(self) -> None:
        self.key = self.key_of(None)


def failed_copy(
    marking: Marking, faces: np.ndarray, read: Callable[[np.ndarray, np.ndarray, WatermarkKey], Verdict]
) -> Optional[tuple[str, Verdict]]:
    """The name and the verdict of the first light copy of the marked mesh (faces (m, 3) int64) whose verdict by
    ``read`` (vertices, faces, key) is not MARKED with the payload confirmed; None when every copy reads."""
    for name, V, F in light_copies(marking.vertices, faces, marking.key.secret):
        verdict = read(V, F, marking.key)
        if not (verdict.marked and verdict.payload_confirmed):
            return name, verdict
    return None


def misread_sites(key: WatermarkKey, verdict: Verdict) -> np.ndarray:
    """(S,) bool: the sites of the coded bits that ``verdict`` erased or read wrong (its per-bit scores against
    the key's coded, scrambled bits)."""
    data = key_data(key)
    coded = coded_bits(key.bits, data.code)
    expected = (coded ^ key.stream("scramble", len(coded))) == 1
    scores = np.asarray(verdict.scores, np.float64)
    misread = (scores == 0) | ((scores > 0) != expected)
    return misread[data.bit]


def ensure(
    mark: Callable[[int, Optional[np.ndarray]], Marking],
    faces: np.ndarray,
    read: Callable[[np.ndarray, np.ndarray, WatermarkKey], Verdict],
    payload: str,
    advice: str,
    report: Callable[[str], None] = lambda message: None,
) -> Marking:
    """The first marking that reads back from every light copy: ``mark(attempt, unread)`` for attempt 0, 1,
    ... ``ATTEMPTS`` - 1, ``unread`` (S,) bool the sites an earlier attempt could not count on (None at first):
    those no registered copy reads, and those of the bits the failed copy misread. faces (m, 3) int64;
    ``read``: the scheme's reader; ``payload`` (the payload in words) and ``advice`` (what to try): for the
    message; ``report(message)``: told of each layout that does not read back. Raises PayloadError (one line:
    the copy that failed, what to try) when none reads back."""
    unread = None
    for attempt in range(ATTEMPTS):
        marking = mark(attempt, unread)
        for _ in range(RELAYOUTS):  # (cheap: no reading) until every bit has a site that reads
            if not _bare_bits(marking):
                break
            unread = _union(unread, marking.unread)
            marking = mark(attempt, unread)
        failed = failed_copy(marking, faces, read)
        if failed is None:
            return marking
        unread = _union(unread, marking.unread | misread_sites(marking.key, failed[1]))
        report(f"layout {attempt + 1} of the sites does not read back from {failed[0]}")
    raise PayloadError(
        f"the robust mark ({payload}) does not read back from {failed[0]} with its payload confirmed, "
        f"in {ATTEMPTS} layouts of its sites; nothing written. Try {advice}"
    )


def _bare_bits(marking: Marking) -> bool:
    """Whether some coded bit of the marking has no site that a registered copy reads."""
    data = key_data(marking.key)
    reads = np.bincount(data.bit[~marking.unread], minlength=data.coded_length(marking.key.n_bits))
    return bool((reads == 0).any())


def _union(a: Optional[np.ndarray], b: np.ndarray) -> np.ndarray:
    return b.copy() if a is None else a | b
