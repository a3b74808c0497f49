"""1-D Kohonen self-organising map (batch training) and the paper's smoothness classes.

The paper clusters vertices by their smoothness feature with a SOM and keeps the
middle clusters as watermark carriers ("flat and peak surface are not suitable").
Here the map is a row of ``n_units`` prototypes trained with the batch algorithm:
every epoch assigns all samples to their best-matching unit at once, then sets each
prototype to the mean of the samples weighted by a Gaussian neighbourhood on the
row whose width shrinks from n_units / 2 to 0.5. Prototypes start on the data's
quantiles along its first principal axis, so the map starts ordered and training is
stable and deterministic given the seed (the seed only picks the training subsample).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FLAT, SUITABLE, PEAK = 0, 1, 2


@dataclass
class SOM:
    """A trained 1-D map: ``prototypes`` (u, d), in map (row) order."""

    prototypes: np.ndarray

    def assign(self, data: np.ndarray) -> np.ndarray:
        """Index of the best-matching unit of every row of ``data``: (n,) int64."""
        return _bmu(np.ascontiguousarray(np.asarray(data, dtype=np.float64).T), self.prototypes)


def _bmu(xt: np.ndarray, protos: np.ndarray) -> np.ndarray:
    """The best-matching unit (n,) int64 of every sample, given as columns xt (d, n): the least
    |x - p|^2 - |x|^2 = |p|^2 - 2 x.p, the first on a tie (as ``np.argmin``). Elementwise, one
    coordinate row at a time, never a BLAS product: OpenBLAS runs a product of this size on every core,
    its threads spinning while they wait, and the embedders choose the carriers while a worker thread
    builds the progressive mesh; with the cores busy the product slows down many times, the elementwise
    form does not (docs/decisions/083-numpy-fast-paths.md)."""
    best = arg = None
    for u, p in enumerate(protos):  # a few units
        d = float(p @ p) - 2.0 * (xt[0] * p[0])
        for j in range(1, len(xt)):  # a few features
            d -= 2.0 * (xt[j] * p[j])
        if best is None:
            best, arg = d, np.zeros(len(d), np.int64)
        else:
            better = d < best
            np.copyto(best, d, where=better)
            arg[better] = u
    return np.zeros(xt.shape[1], np.int64) if arg is None else arg


def _initial_prototypes(x: np.ndarray, n_units: int) -> np.ndarray:
    """Prototypes on the quantiles of x along its first principal axis (no BLAS product: ``_bmu``)."""
    mean = x.mean(axis=0)
    centred = x - mean
    cov = np.einsum("ij,ik->jk", centred, centred) / max(len(x) - 1, 1)
    _, vecs = np.linalg.eigh(cov)
    axis = vecs[:, -1]
    if axis[np.argmax(np.abs(axis))] < 0:  # fix the eigenvector's sign: deterministic map order
        axis = -axis
    proj = np.einsum("ij,j->i", centred, axis)
    q = np.quantile(proj, (np.arange(n_units) + 0.5) / n_units)
    return mean[None, :] + q[:, None] * axis[None, :]


def train_som(data: np.ndarray, n_units: int = 5, epochs: int = 20, seed: int = 0, sample: int = 20000) -> SOM:
    """Train a 1-D SOM on ``data`` (n, d) by batch epochs on a seeded subsample of <= sample rows."""
    x = np.asarray(data, dtype=np.float64)
    if x.ndim != 2 or len(x) == 0:
        raise ValueError("train_som needs a non-empty (n, d) array")
    if n_units < 1 or epochs < 1:
        raise ValueError("n_units and epochs must be positive")
    if len(x) > sample:
        rng = np.random.default_rng(seed)
        x = x[np.sort(rng.choice(len(x), size=sample, replace=False))]
    protos = _initial_prototypes(x, n_units)
    grid = np.arange(n_units, dtype=np.float64)
    dgrid2 = (grid[:, None] - grid[None, :]) ** 2
    s0, s1 = max(n_units / 2.0, 0.5), 0.5
    xt = np.ascontiguousarray(x.T)  # (d, n): one feature per row
    for epoch in range(epochs):
        sigma = s0 * (s1 / s0) ** (epoch / max(epochs - 1, 1))
        h = np.exp(-dgrid2 / (2.0 * sigma * sigma))  # (u, u) neighbourhood weights
        bmu = _bmu(xt, protos)
        counts = np.bincount(bmu, minlength=n_units).astype(np.float64)
        sums = np.stack([np.bincount(bmu, weights=row, minlength=n_units) for row in xt], axis=1)  # (u, d)
        weight = h @ counts
        ok = weight > 1e-12
        protos[ok] = (h @ sums)[ok] / weight[ok, None]
    return SOM(prototypes=protos)


def classify_smoothness(features: np.ndarray, seed: int = 0, n_units: int = 5) -> np.ndarray:
    """Label vertices 0 = flat, 1 = suitable, 2 = peak from their smoothness features.

    Units are ranked by the mean angle of their prototype: the flattest unit is
    flat, the peakiest is peak, the rest are suitable. Ties (identical prototypes,
    e.g. a mesh whose features are all equal) rank in map order, so such a mesh is
    all flat.
    """
    f = np.asarray(features, dtype=np.float64)
    if n_units < 3:
        raise ValueError("classify_smoothness needs at least 3 units (flat, suitable, peak)")
    if len(f) == 0:
        return np.zeros(0, dtype=np.uint8)
    som = train_som(f, n_units=n_units, seed=seed)
    rank = np.empty(n_units, dtype=np.int64)
    rank[np.argsort(som.prototypes.mean(axis=1), kind="stable")] = np.arange(n_units)
    unit_label = np.full(n_units, SUITABLE, dtype=np.uint8)
    unit_label[rank == 0] = FLAT
    unit_label[rank == n_units - 1] = PEAK
    return unit_label[som.assign(f)]
