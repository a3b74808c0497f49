"""Adjacency: the fast sorts, the pinched-vertex walk and the closed-mesh test answer exactly what the
plain forms answer."""

from __future__ import annotations

import numpy as np
import pytest

from pmwm import adjacency
from pmwm.adjacency import build_adjacency, is_closed, stable_order

import meshes


@pytest.mark.parametrize("case", ["ties", "16-bit", "32-bit", "packed", "wide", "negative", "empty", "one"])
@pytest.mark.parametrize("own", [False, True])
def test_stable_order_is_the_stable_argsort(case, own):
    """Every path: one and two 16-bit radix passes (ties across the 2^16 boundary), the packed sort,
    the plain stable argsort (keys too wide, or negative)."""
    rng = np.random.default_rng(3)
    keys = {
        "ties": rng.integers(0, 50, 5000),
        "16-bit": rng.integers(0, 2**16, 5000),
        "32-bit": np.concatenate(
            [rng.integers(0, 2**32, 3000), rng.integers(2**16 - 40, 2**16 + 40, 2000), [2**32 - 1, 0, 2**16]]
        ),
        "packed": rng.integers(0, 2**40, 5000) // 7,
        "wide": rng.integers(0, 2**62, 5000),
        "negative": rng.integers(-20, 20, 5000),
        "empty": np.zeros(0, np.int64),
        "one": np.array([7]),
    }[case].astype(np.int64)
    expected = np.argsort(keys, kind="stable")
    want = keys[expected]
    order, sorted_keys = adjacency._stable_order(keys.copy(), own) if own else stable_order(keys)
    assert np.array_equal(order, expected)
    assert np.array_equal(sorted_keys, want)
    assert order.dtype == np.int64 and sorted_keys.dtype == np.int64


def _pinched_variants():
    """Test meshes with random vertex pairs merged (pinches, non-manifold edges, open fans)."""
    rng = np.random.default_rng(5)
    out = []
    for V, F in (meshes.blob(), meshes.open_cap(), meshes.pinched_torus()):
        n = len(V)
        for k in range(3):
            remap = np.arange(n)
            remap[rng.integers(0, n, 60)] = rng.integers(0, n, 60)
            G = remap[F]
            G = G[(G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 0] != G[:, 2])]
            if k == 1:
                G = G[rng.random(len(G)) > 0.05]  # holes: open fans
            out.append((G, n))
    return out


def _fan_count_reference(F, n):
    """Fans per vertex by the pointer doubling (``_fan_count``), from the same half-edge twins."""
    he_from = F.ravel()
    he_to = np.roll(F, -1, axis=1).ravel()
    keys = np.minimum(he_from, he_to) * n + np.maximum(he_from, he_to)
    o = np.argsort(keys, kind="stable")
    sk = keys[o]
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    counts = np.diff(np.r_[starts, len(sk)])
    fwd = np.add.reduceat((he_from < he_to)[o].astype(np.int64), starts)
    clean = (counts == 2) & (fwd == 1)
    twin = np.full(len(he_from), -1)
    twin[o[starts[clean]]] = o[starts[clean] + 1]
    twin[o[starts[clean] + 1]] = o[starts[clean]]
    return adjacency._fan_count(he_from, twin, np.argsort(he_from, kind="stable"), n)


@pytest.mark.parametrize("walk_steps", [adjacency.WALK_STEPS, 2])
def test_pinched_vertices_match_the_fan_count(monkeypatch, walk_steps):
    monkeypatch.setattr(adjacency, "WALK_STEPS", walk_steps)  # 2: the pointer doubling answers
    found = 0
    for F, n in _pinched_variants():
        adj = build_adjacency(F, n)
        plain = build_adjacency(F, n, detect_pinches=False)
        pinched = _fan_count_reference(F, n) > 1
        assert np.array_equal(adj.nonmanifold_vertex, plain.nonmanifold_vertex | pinched)
        found += int((pinched & ~plain.nonmanifold_vertex).sum())
    assert found > 0  # the variants do have pinches that only the fan count finds


def test_pinched_torus_has_exactly_its_one_pinch():
    V, F = meshes.pinched_torus()
    assert len(np.flatnonzero(build_adjacency(F, len(V)).nonmanifold_vertex)) == 1


@pytest.mark.parametrize("name", ["blob", "open_cap", "cad_part", "pinched_torus"])
def test_is_closed_agrees_with_the_boundary_edges(name):
    V, F = getattr(meshes, name)()
    has_boundary = bool(np.any(build_adjacency(F, len(V)).edge_face_count == 1))
    assert is_closed(F, len(V)) == (not has_boundary)
    if not has_boundary:  # one face removed opens it; one face flipped breaks the twins too
        assert not is_closed(F[1:], len(V))
        assert not is_closed(np.vstack([F[:1, ::-1], F[1:]]), len(V))


@pytest.mark.parametrize("name", ["blob", "open_cap", "cad_part", "pinched_torus"])
def test_edge_face_counts_are_the_adjacencys_edges(name):
    """The cheap edge list is build_adjacency's: the same edges, the same face counts, closed or open;
    with a degenerate face added, its repeated corner makes no edge."""
    V, F = getattr(meshes, name)()
    adj = build_adjacency(F, len(V))
    edges, count = adjacency.edge_face_counts(F, len(V))
    assert np.array_equal(edges, adj.edges) and np.array_equal(count, adj.edge_face_count)
    edges, _ = adjacency.edge_face_counts(np.vstack([F, [[F[0, 0], F[0, 0], F[0, 1]]]]), len(V))
    assert not (edges[:, 0] == edges[:, 1]).any()


