"""The vertex-split record's format, and the face-corner arithmetic the encoder and the decoder share.

Record r of a progressive mesh adds vertex ``n_base_vertices + r`` at ``pos[r]`` next to vertex
``v[r]``. Bit i of ``mask[r]`` says whether v's i-th face (v's faces sorted by face index at the moment
of the split) moves to the new vertex u; the moved faces form one arc around v, whose ends p and q give
the new faces [u, v, p] and/or [u, q, v]. ``flags[r]`` says how many faces the split adds (one on a
boundary) and which. The mask's top 12 bits, which no face uses when v has at most ``ENDS_SHIFT``
faces, may name the two faces that end the arc (p's, then q's; 6 bits each), so that the decoder reads
p and q from two faces instead of summing around the arc.

A face's corner j is the half-edge F[f, j] -> F[f, (j + 1) % 3]; a flat corner id is ``3 * f + j``.
"""

from __future__ import annotations

import numpy as np

MAX_FAN = 64  # faces around v at a split: the mask is 64 bits
FLAG_SINGLE = 1  # the split adds one face (a boundary collapse)
FLAG_SECOND = 2  # ... and that face is the one holding the half-edge v -> u
# The mask's top bits, when the progressive mesh has ``end_ranks`` and v has at most ENDS_SHIFT faces: the
# ranks among v's faces of the moved faces that end the arc, p's (next to u's corner) then q's, 6 bits
# each; NO_END in both when the record names none.
ENDS_SHIFT = 52
NO_END = 63

NEXT_CORNER = np.array([1, 2, 0])  # (3,) the next corner of a face, by corner
PREV_CORNER = np.array([2, 0, 1])  # (3,) the previous corner
TO_NEXT_CORNER = NEXT_CORNER - np.arange(3)  # (3,) added to a flat corner id: the next corner's, by corner
TO_PREV_CORNER = PREV_CORNER - np.arange(3)  # (3,) ... the previous corner's
