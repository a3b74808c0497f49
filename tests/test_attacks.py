"""Each attack's defining property, for both evaluation protocols."""

from __future__ import annotations

import sys
from collections import deque
from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshes
from pmwm import attacks as A
from pmwm.adjacency import build_adjacency
from pmwm.errors import MeshError
from pmwm.metrics import surface_distance
from pmwm.spatial import nearest

BUNNY = Path(A.__file__).parent / "data" / "bunny.off"


def grid(nx: int = 12, ny: int = 10, jitter: float = 0.0, seed: int = 0):
    """A triangulated square grid in the z = 0 plane (open, with a boundary)."""
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    rng = np.random.default_rng(seed)
    v[:, :2] += rng.uniform(-jitter, jitter, size=(len(v), 2))
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, f


@pytest.fixture(scope="module")
def sphere():
    m = trimesh.creation.icosphere(subdivisions=3)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="module")
def ellipsoid(sphere):
    """Stretched sphere: max norm and mean norm differ, so the two noise protocols differ."""
    v, f = sphere
    return v * np.array([3.0, 1.0, 0.5]) + np.array([10.0, -4.0, 2.0]), f


@pytest.fixture(scope="module")
def bunny():
    m = trimesh.load(BUNNY, process=False)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


def norms_about_mean(v):
    return np.linalg.norm(v - v.mean(axis=0), axis=1)


def survivors_in_order(original, cropped):
    """Indices of the cropped vertices in the original; asserts they are an increasing subset."""
    lookup = {tuple(p): i for i, p in enumerate(original)}
    idx = np.array([lookup[tuple(p)] for p in cropped])
    assert np.all(np.diff(idx) > 0), "survivors lost their relative order"
    return idx


# ---------------------------------------------------------------------------------------------
# every attack


ALL_CALLS = [
    ("noise_paper", {"amplitude": 0.01}),
    ("smooth_laplacian", {"lam": 0.1, "iterations": 3}),
    ("crop_paper", {"fraction": 0.2}),
    ("noise_benchmark", {"amplitude": 0.005}),
    ("quantize", {"bits": 6}),
    ("similarity", {}),
    ("reorder", {}),
    ("crop_plane", {"fraction": 0.3}),
    ("simplify", {"ratio": 0.5}),
    ("subdivide", {"scheme": "midpoint"}),
    ("retriangulate", {"fraction": 0.8}),
]


def test_registry_covers_every_attack():
    assert sorted(name for name, _ in ALL_CALLS) == sorted(A.ATTACKS)
    for name in A.ATTACKS:
        params = A.attack_parameters(name)
        assert "seed" in params and "vertices" not in params


@pytest.mark.parametrize("name,params", ALL_CALLS)
def test_attack_returns_new_arrays_and_is_reproducible(name, params, ellipsoid):
    v, f = ellipsoid
    v0, f0 = v.copy(), f.copy()
    v1, f1 = A.ATTACKS[name](v, f, seed=7, **params)
    np.testing.assert_array_equal(v, v0)
    np.testing.assert_array_equal(f, f0)
    assert not np.shares_memory(v1, v) and not np.shares_memory(f1, f)
    assert v1.dtype == np.float64 and f1.dtype == np.int64 and v1.shape[1] == 3 and f1.shape[1] == 3
    assert f1.min() >= 0 and f1.max() < len(v1)
    v2, f2 = A.ATTACKS[name](v, f, seed=7, **params)
    np.testing.assert_array_equal(v1, v2)
    np.testing.assert_array_equal(f1, f2)


RANDOM_ATTACKS = ["noise_paper", "crop_paper", "noise_benchmark", "similarity", "reorder", "crop_plane"]


@pytest.mark.parametrize("name", RANDOM_ATTACKS)
def test_random_attacks_depend_on_the_seed(name, ellipsoid):
    v, f = ellipsoid
    a = A.ATTACKS[name](v, f, seed=1)
    b = A.ATTACKS[name](v, f, seed=2)
    assert not (np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]))


def test_bad_mesh_is_a_mesh_error():
    with pytest.raises(MeshError):
        A.noise_paper(np.zeros((4, 2)), np.array([[0, 1, 2]]), 0.01)
    with pytest.raises(MeshError):
        A.reorder(np.zeros((3, 3)), np.array([[0, 1, 5]]))


