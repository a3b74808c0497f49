"""Uniform Laplacian smoothing and its inverse (``pmwm.smoothing``): the operator is the attack's step,
and steps taken back restore what the steps forward smoothed."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import meshes
from pmwm import adjacency, metrics, smoothing
from pmwm import attacks as A


@pytest.mark.parametrize("mesh", ["blob", "open_cap"])
def test_the_operator_takes_the_attacks_step(mesh):
    V, F = getattr(meshes, mesh)()
    M = smoothing.mean_operator(F, len(V))
    step = V + 0.1 * (M @ V - V)
    want, _ = A.smooth_laplacian(V, F, lam=0.1, iterations=1)
    assert np.abs(step - want).max() < 1e-12 * np.ptp(V, axis=0).max()


@pytest.mark.parametrize("mesh", ["bunny", "blob", "open_cap", "cad_part", "pinched_torus"])
def test_the_numpy_operator_is_scipys_bit_for_bit(mesh, monkeypatch):
    """A small mesh in a process that has not loaded scipy.sparse gets its edges and its neighbour mean
    from numpy (``adjacency.numpy_sparse``): the same edges and counts, and products equal to the CSR
    matrix's bit for bit, step after step (with a vertex of no face, which keeps itself), so a reading
    does not depend on which of the two a process used."""
    V, F = getattr(meshes, mesh)()
    V = np.vstack([V, [[9.0, 9.0, 9.0]]])
    n = len(V)
    answers = {}
    for numpy_path in (False, True):
        monkeypatch.setattr(adjacency, "numpy_sparse", lambda n, on=numpy_path: on)
        monkeypatch.setattr(smoothing, "numpy_sparse", lambda n, on=numpy_path: on)
        answers[numpy_path] = adjacency.edge_face_counts(F, n), smoothing.mean_operator(F, n)
    (edges, count), M = answers[False]
    (edges_np, count_np), N = answers[True]
    assert isinstance(N, smoothing.NeighbourMean) and not isinstance(M, smoothing.NeighbourMean)
    assert np.array_equal(edges, edges_np) and np.array_equal(count, count_np)
    assert edges_np.dtype == count_np.dtype == np.int64
    assert np.array_equal(M @ V[:, 1], N @ V[:, 1])
    X = Y = V
    for _ in range(20):
        X, Y = 1.1 * X - 0.1 * (M @ X), 1.1 * Y - 0.1 * (N @ Y)
        assert np.array_equal(X, Y)
    assert np.array_equal(Y[-1], V[-1])


def test_a_vertex_with_no_neighbour_stays():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]])
    F = np.array([[0, 1, 2]])
    M = smoothing.mean_operator(F, len(V))
    back = next(smoothing.unsmoothing_steps(V, M, 0.1))
    assert np.array_equal(back[3], V[3])


@pytest.mark.parametrize("mesh", ["blob", "open_cap"])
@pytest.mark.parametrize("steps", [0, 1, 3])
def test_smoothed_takes_the_attacks_steps(mesh, steps):
    """``smoothing.smoothed`` is the benchmark's smoothing attack, step for step (no step: the input)."""
    V, F = getattr(meshes, mesh)()
    M = smoothing.mean_operator(F, len(V))
    want, _ = A.smooth_laplacian(V, F, lam=0.1, iterations=steps)
    got = smoothing.smoothed(V, M, 0.1, steps)
    assert got.shape == V.shape and np.abs(got - want).max() < 1e-12 * np.ptp(V, axis=0).max()


@pytest.mark.parametrize("steps", [5, 20])
def test_steps_back_restore_what_the_steps_forward_smoothed(steps):
    """A step back is the forward step's first-order inverse (it leaves (lam L)^2 per step), so k steps
    forward are undone best by k steps back or a few more: to about a tenth of what they moved (the
    bunny and the blob: 9-12 %, measured), and fewer steps back leave more."""
    V, F = meshes.blob()
    smooth, _ = A.smooth_laplacian(V, F, lam=0.1, iterations=steps)
    M = smoothing.mean_operator(F, len(V))
    back = list(itertools.islice(smoothing.unsmoothing_steps(smooth, M, 0.1), steps + 3))
    moved = metrics.vertex_rmse(smooth, V)
    left = [metrics.vertex_rmse(X, V) / moved for X in back]
    assert min(left[steps - 1 :]) < 0.13
    assert left[steps // 2 - 1] > 0.3 and left[steps // 2 - 1] > min(left[steps - 1 :]) * 2


def _pairs_by_hand(F, n):
    """The neighbour pairs from their definition, edge by edge (a small mesh: a loop is fine here)."""
    from collections import Counter

    faces_of_edge = Counter(
        tuple(sorted((int(f[i]), int(f[(i + 1) % 3])))) for f in F for i in range(3) if f[i] != f[(i + 1) % 3]
    )
    boundary = {v for e, c in faces_of_edge.items() if c == 1 for v in e}
    want = set()
    for (a, b), c in faces_of_edge.items():
        for u, w in ((a, b), (b, a)):
            if u not in boundary or c == 1:
                want.add((u, w))
    return want


@pytest.mark.parametrize("mesh", ["blob", "open_cap"])
def test_whom_each_vertex_averages(mesh):
    """Interior vertices average their 1-ring, boundary vertices their neighbours along boundary edges,
    on a closed mesh, an open one, and one with an edge of three faces and a degenerate face added."""
    V, F = getattr(meshes, mesh)()
    n = len(V)
    extra = np.array([[F[0, 0], F[0, 1], n], [F[0, 1], F[0, 1], F[1, 2]]])  # a third face on edge 0-1; a degenerate one
    for faces, count in ((F, n), (np.vstack([F, extra]), n + 1)):
        owner, nbr = smoothing.neighbour_pairs(faces, count)
        got = list(zip(owner.tolist(), nbr.tolist()))
        assert len(got) == len(set(got))  # each pair once: the mean weighs every neighbour the same
        assert set(got) == _pairs_by_hand(faces, count)
