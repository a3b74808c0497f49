"""The robust embed's check of its own output: a mark whose payload does not read back, confirmed, is never
handed back.

Before the embedder returns, it reads the marked mesh with the key it is about to return, with the scheme's own
reader, from the light copies of ``pmwm.readback`` (the mesh as written, a re-export in another pose and vertex
order, which takes the registration path, and a copy with a small noise), and asks each for MARKED with the
payload confirmed. On a small mesh a bit's few sites may all be spoilt by their neighbours' bumps, or find no
protected ring: a registered copy then reads that bit as an erasure (a keyed coin flip), and a payload without
a code is unconfirmed half the time; a bit whose one readable site reads weakly by position reads right in some
poses and wrong in others. A larger strength does not help (the spoilt sites stay spoilt); another layout does.
So the sites are dealt to the bits again (``embed.lay_out``, ``layout.assign_bits``), each bit given a site
that reads: first, without reading anything, while some bit has no site a registered copy can read (at most
``RELAYOUTS`` times); then, when a copy does not read with margin (``weak_bits``: each bit right by at least
``MARGIN`` times the median score, or the code confirming the payload without the weak ones), in a layout drawn
from the secret with the attempt's number, the sites of the weak bits no longer counted on, up to ``ATTEMPTS``
readings in all. No layout with margin: the first that every copy reads confirmed. None: the embed refuses with
a PayloadError of one line (the copy that failed, what to try), so the command line and the add-on report it
and write nothing.

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
from .read import confirm, expected_signs, key_data

__all__ = ["ATTEMPTS", "MARGIN", "Marking", "ensure", "failed_copy", "misread_sites", "weak_bits"]

ATTEMPTS = 4  # layouts of the same sites read back before the embed refuses
RELAYOUTS = 3  # layouts dealt again, without reading, while a bit has no site that reads
MARGIN = 0.05  # a bit read right by less than this share of the median score is weak (erased in the check)


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
) -> Optional[tuple[str, Verdict, bool]]:
    """The first light copy of the marked mesh (faces (m, 3) int64) that does not read back well, as (its name,
    its verdict by ``read`` (vertices, faces, key), whether that verdict is at least MARKED with the payload
    confirmed); None when every copy reads MARKED with the payload confirmed even once the bits it read
    weakly (``weak_bits``) are erased. A copy not confirmed ends the reading; a weak one is kept while the
    others are read."""
    weak = None
    for name, V, F in light_copies(marking.vertices, faces, marking.key.secret):
        verdict = read(V, F, marking.key)
        if not (verdict.marked and verdict.payload_confirmed):
            return name, verdict, False
        scores = np.where(weak_bits(marking.key, verdict), 0.0, verdict.scores)
        if weak is None and not confirm(scores, marking.key)[1]:
            weak = (name, verdict, True)
    return weak


def weak_bits(key: WatermarkKey, verdict: Verdict) -> np.ndarray:
    """(N,) bool: the coded bits that ``verdict`` erased, read wrong, or read right by less than ``MARGIN``
    times the median score (its per-bit scores against the key's coded, scrambled bits): a copy in another
    pose may read such a bit wrong."""
    expected = expected_signs(key)
    scores = np.asarray(verdict.scores, np.float64)
    return scores * expected <= MARGIN * np.median(np.abs(scores))


def misread_sites(key: WatermarkKey, verdict: Verdict) -> np.ndarray:
    """(S,) bool: the sites of the coded bits that ``verdict`` read weakly (``weak_bits``)."""
    return weak_bits(key, verdict)[key_data(key).bit]


def ensure(
    mark: Callable[[int, Optional[np.ndarray]], Marking],
    faces: np.ndarray,
    read: Callable[[np.ndarray, np.ndarray, WatermarkKey], Verdict],
    payload: str,
    advice: str,
    report: Callable[[str], None] = lambda message: None,
) -> Marking:
    """The first marking that reads back from every light copy with margin (``failed_copy``): ``mark(attempt,
    unread)`` for attempt 0, 1, ... ``ATTEMPTS`` - 1, ``unread`` (S,) bool the sites an earlier attempt could not
    count on (None at first): those no registered copy reads, and those of the bits a copy read weakly. When no
    layout reads with margin, the first whose every copy reads MARKED with the payload confirmed. faces (m, 3)
    int64; ``read``: the scheme's reader; ``payload`` (the payload in words) and ``advice`` (what to try): for
    the message; ``report(message)``: told of each layout that does not read back. Raises PayloadError (one
    line: the copy that failed, what to try) when no layout reads back confirmed."""
    unread, confirmed = None, None
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
        name, verdict, read_back = failed
        if read_back and confirmed is None:
            confirmed = marking
        unread = _union(unread, marking.unread | misread_sites(marking.key, verdict))
        how = "reads weakly from" if read_back else "does not read back from"
        report(f"layout {attempt + 1} of the sites {how} {name}")
    if confirmed is not None:  # every copy confirmed, if not with margin in every bit: the first such layout
        return confirmed
    raise PayloadError(
        f"the robust mark ({payload}) does not read back from {name} with its payload confirmed, "
        f"in {ATTEMPTS} layouts of its sites; nothing written. Try {advice}"
    )


def _bare_bits(marking: Marking) -> bool:
    """Whether some coded bit of the marking has no site that a registered copy reads."""
    data = key_data(marking.key)
    reads = np.bincount(data.bit[~marking.unread], minlength=data.coded_length(marking.key.n_bits))
    return bool((reads == 0).any())


def _union(a: Optional[np.ndarray], b: np.ndarray) -> np.ndarray:
    return b.copy() if a is None else a | b
