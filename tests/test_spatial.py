"""pmwm.spatial, the one place of nearest-point and radius queries: the KD-tree answers exactly what a
brute-force scan answers (the same neighbours, pairs, order and distances), on the awkward inputs
too (duplicates, points far from the origin, radii of very different sizes, empty sets), with each
engine (pykdtree, a dependency of the package, and scipy, which answers inside Blender)."""

from __future__ import annotations

import numpy as np
import pytest

from pmwm import spatial
from pmwm.spatial import PointIndex


@pytest.fixture(autouse=True, params=spatial.ENGINES)
def kdtree_engine(request):
    """Every test of this module once per engine."""
    with spatial.using_engine(request.param):
        yield request.param


def test_pykdtree_is_the_engine_where_it_is_installed(kdtree_engine):
    """The package depends on pykdtree, so a pip install answers with it (scipy inside Blender); an
    engine can be chosen for a block, and an unknown one is refused."""
    assert spatial._pykdtree() is not None  # a dependency: importable wherever the tests run
    assert spatial.engine() == kdtree_engine
    with spatial.using_engine("scipy"):
        assert spatial.engine() == "scipy"
    assert spatial.engine() == kdtree_engine
    with pytest.raises(ValueError, match="unknown KD-tree engine"):
        with spatial.using_engine("flann"):
            pass
    spatial._engine.clear()  # chosen afresh at the next query, as in a new process
    assert spatial.engine() == "pykdtree"


def test_radius_queries_ask_for_more_neighbours_until_they_have_them_all():
    """Points with hundreds of neighbours within the radius (far more than FIRST_K): every pair found."""
    rng = np.random.default_rng(12)
    P, Q = rng.normal(size=(30, 3)) * 0.1, rng.normal(size=(3000, 3)) * 0.1
    for a, b in ((P, Q), (Q, P)):
        i, j, d = spatial.pairs_within(a, b, 0.15)
        bi, bj, bd = _pairs_brute(a, b, 0.15)
        assert np.bincount(i).max() > 40 * spatial.FIRST_K or np.bincount(j).max() > 40 * spatial.FIRST_K
        np.testing.assert_array_equal(i, bi)
        np.testing.assert_array_equal(j, bj)
        np.testing.assert_allclose(d, bd, rtol=0, atol=1e-12)