# ---------------------------------------------------------------------------------------------
# paper protocol


def test_noise_paper_amplitude_is_relative_to_max_norm(ellipsoid):
    v, f = ellipsoid
    amp = 0.02
    bound = amp * norms_about_mean(v).max()
    v2, f2 = A.noise_paper(v, f, amp, seed=3)
    delta = v2 - v
    assert np.abs(delta).max() <= bound
    assert np.abs(delta).max() > 0.95 * bound  # the whole range is used
    assert abs(delta.mean()) < 0.1 * bound
    np.testing.assert_array_equal(f2, f)


def test_smoothing_one_step_is_the_simultaneous_uniform_update():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # tetrahedron: every vertex sees the 3 others
    lam = 0.25
    v2, _ = A.smooth_laplacian(v, f, lam=lam, iterations=1)
    others_mean = (v.sum(axis=0) - v) / 3.0
    np.testing.assert_allclose(v2, v + lam * (others_mean - v))


def test_smoothing_leaves_a_plane_planar():
    v, f = grid(jitter=0.3)
    normal = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    # tilt the grid into the plane normal . x = 2
    basis = np.linalg.svd(np.eye(3) - np.outer(normal, normal))[0][:, :2]
    v = v[:, :2] @ basis.T + 2.0 * normal
    v2, _ = A.smooth_laplacian(v, f, lam=0.5, iterations=20)
    np.testing.assert_allclose(v2 @ normal, 2.0, atol=1e-12)
    assert np.abs(v2 - v).max() > 0.05  # it did smooth


def test_smoothing_moves_boundary_along_the_boundary_only():
    v, f = grid(jitter=0.0)
    v[:, 1] += 0.2 * np.sin(v[:, 0])  # wavy straight rows: the bottom border is a wavy curve
    adj = build_adjacency(f, len(v))
    v2, _ = A.smooth_laplacian(v, f, lam=0.5, iterations=1)
    bottom = np.flatnonzero(np.isclose(v[:, 1] - 0.2 * np.sin(v[:, 0]), 0.0))[1:-1]  # no corners
    assert adj.boundary_vertex[bottom].all()
    # a straight-grid boundary vertex with boundary neighbours left and right averages only those two
    left, right = bottom - 10, bottom + 10  # grid index = i * ny + j, ny = 10
    expected = v[bottom] + 0.5 * (0.5 * (v[left] + v[right]) - v[bottom])
    np.testing.assert_allclose(v2[bottom], expected)


def test_smoothing_shrinks_and_denoises_a_sphere(sphere):
    v, f = sphere
    noisy, _ = A.noise_paper(v, f, 0.02, seed=1)
    smooth, _ = A.smooth_laplacian(noisy, f, lam=0.1, iterations=10)
    r_noisy, r_smooth = norms_about_mean(noisy), norms_about_mean(smooth)
    assert r_smooth.std() < 0.5 * r_noisy.std()
    assert r_smooth.mean() < r_noisy.mean()


@pytest.mark.parametrize("fraction", [0.03, 0.2])
def test_crop_paper_removes_one_connected_patch(bunny, fraction):
    v, f = bunny
    v2, f2 = A.crop_paper(v, f, fraction, seed=11)
    n = len(v)
    assert n - len(v2) == round(fraction * n)
    kept = survivors_in_order(v, v2)
    removed = np.setdiff1d(np.arange(n), kept)
    # faces: exactly the original faces whose three vertices survive, renumbered
    new_of_old = -np.ones(n, dtype=np.int64)
    new_of_old[kept] = np.arange(len(kept))
    expected = new_of_old[f[(new_of_old[f] >= 0).all(axis=1)]]
    np.testing.assert_array_equal(f2, expected)
    # the removed vertices form one connected piece of the mesh graph
    adj = build_adjacency(f, n)
    is_removed = np.zeros(n, bool)
    is_removed[removed] = True
    seen = {int(removed[0])}
    queue = deque(seen)
    while queue:
        u = queue.popleft()
        for w in adj.ring(u):
            if is_removed[w] and int(w) not in seen:
                seen.add(int(w))
                queue.append(int(w))
    assert len(seen) == len(removed)


