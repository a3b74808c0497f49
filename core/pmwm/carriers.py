"""Key-seeded choice of watermark carriers, spread over the surface (paper section 4.1).

Candidates are the vertices the SOM calls suitable (neither flat nor peak) that sit
inside a clean manifold fan with valence >= 4 (after Alg. 1 collapses the first
neighbour the carrier keeps >= 3 neighbours for a meaningful mean and std).
Carriers are picked by jittered farthest-point sampling in 3-D: start at a seeded
random candidate, then repeatedly take the remaining candidate that maximises
(distance to the nearest chosen carrier) x (its jitter weight in [0.75, 1]). The
jitter weight is drawn once per candidate from the seed, so a different key gives a
different set that is still spread out. Hard rule: no two carriers within graph
distance 2 (their closed 1-rings are disjoint, so their collapses are independent):
picking c removes c's 2-ring from the candidates.
"""

from __future__ import annotations

import numpy as np

from .adjacency import Adjacency, gather_rows
from .errors import PayloadError
from .features import smoothness_feature
from .som import SUITABLE, classify_smoothness

JITTER_MIN = 0.75


def eligible_carriers(vertices: np.ndarray, adj: Adjacency, seed: int, cross: np.ndarray | None = None) -> np.ndarray:
    """Bool mask (n,): SOM-suitable, manifold interior, valence >= 4. ``cross``: the faces'
    ``features.face_cross`` (m, 3) when the caller has it already.

    The SOM is trained on the manifold-interior vertices only: boundary fans are
    half-fans and isolated vertices have no feature, both would skew the clusters.
    """
    ok = adj.manifold_interior & (adj.valence >= 4)
    mask = np.zeros(adj.n_vertices, dtype=bool)
    idx = np.flatnonzero(adj.manifold_interior)
    if len(idx) == 0:
        return mask
    feats = smoothness_feature(vertices, adj, cross=cross)[idx]
    labels = classify_smoothness(feats, seed=seed)
    mask[idx] = labels == SUITABLE
    return mask & ok


def two_ring(adj: Adjacency, c: int) -> np.ndarray:
    """Vertices within graph distance 2 of c, c included (may repeat)."""
    ring = adj.ring_idx[adj.ring_ptr[c] : adj.ring_ptr[c + 1]]
    return np.concatenate([[c], ring, gather_rows(adj.ring_ptr, adj.ring_idx, ring)])


def select_carriers(vertices: np.ndarray, adj: Adjacency, eligible: np.ndarray, n: int, seed: int) -> np.ndarray:
    """Pick n carrier vertex indices (n,) int64, in pick order, from the ``eligible`` mask.

    Boundary, non-manifold and isolated vertices are never picked, whatever the mask
    says. Raises PayloadError when the mesh cannot hold n carriers under the 2-ring rule.
    """
    n = int(n)
    v = np.asarray(vertices, dtype=np.float64)
    eligible = np.asarray(eligible, dtype=bool) & adj.manifold_interior
    if n < 0:
        raise ValueError("n must be non-negative")
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    cand = np.flatnonzero(eligible)
    rng = np.random.default_rng(seed)
    jitter = rng.uniform(JITTER_MIN, 1.0, size=len(cand))
    # farthest-point order with a keyed jitter: the next pick maximises distance * jitter, kept squared
    # (the same order as the distance itself) and -inf where the 2-ring rule blocks a candidate; ties
    # go to the lowest vertex index. A pick can only lower the distance of the candidates closer than
    # the largest distance of a live one: with the candidates held sorted along the longest side of
    # their bounding box, a slab around it.
    # A blocked candidate's squared distance is -inf too, so that its score stays -inf without a mask.
    axis = int(np.argmax(np.ptp(v[cand], axis=0))) if len(cand) else 0
    by_axis = np.argsort(v[cand, axis], kind="stable")
    cand = cand[by_axis]
    local = np.full(adj.n_vertices, -1, dtype=np.int64)
    local[cand] = np.arange(len(cand))
    pos = np.ascontiguousarray(v[cand].T)  # (3, k): one coordinate per row, pos[axis] ascending
    weight = (jitter * jitter)[by_axis]
    w_min = float(weight.min()) if len(cand) else 1.0
    dist2 = np.full(len(cand), np.inf)
    score = np.full(len(cand), np.inf)
    buf, d2_buf = np.empty(len(cand)), np.empty(len(cand))
    chosen: list[int] = []
    pick = int(np.flatnonzero(by_axis == rng.integers(len(cand)))[0]) if len(cand) else -1
    while pick >= 0:
        c = int(cand[pick])
        chosen.append(c)
        if len(chosen) == n:
            break
        # every live candidate has dist2 <= score / weight <= score[pick] / w_min
        x = float(pos[axis, pick])
        reach = float(np.sqrt(score[pick] / w_min)) * (1.0 + 1e-6) + abs(x) * 1e-12
        lo, hi = (
            (0, len(cand))
            if not np.isfinite(reach)
            else (int(np.searchsorted(pos[axis], x - reach)), int(np.searchsorted(pos[axis], x + reach, "right")))
        )
        # d2 = ((x - x0)^2 + (y - y0)^2) + (z - z0)^2, in two reused buffers
        t, d2 = buf[: hi - lo], d2_buf[: hi - lo]
        np.subtract(pos[0, lo:hi], pos[0, pick], out=t)
        np.multiply(t, t, out=d2)
        for row in (1, 2):
            np.subtract(pos[row, lo:hi], pos[row, pick], out=t)
            np.multiply(t, t, out=t)
            d2 += t
        np.minimum(dist2[lo:hi], d2, out=dist2[lo:hi])
        blocked = local[two_ring(adj, c)]
        blocked = blocked[blocked >= 0]
        dist2[blocked] = -np.inf
        score[blocked] = -np.inf
        np.multiply(dist2[lo:hi], weight[lo:hi], out=score[lo:hi])
        pick = int(np.argmax(score))
        best = score[pick]
        if best == -np.inf:  # no live candidate left
            break
        if score[pick + 1 :].max(initial=-np.inf) == best:  # a tie: the lowest vertex index
            tied = np.flatnonzero(score == best)
            pick = int(tied[np.argmin(cand[tied])])
    if len(chosen) < n:
        raise PayloadError(
            f"only {len(chosen)} vertices of this mesh can carry a bit, {n} requested; "
            "use a shorter payload (fewer bits) or a denser mesh"
        )
    return np.asarray(chosen, dtype=np.int64)
