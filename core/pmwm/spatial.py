"""Nearest-point and radius queries between point sets: the one place spatial search is done.

Every scheme, the registration and the metrics ask their spatial questions through these three
functions, so that a faster engine (a KD-tree) can be swapped in here alone. Today they are exact
brute force in bounded chunks (memory stays about ``budget`` float64 values whatever the sizes).
"""

from __future__ import annotations

import numpy as np

__all__ = ["nearest", "pairs_within", "min_spacing"]


def nearest(T: np.ndarray, Q: np.ndarray, budget: int = 1 << 22) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point of T to each query.

    T : (n, 3) float64 targets; Q : (m, 3) float64 queries.
    Returns the index into T (m,) int64 (-1 when T is empty) and the squared distance (m,) float64.
    Computed about T's mean, so far-off coordinates keep their digits.
    """
    idx = np.empty(len(Q), np.int64)
    d2 = np.empty(len(Q))
    if len(T) == 0:
        return np.full(len(Q), -1, np.int64), np.full(len(Q), np.inf)
    centre = T.mean(axis=0)
    T, Q = T - centre, Q - centre
    tt = np.einsum("ij,ij->i", T, T)
    step = max(1, budget // max(len(T), 1))
    for s in range(0, len(Q), step):
        q = Q[s:s + step]
        D = tt[None, :] - 2.0 * q @ T.T
        j = np.argmin(D, axis=1)
        idx[s:s + step] = j
        d2[s:s + step] = np.maximum(D[np.arange(len(q)), j] + np.einsum("ij,ij->i", q, q), 0.0)
    return idx, d2


def pairs_within(P: np.ndarray, Q: np.ndarray, radius, budget: int = 1 << 23
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of points closer than ``radius``.

    P : (n, 3), Q : (m, 3) float64; radius : scalar or (n,) per point of P.
    Returns (i, j, distance): (k,) int64, (k,) int64, (k,) float64, ordered by i then j.
    """
    rad = np.broadcast_to(np.asarray(radius, np.float64), (len(P),))
    qq = np.einsum("ij,ij->i", Q, Q)
    out_i, out_j, out_d = [np.empty(0, np.int64)], [np.empty(0, np.int64)], [np.empty(0)]
    step = max(1, budget // max(len(Q), 1))
    for s in range(0, len(P), step):
        p = P[s:s + step]
        d2 = qq[None, :] - 2.0 * p @ Q.T + np.einsum("ij,ij->i", p, p)[:, None]
        i, j = np.nonzero(d2 < (rad[s:s + step] ** 2)[:, None])
        out_i.append(i + s)
        out_j.append(j)
        out_d.append(np.sqrt(np.maximum(d2[i, j], 0.0)))
    return np.concatenate(out_i), np.concatenate(out_j), np.concatenate(out_d)


def min_spacing(P: np.ndarray, chunk: int = 1024) -> float:
    """Smallest distance between two distinct points of P (n, 3); inf for fewer than two."""
    best = np.inf
    for s in range(0, len(P), chunk):
        d2 = ((P[s:s + chunk, None, :] - P[None, :, :]) ** 2).sum(axis=2)
        d2[np.arange(len(d2)), np.arange(s, s + len(d2))] = np.inf
        best = min(best, float(d2.min()))
    return float(np.sqrt(best))
