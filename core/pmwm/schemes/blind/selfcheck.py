"""The blind embed's check of its own output: a mark that does not read back is never written.

Before the embedder returns, it reads the marked mesh as it will be written (float32) and a few light
copies of it, each as a user's file might come back (``pmwm.readback.light_copies``: a re-export in another pose and
vertex order, a small noise), with the pass phrase, and asks for the whole payload, confirmed. When a
copy does not read, a calibrated margin is raised step by step (``RAISE``) while the marking's MRMS
stays within ``MAX_MRMS`` % of the bounding-box diagonal; an explicit strength is kept as given. If no
allowed margin reads back, the embed refuses with a PayloadError saying which copy failed and what to
try, so the command line and the add-on report one line and write nothing.

The copies' random choices come from the secret (``pmwm.key.derive_seed``): the same phrase and mesh
give the same check.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ... import metrics
from ...base import Verdict
from ...errors import PayloadError
from ...readback import LIGHT_NOISE, light_copies
from .word import PAYLOAD_BITS

__all__ = ["LIGHT_NOISE", "MAX_MRMS", "RAISE", "Mark", "ensure", "failed_copy", "light_copies"]

MAX_MRMS = 0.03  # % of the bbox diagonal: the most a raised margin may cost (surface distance)
RAISE = 1.3  # a margin that does not read back is multiplied by this, step by step
MAX_MARGIN = 0.45  # below the bin half-width (0.5): a bin mean cannot move further
MRMS_SAMPLES = 5000
SHORTEST = PAYLOAD_BITS[0]


@dataclass
class Mark:
    """What the check needs of an embedding: the unmarked mesh (vertices (n, 3) float64, faces (m, 3)
    int64), ``mark(margin) -> marked vertices (n, 3)``, ``read(vertices, faces) -> Verdict`` with the
    secret, the payload bits expected (a "0"/"1" string), the text expected (None for a bits payload),
    and the secret (the copies' seeds)."""

    vertices: np.ndarray
    faces: np.ndarray
    mark: Callable[[float], np.ndarray]
    read: Callable[[np.ndarray, np.ndarray], Verdict]
    bits: str
    text: str | None
    secret: str


def failed_copy(m: Mark, marked: np.ndarray) -> str | None:
    """The name of the first light copy of ``marked`` whose reading is not the payload, confirmed
    (p below the threshold, the bits and the text as marked); None when every copy reads."""
    for name, V, F in light_copies(marked, m.faces, m.secret):
        v = m.read(V, F)
        if not (v.marked and v.bits == m.bits and v.payload == m.text):
            return name
    return None


def ensure(m: Mark, marked: np.ndarray, margin: float, adjustable: bool) -> tuple[float, np.ndarray]:
    """(margin, marked vertices) that read back from every light copy: ``marked`` at ``margin`` when
    it does, else (``adjustable``) the first of the margins raised by RAISE steps up to MAX_MARGIN whose
    marking stays within MAX_MRMS and reads back (the marking's MRMS is not monotone in the margin: the
    embedder raises the margins of bins that do not read, more so from a low start). Raises PayloadError
    (one line: the copy that failed, what to try) otherwise."""
    failed = failed_copy(m, marked)
    if failed is None:
        return margin, marked
    if m.text is not None:
        size = f"{len(m.text.encode('utf-8'))}-byte payload"
    else:
        size = f"{len(m.bits)}-bit payload"
    shorter = "" if len(m.bits) == SHORTEST else "a shorter payload, "
    if not adjustable:
        raise PayloadError(
            f"the blind mark at strength {margin:g} does not read back from {failed} ({size}); "
            f"nothing written. Try a larger --strength (below 0.5), {shorter}or omit --strength "
            "to let pmwm choose"
        )
    tried = margin
    while tried * RAISE <= MAX_MARGIN:
        tried *= RAISE
        raised = m.mark(tried)
        if metrics.displaced_surface_distance(m.vertices, raised, m.faces, MRMS_SAMPLES, seed=0)[0] > MAX_MRMS:
            continue
        if failed_copy(m, raised) is None:
            return tried, raised
    raise PayloadError(
        f"the blind mark ({size}) does not read back from {failed}, nor at a higher strength "
        f"within the distortion budget ({MAX_MRMS:g} % MRMS); nothing written. Try {shorter}another "
        "pass phrase, or the keyed scheme (--scheme robust)"
    )
