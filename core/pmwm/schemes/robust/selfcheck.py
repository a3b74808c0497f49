"""The robust embed's check of its own output: a mark whose payload does not read back, confirmed, is never
handed back.

Before the embedder returns, it reads the marked mesh with the key it is about to return, with the scheme's own
reader, from the light copies of ``pmwm.readback`` (the mesh as written, a re-export in another pose and vertex
order, which takes the registration path, and a copy with a small noise), and asks each for MARKED with the
payload confirmed. On a small mesh a bit's few sites may all be spoilt by their neighbours' bumps, or find no
protected ring: a registered copy then reads that bit as an erasure (a keyed coin flip), and a payload without
a code is unconfirmed half the time. A larger strength does not help (the spoilt sites stay spoilt); another
layout does. So when a copy does not read, the same sites are dealt to the bits again, in a layout drawn from
the secret with the attempt's number (``embed.lay_out``), the sites that no registered copy can read given no
readable energy (the layout then pairs them with sites that read), up to ``ATTEMPTS`` layouts in all. If none
reads back, the embed refuses with a PayloadError of one line (the copy that failed, what to try), so the
command line and the add-on report it and write nothing.

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

__all__ = ["ATTEMPTS", "Marking", "ensure", "failed_copy"]

ATTEMPTS = 4  # layouts of the same sites tried before the embed refuses


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
) -> Optional[str]:
    """The name of the first light copy of the marked mesh (faces (m, 3) int64) whose verdict by ``read``
    (vertices, faces, key) is not MARKED with the payload confirmed; None when every copy reads."""
    for name, V, F in light_copies(marking.vertices, faces, marking.key.secret):
        verdict = read(V, F, marking.key)
        if not (verdict.marked and verdict.payload_confirmed):
            return name
    return None


def ensure(
    mark: Callable[[int, Optional[np.ndarray]], Marking],
    faces: np.ndarray,
    read: Callable[[np.ndarray, np.ndarray, WatermarkKey], Verdict],
    payload: str,
) -> Marking:
    """The first marking that reads back from every light copy: ``mark(attempt, unread)`` for attempt 0, 1,
    ... ``ATTEMPTS`` - 1, ``unread`` (S,) bool the sites unread in any earlier attempt (None at first). faces
    (m, 3) int64; ``read``: the scheme's reader; ``payload``: the payload in words, for the message. Raises
    PayloadError (one line: the copy that failed, what to try) when none does."""
    unread = None
    for attempt in range(ATTEMPTS):
        marking = mark(attempt, unread)
        failed = failed_copy(marking, faces, read)
        if failed is None:
            return marking
        unread = marking.unread if unread is None else unread | marking.unread
    raise PayloadError(
        f"the robust mark ({payload}) does not read back from {failed} with its payload confirmed, "
        f"in {ATTEMPTS} layouts of its sites; nothing written. Try a shorter payload, or a mesh with more "
        "vertices (subdivide it)"
    )