def _points(n: int, seed: int, offset: float = 0.0) -> np.ndarray:
    """n points, a fifth of them exact duplicates of others, some on a coarse grid (ties)."""
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(n, 3))
    P[: n // 5] = P[rng.integers(n // 5, n, n // 5)]
    P[n // 5 : n // 3] = np.round(P[n // 5 : n // 3], 1)
    return P + offset


def _dist(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    return np.sqrt(((A[:, None, :] - B[None, :, :]) ** 2).sum(axis=2))


@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_nearest_finds_a_closest_point_for_every_query(offset):
    T, Q = _points(500, 1, offset), _points(300, 2, offset)
    Q[:50] = T[:50]  # queries exactly on targets
    j, d2 = spatial.nearest(T, Q)
    D = _dist(Q - offset, T - offset)
    best = D.min(axis=1)
    # the point returned is a closest one (ties: any of them), its distance the true distance
    np.testing.assert_allclose(D[np.arange(len(Q)), j], best, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.sqrt(d2), best, rtol=0, atol=1e-9)
    assert np.all(d2[:50] == 0)


def test_nearest_on_an_empty_set_and_a_reused_index():
    j, d2 = spatial.nearest(np.empty((0, 3)), np.zeros((4, 3)))
    assert np.all(j == -1) and np.all(np.isinf(d2))
    T = _points(200, 3)
    index = PointIndex(T)
    for seed in range(3):  # one tree, many queries of any leading shape
        Q = _points(60, 10 + seed).reshape(3, 20, 3)
        j, d2 = index.nearest(Q)
        j1, d21 = spatial.nearest(T, Q.reshape(-1, 3))
        assert j.shape == (3, 20)
        np.testing.assert_array_equal(d2.ravel(), d21)


def test_nearest_within_a_bound_returns_nothing_beyond_it():
    T = np.array([[0.0, 0, 0], [10.0, 0, 0]])
    j, d2 = PointIndex(T).nearest(np.array([[1.0, 0, 0], [4.0, 0, 0], [9.5, 0, 0]]), bound=2.0)
    np.testing.assert_array_equal(j, [0, -1, 1])
    np.testing.assert_array_equal(d2, [1.0, np.inf, 0.25])


@pytest.mark.parametrize("offset", [0.0, 1e6])
@pytest.mark.slow
def test_moving_nearest_answers_as_a_search_of_every_point(offset):
    """Rows of points moved a little (and sometimes far) between calls, searched within bounds of
    every size: the tracker's answers are the tree's, index for index and bit for bit, ties too."""
    T = _points(400, 8, offset)
    index = PointIndex(T)
    rng = np.random.default_rng(9)
    S = _points(120, 11, offset)
    S[:10] = T[:10]  # on targets, some of them duplicated (two nearest at one distance)
    rows = 4
    tracker = spatial.MovingNearest(index, rows, len(S))
    X = np.repeat(S[None], rows, axis=0)
    for step in range(12):
        ids = np.arange(rows) if step % 3 == 0 else np.array([0, 2])
        scale = 1e-3 if step % 4 else 0.3  # mostly small moves, now and then a jump
        X[ids] += rng.normal(scale=scale, size=(len(ids), len(S), 3))
        if step in (5, 9):  # points with none within the bound land next to targets
            X[ids, 20:40] = T[40 + step : 60 + step] + rng.normal(scale=1e-4, size=(len(ids), 20, 3))
        bound = np.array([np.inf, 0.4, 0.05, 2.0])[ids] if step else np.full(len(ids), np.inf)
        j, d2 = tracker.nearest(ids, X[ids], bound)
        for r, b in enumerate(ids):
            fj, fd2 = index.nearest(X[b], bound[r])
            np.testing.assert_array_equal(j[r], fj)
            np.testing.assert_array_equal(d2[r], fd2)
        j2, d22 = index.nearest_rows(X[ids], bound)
        np.testing.assert_array_equal(j2, j)
        np.testing.assert_array_equal(d22, d2)


def test_moving_nearest_on_an_empty_set():
    tracker = spatial.MovingNearest(PointIndex(np.empty((0, 3))), 2, 5)
    j, d2 = tracker.nearest(np.arange(2), np.zeros((2, 5, 3)), np.full(2, np.inf))
    assert np.all(j == -1) and np.all(np.isinf(d2))


def _pairs_brute(P, Q, radius):
    D = _dist(P, Q)
    rad = np.broadcast_to(np.asarray(radius, float), (len(P),))
    i, j = np.nonzero(D < rad[:, None])
    return i, j, D[i, j]


@pytest.mark.parametrize("n_p, n_q", [(80, 400), (400, 80)])  # tree over Q, and over P by radius
@pytest.mark.parametrize("kind", ["scalar", "per point", "spread"])
def test_pairs_within_are_the_brute_force_pairs_in_order(n_p, n_q, kind):
    P, Q = _points(n_p, 4), _points(n_q, 5)
    rng = np.random.default_rng(6)
    radius = {
        "scalar": 0.7,
        "per point": rng.uniform(0.2, 0.9, n_p),
        "spread": np.where(rng.random(n_p) < 0.05, 3.0, rng.uniform(0.0, 0.3, n_p)),
    }[kind]
    i, j, d = spatial.pairs_within(P, Q, radius)
    bi, bj, bd = _pairs_brute(P, Q, radius)
    assert len(i) > 0
    np.testing.assert_array_equal(i, bi)  # ordered by i then j, as the brute force's nonzero
    np.testing.assert_array_equal(j, bj)
    np.testing.assert_allclose(d, bd, rtol=0, atol=1e-12)


@pytest.mark.parametrize("n_p, n_q", [(80, 400), (400, 80)])
@pytest.mark.slow
def test_pairs_within_by_j_are_the_same_pairs_ordered_by_j_then_i(n_p, n_q):
    P, Q = _points(n_p, 4), _points(n_q, 5)
    radius = np.random.default_rng(6).uniform(0.2, 0.9, n_p)
    i, j, d = spatial.pairs_within(P, Q, radius)
    bi, bj, bd = spatial.pairs_within(P, Q, radius, by_j=True)
    order = np.lexsort((i, j))
    np.testing.assert_array_equal(bi, i[order])
    np.testing.assert_array_equal(bj, j[order])
    np.testing.assert_array_equal(bd, d[order])


def test_pairs_within_are_strictly_closer_and_handle_empty_sets():
    P = np.zeros((1, 3))
    Q = np.array([[1.0, 0, 0], [0.5, 0, 0], [2.0, 0, 0]])
    i, j, d = spatial.pairs_within(P, Q, 1.0)  # the point at exactly 1.0 is not closer than 1.0
    np.testing.assert_array_equal(j, [1])
    for a, b in ((np.empty((0, 3)), Q), (Q, np.empty((0, 3)))):
        i, j, d = spatial.pairs_within(a, b, 1.0)
        assert len(i) == len(j) == len(d) == 0
    assert len(spatial.pairs_within(Q, Q, 0.0)[0]) == 0


def test_min_spacing_is_the_smallest_distance_between_two_points():
    P = _points(300, 7)[60:]  # no duplicates
    D = _dist(P, P) + np.diag(np.full(len(P), np.inf))
    assert spatial.min_spacing(P) == pytest.approx(D.min(), abs=1e-12)
    assert spatial.min_spacing(_points(300, 7)) == 0.0  # duplicates
    assert spatial.min_spacing(P[:1]) == np.inf and spatial.min_spacing(np.empty((0, 3))) == np.inf


def test_surface_distances_are_the_brute_force_minimum_over_every_triangle():
    """Triangles of very different sizes (one large, many small), points on, near and far from them."""
    rng = np.random.default_rng(8)
    small = rng.normal(size=(200, 1, 3)) + 0.05 * rng.normal(size=(200, 3, 3))
    big = [[[-5.0, -5, 0], [5, -5, 0], [0, 5, 0]]]
    tri = np.concatenate([small, big, np.zeros((1, 3, 3))])  # + a point-like one
    P = np.concatenate([tri[:50].mean(axis=1), rng.normal(size=(300, 3)), 20 * rng.normal(size=(20, 3))])
    got = spatial.surface_distances(P, tri, chunk=64)
    q, f = np.repeat(np.arange(len(P)), len(tri)), np.tile(np.arange(len(tri)), len(P))
    cp = spatial.closest_point_on_triangles(P[q], tri[f, 0], tri[f, 1], tri[f, 2])
    d = np.linalg.norm(cp - P[q], axis=1)
    np.testing.assert_array_equal(got, d.reshape(len(P), len(tri)).min(axis=1))


@pytest.mark.parametrize("shape", ["two corners equal", "last two equal", "in a line", "all equal"])
def test_the_closest_point_of_a_triangle_of_no_area_is_on_the_segment_it_spans(shape):
    """A triangle without area is a segment (or a point): the region tests divide by zero there (they
    gave NaN); the closest point is the segment's, as its projection finds it."""
    rng = np.random.default_rng(3)
    a, c, P = rng.normal(size=(300, 3)), rng.normal(size=(300, 3)), 2 * rng.normal(size=(300, 3))
    if shape == "all equal":
        c = a.copy()
    b = {
        "two corners equal": a.copy(),
        "last two equal": c.copy(),
        "in a line": 0.3 * a + 0.7 * c,
        "all equal": a.copy(),
    }[shape]
    if shape == "last two equal":
        b, c = c, c.copy()
    with np.errstate(all="raise"):
        got = spatial.closest_point_on_triangles(P, a, b, c)
    d = c - a
    t = np.clip(np.einsum("ij,ij->i", P - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
    np.testing.assert_allclose(got, a + t[:, None] * d, atol=1e-12)