# ---------------------------------------------------------------------------------------------
# benchmark protocol


def test_noise_benchmark_amplitude_is_relative_to_mean_norm(ellipsoid):
    v, f = ellipsoid
    amp = 0.005
    norms = norms_about_mean(v)
    assert norms.max() > 1.3 * norms.mean()
    v2, _ = A.noise_benchmark(v, f, amp, seed=5)
    delta = np.abs(v2 - v)
    assert delta.max() <= amp * norms.mean()
    assert delta.max() > 0.95 * amp * norms.mean()


@pytest.mark.parametrize("bits", [7, 11])
def test_quantize_snaps_to_the_bounding_box_grid(bunny, bits):
    v, f = bunny
    v2, f2 = A.quantize(v, f, bits)
    lo, hi = v.min(axis=0), v.max(axis=0)
    step = (hi - lo) / (2**bits - 1)
    q = (v2 - lo) / step
    np.testing.assert_allclose(q, np.rint(q), atol=1e-6)
    assert (np.abs(v2 - v) <= step / 2 + 1e-12).all()
    for axis in range(3):
        assert len(np.unique(np.rint(q[:, axis]))) <= 2**bits
    np.testing.assert_allclose(v2.min(axis=0), lo)
    np.testing.assert_allclose(v2.max(axis=0), hi)
    np.testing.assert_array_equal(f2, f)


@pytest.mark.parametrize("seed", range(5))
def test_similarity_preserves_shape_up_to_scale(ellipsoid, seed):
    v, f = ellipsoid
    v2, f2 = A.similarity(v, f, seed=seed)
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, len(v), size=(2, 200))
    keep = i != j
    ratio = np.linalg.norm(v2[i] - v2[j], axis=1)[keep] / np.linalg.norm(v[i] - v[j], axis=1)[keep]
    scale = ratio.mean()
    np.testing.assert_allclose(ratio, scale, rtol=1e-9)
    assert 0.1 <= scale <= 10.0
    vol = trimesh.Trimesh(v, f, process=False).volume
    vol2 = trimesh.Trimesh(v2, f2, process=False).volume
    np.testing.assert_allclose(vol2, vol * scale**3, rtol=1e-9)  # a rotation: no mirror
    d_bar = norms_about_mean(v).mean()
    # centroid -> s R centroid + t with |t_i| <= 5 dbar
    bound = scale * np.linalg.norm(v.mean(axis=0)) + 5 * np.sqrt(3) * d_bar
    assert np.linalg.norm(v2.mean(axis=0)) <= bound


def canonical_triangles(v, f):
    """Faces as coordinate triples, rotated to start at their smallest point (keeps orientation)."""
    tri = v[f]  # (m, 3, 3)
    keys = [tuple(map(tuple, t)) for t in tri]
    out = []
    for t in keys:
        k = min(range(3), key=lambda r: t[r])
        out.append(t[k:] + t[:k])
    return sorted(out)


def test_reorder_is_a_permutation_of_the_same_geometry(sphere):
    v, f = sphere
    v2, f2 = A.reorder(v, f, seed=4)
    assert not np.array_equal(v2, v) and not np.array_equal(f2, f)
    np.testing.assert_array_equal(np.unique(v, axis=0), np.unique(v2, axis=0))
    assert canonical_triangles(v, f) == canonical_triangles(v2, f2)


@pytest.mark.parametrize("fraction", [0.1, 0.5])
def test_crop_plane_removes_the_requested_share_and_touching_faces(bunny, fraction):
    v, f = bunny
    v2, f2 = A.crop_plane(v, f, fraction, seed=2)
    assert len(v) - len(v2) == round(fraction * len(v))
    kept = survivors_in_order(v, v2)
    new_of_old = -np.ones(len(v), dtype=np.int64)
    new_of_old[kept] = np.arange(len(kept))
    np.testing.assert_array_equal(f2, new_of_old[f[(new_of_old[f] >= 0).all(axis=1)]])
    # the cut is a plane: the removed vertices are linearly separable from the kept ones, so the
    # direction between the two groups' means orders them with at most a thin overlap band
    removed = np.setdiff1d(np.arange(len(v)), kept)
    d = v[removed].mean(axis=0) - v[kept].mean(axis=0)
    assert np.percentile(v[removed] @ d, 5) > np.percentile(v[kept] @ d, 50)