@pytest.mark.parametrize("name", ["bunny", "blob", "open_cap", "cad_part", "pinched_torus"])
def test_boundary_edges_are_the_edges_of_one_face(name):
    """``boundary_edges`` (numpy alone) names exactly the edges ``edge_face_counts`` counts once, in its
    order: closed and open meshes, a mesh cut by a plane, one with a face flipped (its edges then have
    two faces that disagree), with a degenerate face, and random soups with repeated corners and edges of
    one, two, three or more faces."""

    def expected(F, n):
        edges, count = adjacency.edge_face_counts(F, n)
        return edges[count == 1]

    V, F = getattr(meshes, name)()
    n = len(V)
    cut = F[(V[F].mean(1)[:, 0] < np.median(V[:, 0]))]
    flipped = np.vstack([F[:1, ::-1], F[1:]])
    degenerate = np.vstack([F, [[F[0, 0], F[0, 0], F[0, 1]]]])
    for faces in (F, F[1:], cut, flipped, degenerate):
        want = expected(faces, n)
        got = adjacency.boundary_edges(faces, n)
        assert got.dtype == np.int64 and got.shape == want.shape and np.array_equal(got, want)
    assert len(expected(cut, n)) > 0
    rng = np.random.default_rng(5)
    for _ in range(200):
        k = int(rng.integers(3, 30))
        soup = rng.integers(0, k, size=(int(rng.integers(1, 60)), 3))
        assert np.array_equal(adjacency.boundary_edges(soup, k), expected(soup, k))


def test_edge_face_counts_in_numpy_are_scipys(monkeypatch):
    """The two ways ``edge_face_counts`` counts (``adjacency.numpy_sparse``) agree on random soups:
    repeated corners, edges of one to many faces, vertices of no face, no face at all."""
    rng = np.random.default_rng(8)
    soups = [rng.integers(0, k, size=(int(rng.integers(0, 60)), 3)) for k in rng.integers(3, 30, 200)]
    for F in soups:
        n = int(F.max(initial=0)) + 3
        got = []
        for numpy_path in (False, True):
            monkeypatch.setattr(adjacency, "numpy_sparse", lambda n, on=numpy_path: on)
            got.append(adjacency.edge_face_counts(F, n))
        (e1, c1), (e2, c2) = got
        assert e1.shape == e2.shape and np.array_equal(e1, e2) and np.array_equal(c1, c2)
        assert e2.dtype == c2.dtype == np.int64


def test_unique_values_are_those_of_np_unique():
    """``unique_values`` (a sort, not numpy 2's hash set) gives np.unique's values: integers with many
    repeats or none, any shape, floats, one value, none."""
    rng = np.random.default_rng(3)
    cases = [
        rng.integers(0, 50, 1000),
        rng.integers(-(2**40), 2**40, 5000),
        rng.integers(0, 9, (30, 4)),
        rng.normal(size=200).round(1),
        np.array([7]),
        np.zeros(0, np.int64),
        np.arange(10)[::-1],
    ]
    for x in cases:
        got = adjacency.unique_values(x)
        assert got.dtype == x.dtype and np.array_equal(got, np.unique(x))


@pytest.mark.parametrize("seed", range(4))
def test_component_labels_are_scipys_components_named_by_their_least_vertex(seed):
    """Random graphs of cycles, paths and stray edges over scattered vertex ids: every edge gets its
    component's least vertex id, the same partition as scipy's connected_components."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(seed)
    ids = rng.permutation(5000)
    parts, at = [], 0
    for length in rng.integers(2, 300, 12):
        p = ids[at : at + length]
        at += length
        parts.append(
            np.stack([p, np.roll(p, -1)], 1) if length > 2 and rng.random() < 0.7 else np.stack([p[:-1], p[1:]], 1)
        )
    E = np.concatenate(parts)[rng.permutation(sum(len(q) for q in parts))]
    got = adjacency.component_labels(E)
    _, comp = connected_components(
        coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(5000, 5000)), directed=False
    )
    least = np.full(comp.max() + 1, 1 << 40)
    np.minimum.at(least, comp[E.ravel()], E.ravel())
    np.testing.assert_array_equal(got, least[comp[E[:, 0]]])
    assert len(adjacency.component_labels(np.zeros((0, 2), np.int64))) == 0


def test_component_labels_of_one_long_cycle():
    p = np.random.default_rng(1).permutation(200_000)[:50_000]
    got = adjacency.component_labels(np.stack([p, np.roll(p, -1)], 1))
    assert np.all(got == p.min())


@pytest.mark.parametrize("kind", ["distinct", "ties", "nan"])
def test_stable_argsort_is_numpys_stable_argsort(kind):
    x = np.random.default_rng(2).random(5000)
    if kind == "ties":
        x = np.round(x * 50) / 50
    if kind == "nan":
        x[[3, 70, 900]] = np.nan
    np.testing.assert_array_equal(adjacency.stable_argsort(x), np.argsort(x, kind="stable"))
    assert adjacency.stable_argsort(np.zeros(0)).tolist() == [] and adjacency.stable_argsort([2.0]).tolist() == [0]
