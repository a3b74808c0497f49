"""The light copies an embedder reads its own output back from before returning it (the blind and the
robust self-checks): a mark that does not read from them is never handed to the user.

Each copy is one a user's file may come back as after an ordinary round trip: the mesh as written (float32),
a re-export in another pose and vertex order, and a copy with a small noise. Their random choices come from the
key's secret (``pmwm.key.derive_seed``): the same secret and mesh give the same copies.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from . import attacks
from .key import derive_seed

__all__ = ["LIGHT_NOISE", "light_copies"]

LIGHT_NOISE = 0.0005  # noise copy: uniform in +- this fraction of the mean distance to the centroid


def light_copies(marked: np.ndarray, faces: np.ndarray, secret: str) -> Iterator[tuple[str, np.ndarray, np.ndarray]]:
    """(name, vertices (n, 3) float64, faces (m, 3) int64) of the copies of a marked mesh ``marked`` (n, 3),
    ``faces`` (m, 3), cheapest to read first: the mesh as written, the mesh re-exported in a random pose and
    order (float32: a similarity, then a permutation of the vertices and the faces), and the mesh with a small
    noise (``LIGHT_NOISE``)."""
    yield "the mesh as written", marked, faces
    Vp, Fp = attacks.similarity(marked, faces, seed=derive_seed(secret, "selfcheck-pose"))
    Vp, Fp = attacks.reorder(Vp, Fp, seed=derive_seed(secret, "selfcheck-order"))
    yield "a re-export in another pose and vertex order", Vp.astype(np.float32).astype(np.float64), Fp
    yield (
        "a copy with 0.05 % noise",
        *attacks.noise_benchmark(marked, faces, LIGHT_NOISE, seed=derive_seed(secret, "selfcheck-noise")),
    )