def test_simplify_removes_the_requested_share_of_faces(bunny):
    v, f = bunny
    v2, f2 = A.simplify(v, f, ratio=0.9)
    assert abs(len(f2) - 0.1 * len(f)) < 0.02 * len(f)
    mrms, _ = surface_distance(v, f, v2, f2, n_samples=2000, seed=0)
    assert mrms < 0.5  # % of the bbox diagonal: still the same shape


def test_simplify_without_the_dependency_says_how_to_install(bunny, monkeypatch):
    monkeypatch.setitem(sys.modules, "fast_simplification", None)
    v, f = bunny
    with pytest.raises(ImportError, match="pip install fast-simplification"):
        A.simplify(v, f, 0.5)


def test_midpoint_subdivision_keeps_vertices_and_surface(sphere):
    v, f = sphere
    v2, f2 = A.subdivide(v, f, "midpoint")
    n_edges = len(build_adjacency(f, len(v)).edges)
    assert len(v2) == len(v) + n_edges and len(f2) == 4 * len(f)
    np.testing.assert_array_equal(v2[: len(v)], v)
    area = trimesh.Trimesh(v, f, process=False).area
    np.testing.assert_allclose(trimesh.Trimesh(v2, f2, process=False).area, area, rtol=1e-12)
    adj = build_adjacency(f2, len(v2))
    assert not adj.boundary_vertex.any() and not adj.nonmanifold_vertex.any()


@pytest.mark.parametrize("scheme,face_factor", [("loop", 4), ("sqrt3", 3), ("catmull-clark", 6)])
def test_smooth_subdivisions_give_a_closed_refined_mesh(sphere, scheme, face_factor):
    v, f = sphere
    v2, f2 = A.subdivide(v, f, scheme)
    assert len(f2) == face_factor * len(f)
    adj = build_adjacency(f2, len(v2))
    assert not adj.boundary_vertex.any() and not adj.nonmanifold_vertex.any()
    m, m2 = trimesh.Trimesh(v, f, process=False), trimesh.Trimesh(v2, f2, process=False)
    assert m2.volume > 0  # outward orientation kept
    np.testing.assert_allclose(m2.volume, m.volume, rtol=0.05)


def test_unknown_subdivision_scheme_is_rejected(sphere):
    with pytest.raises(ValueError, match="midpoint"):
        A.subdivide(*sphere, scheme="butterfly")


def test_retriangulate_flips_diagonals_and_keeps_the_surface(bunny):
    V, F = bunny
    V2, F2 = A.retriangulate(V, F, seed=3)
    assert np.array_equal(V2, V) and len(F2) == len(F)
    changed = np.any(np.sort(F2, axis=1) != np.sort(F, axis=1), axis=1).mean()
    assert changed > 0.5  # most faces were re-triangulated
    adj = build_adjacency(F2, len(V))
    assert not adj.nonmanifold_vertex.any()  # no duplicated edge

    # orientation and enclosed volume are kept (a flip inside a planar-ish quad)
    def vol(F_):
        return np.einsum("ij,ij->", np.cross(V[F_[:, 1]], V[F_[:, 2]]), V[F_[:, 0]])

    assert vol(F2) == pytest.approx(vol(F), rel=1e-3)
    assert np.array_equal(A.retriangulate(V, F, seed=3)[1], F2)  # seeded
    assert np.array_equal(A.retriangulate(V, F, fraction=0.0, seed=3)[1], F)


@pytest.mark.parametrize("ext", [".obj", ".ply", ".stl", ".glb"])
def test_reexport_keeps_the_surface_up_to_float32(ext):
    V, F = meshes.blob()
    Vr, Fr = A.reexport(V, F, ext)
    assert len(Fr) == len(F)
    # every written triangle comes back (corners in order), up to float32 rounding, whatever the order
    j, _ = nearest(Vr[Fr].mean(axis=1), V[F].mean(axis=1))  # each triangle's counterpart, by centre
    assert len(np.unique(j)) == len(F)
    assert np.abs(Vr[Fr][j] - V[F]).max() < 1e-6 * np.abs(V).max()
