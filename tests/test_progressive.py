"""Progressive mesh: exact reconstruction at every level of detail, and the .pmwm round trip."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import pmwm
from pmwm.progressive import build_progressive_mesh, from_bytes, to_bytes, with_positions

import meshes
from conftest import canonical_faces, quad_torus_obj


def _oriented_manifold(F: np.ndarray) -> bool:
    """No face repeats a vertex and every directed edge appears once (so every edge has at most two
    faces, consistently oriented)."""
    if np.any((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])):
        return False
    e = np.stack([F.ravel(), F[:, [1, 2, 0]].ravel()], axis=1)
    return len(np.unique(e, axis=0)) == len(e)


def _euler(F: np.ndarray, n: int) -> int:
    e = np.sort(np.stack([F.ravel(), F[:, [1, 2, 0]].ravel()], axis=1), axis=1)
    return n - len(np.unique(e, axis=0)) + len(F)


def _check_every_level(V, F, base_ratio=0.03, protected=None, forced=None, **kw):
    trace: list = []
    pm, done = build_progressive_mesh(
        V, F, base_vertices=int(base_ratio * len(V)), protected=protected, forced=forced, trace=trace, **kw
    )
    if forced is not None:
        # every applied forced collapse happened: its u is a record that splits from its v
        rec_of = np.full(len(V), -1)
        rec_of[pm.vertex_order[pm.n_base_vertices :]] = np.arange(pm.n_records)
        u, v = forced[done, 0], forced[done, 1]
        assert np.all(rec_of[u] >= 0)
        assert np.array_equal(pm.vertex_order[pm.v[rec_of[u]]], v)
    order = pm.vertex_order
    # the full mesh is the input, exactly: same positions, same oriented triangles
    V_full, F_full = pm.decode()
    assert np.array_equal(V_full, V[order])
    assert np.array_equal(canonical_faces(order[F_full]), canonical_faces(F))
    # every level of detail is exactly the mesh the encoder had after the matching pass
    P = len(trace)
    assert len(pm.level_records) == P
    for j in range(P):
        k = int(pm.level_records[j]) if j < P - 1 else None
        expect = trace[P - 2 - j] if j < P - 1 else F
        Vk, Fk = pm.decode(records=k)
        assert np.array_equal(Vk, V[order[: len(Vk)]])
        assert np.array_equal(canonical_faces(order[Fk]), canonical_faces(expect))
        # (the collapses of a pass together keep the mesh an oriented manifold: no edge gets three
        # faces, no face comes twice)
        assert _oriented_manifold(Fk) or not _oriented_manifold(F)
        assert _euler(Fk, len(Vk)) == _euler(F, len(V))
    Vb, Fb = pm.decode(records=0)
    assert np.array_equal(canonical_faces(order[Fb]), canonical_faces(trace[-1]))
    # and the file stores exactly the same progressive mesh
    back = from_bytes(to_bytes(pm))
    for k in [0, pm.n_records // 3, pm.n_records]:
        a, b = pm.decode(records=k), back.decode(records=k)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    return pm


@pytest.mark.slow
def test_bunny_every_level_exact(bunny):
    V, F = bunny
    V = V.astype(np.float32).astype(np.float64)
    pm = _check_every_level(V, F)
    assert pm.n_base_vertices <= 0.035 * len(V)
    Vb, Fb = pm.decode(records=0)
    base = trimesh.Trimesh(Vb, Fb, process=False)
    assert base.is_watertight and base.is_winding_consistent
    assert base.euler_number == trimesh.Trimesh(V, F, process=False).euler_number


@pytest.mark.parametrize("rounds", [1, 4])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.slow
def test_rough_shapes_every_level_exact_and_manifold(seed, rounds):
    # noisy, unevenly sampled closed shapes: many collapses with overlapping 1-rings in one pass; with
    # more than one selection round, later rounds must respect the collapses accepted before
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(subdivisions=4)
    V = m.vertices * (1 + 0.2 * rng.random((len(m.vertices), 1))) + 0.01 * rng.standard_normal(m.vertices.shape)
    pm = _check_every_level(V, np.asarray(m.faces), base_ratio=0.02, selection_rounds=rounds)
    assert len(pm.level_records) >= 4


@pytest.mark.parametrize("seed", [1, 14, 25])
@pytest.mark.slow
def test_a_sphere_full_of_holes_keeps_its_topology_at_every_level(seed):
    # a quarter of the faces dropped: many triangles with two boundary edges (ears). Collapsing an
    # ear's edge would close a hole; the check counted an ear's two boundary edges as one (seed 14 then
    # changed the Euler number at some level)
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(subdivisions=3)
    F = m.faces[rng.random(len(m.faces)) > 0.25]
    V = m.vertices + 0.02 * rng.standard_normal(m.vertices.shape)
    _check_every_level(V, F, base_ratio=0.016)


def _thin_tube(per_ring: int, rings: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed, twisted tube of ``rings`` rings of ``per_ring`` vertices (each quad split along a random
    diagonal), capped by two poles, its vertices jittered: (n, 3) float64, (m, 3) int64."""
    rng = np.random.default_rng(seed)
    twist = rng.random()
    r, i = np.divmod(np.arange(rings * per_ring), per_ring)
    angle = 2 * np.pi * i / per_ring + twist * r
    V = np.stack([np.cos(angle), np.sin(angle), 0.7 * r], axis=1)
    V = np.vstack([V + 0.05 * rng.standard_normal(V.shape), [[0, 0, -0.7], [0, 0, 0.7 * rings]]])
    r, i = np.divmod(np.arange((rings - 1) * per_ring), per_ring)
    a, b = r * per_ring + i, r * per_ring + (i + 1) % per_ring
    c, d = a + per_ring, b + per_ring
    one = rng.random(len(a)) < 0.5  # the diagonal a-d, else b-c
    quads = np.where(
        one[:, None, None],
        np.stack([np.stack([a, b, d], 1), np.stack([a, d, c], 1)], 1),
        np.stack([np.stack([a, b, c], 1), np.stack([b, d, c], 1)], 1),
    ).reshape(-1, 3)
    i = np.arange(per_ring)
    n, top = len(V) - 2, (rings - 1) * per_ring
    caps = np.concatenate(
        [
            np.stack([np.full(per_ring, n), (i + 1) % per_ring, i], 1),
            np.stack([np.full(per_ring, n + 1), top + i, top + (i + 1) % per_ring], 1),
        ]
    )
    return V, np.concatenate([quads, caps])


@pytest.mark.slow
def test_every_level_keeps_the_topology_with_holes_protected_vertices_and_forced_collapses(bunny):
    # the link and valence checks read each vertex's face count, which the passes keep up to date
    # instead of recounting (``self_check`` compares it with a recount after every pass); a wrong count
    # lets a collapse fold two faces onto each other or close a hole: every level must stay an oriented
    # manifold with the input's Euler number (holes, protected vertices, the paper scheme's forced
    # collapses)
    rng = np.random.default_rng(14)
    m = trimesh.creation.icosphere(subdivisions=3)
    _check_every_level(m.vertices, m.faces[rng.random(len(m.faces)) > 0.25], base_ratio=0.06, self_check=True)
    V, F = bunny
    _check_every_level(V, F, base_ratio=0.1, protected=rng.random(len(V)) < 0.05, self_check=True)
    V, F = meshes.blob()
    adj = pmwm.adjacency.build_adjacency(F, len(V))
    u = np.arange(0, len(V), 31)
    _check_every_level(V, F, forced=np.stack([u, adj.ring_idx[adj.ring_ptr[u]]], axis=1), self_check=True)


@pytest.mark.parametrize("per_ring, rings, seed", [(4, 13, 30), (4, 14, 138), (4, 13, 159), (4, 19, 278)])
def test_thin_tubes_keep_every_level_manifold(per_ring, rings, seed):
    # rings of 4 vertices: two opposite vertices of a ring share both their neighbours in it, so one pass
    # could collapse each into a different one of them, each collapse valid alone, and make the edge
    # between those two twice (four faces on it); a pass allows no such pair (the third rule of
    # ``pmwm.progressive.select``)
    V, F = _thin_tube(per_ring, rings, seed)
    assert _oriented_manifold(F)
    _check_every_level(V, F, base_ratio=0.05)


@pytest.mark.slow
def test_levels_of_detail_stay_close_to_the_input(bunny):
    # a pass collapses the cheap vertices first: halfway and three quarters of the way up, no point of
    # the bunny's level is more than 0.1 % / 0.06 % of the bounding-box diagonal from the full mesh
    # (about twice that, or four times, when expensive collapses win a pass among more expensive ones)
    V, F = bunny
    pm, _ = build_progressive_mesh(V, F, base_vertices=int(0.03 * len(V)))
    ends = np.r_[0, pm.level_records]
    for share, bound in [(0.5, 0.1), (0.75, 0.06)]:
        k = int(ends[np.argmin(np.abs(ends - share * pm.n_records))])
        Vk, Fk = pm.decode(records=k)
        mrms, hausdorff = pmwm.metrics.surface_distance(V, F, Vk, Fk, n_samples=20000, seed=0)
        assert hausdorff < bound, (share, mrms, hausdorff)


@pytest.mark.slow
def test_open_boundary_every_level_exact():
    V, F = meshes.open_cap()
    pm = _check_every_level(V, F)
    # the boundary stays one loop at every level
    for k in [0, int(pm.level_records[len(pm.level_records) // 2])]:
        Vk, Fk = pm.decode(records=k)
        m = trimesh.Trimesh(Vk, Fk, process=False)
        assert not m.is_watertight and m.is_winding_consistent
        assert m.euler_number == 1


def test_quad_mesh_every_level_exact(tmp_path):
    path = tmp_path / "torus.obj"
    path.write_text(quad_torus_obj())
    src = pmwm.read_mesh(path)
    assert len(src.faces) == 2 * 40 * 24  # every quad became two triangles
    _check_every_level(src.vertices, src.faces, base_ratio=0.1)


def test_protected_vertices_survive_to_the_base(bunny):
    V, F = bunny
    keep = np.zeros(len(V), bool)
    keep[::997] = True
    pm, _ = build_progressive_mesh(V, F, base_vertices=500, protected=keep)
    base_input_ids = pm.vertex_order[: pm.n_base_vertices]
    assert set(np.flatnonzero(keep)) <= set(base_input_ids.tolist())


@pytest.mark.slow
def test_vertices_to_protect_given_after_the_set_up_give_the_same_progressive_mesh(bunny):
    """The robust embedder starts the build before it knows which vertices to protect: the build
    asks for them after its set-up, and must build what it builds when given them at the start."""
    V, F = bunny
    keep = np.zeros(len(V), bool)
    keep[::211] = True
    asked = []

    def later():
        asked.append(True)
        return keep

    want, _ = build_progressive_mesh(V, F, base_vertices=800, protected=keep)
    got, _ = build_progressive_mesh(V, F, base_vertices=800, protected=later)
    assert asked == [True]
    assert np.array_equal(got.vertex_order, want.vertex_order)
    assert np.array_equal(got.level_records, want.level_records)
    assert to_bytes(got) == to_bytes(want)
    assert set(np.flatnonzero(keep)) <= set(got.vertex_order[: got.n_base_vertices].tolist())
    unprotected, _ = build_progressive_mesh(V, F, base_vertices=800)
    assert to_bytes(unprotected) != to_bytes(want)  # (the protection made a difference to check)


def test_decode_by_vertex_count(bunny):
    V, F = bunny
    pm, _ = build_progressive_mesh(V, F, base_vertices=1000)
    Vn, Fn = pm.decode(vertices=5000)
    assert len(Vn) == 5000
    assert trimesh.Trimesh(Vn, Fn, process=False).is_watertight
    # clamped at both ends
    assert len(pm.decode(vertices=10)[0]) == pm.n_base_vertices
    assert len(pm.decode(vertices=10**9)[0]) == len(V)


@pytest.mark.slow
def test_nonmanifold_vertex_is_kept_and_reconstructed():
    V, F = meshes.pinched_torus()  # one pinched vertex
    adj = pmwm.adjacency.build_adjacency(F, len(V))
    pinched = np.flatnonzero(adj.nonmanifold_vertex)
    assert len(pinched) == 1
    pm = _check_every_level(V, F, base_ratio=0.05)
    assert pinched[0] in pm.vertex_order[: pm.n_base_vertices]


@pytest.mark.slow
def test_forced_collapses_go_first_and_every_level_stays_exact():
    V, F = meshes.blob()
    adj = pmwm.adjacency.build_adjacency(F, len(V))
    # spread-out vertices, each absorbed by its first neighbour (what the paper scheme forces)
    u = np.arange(0, len(V), 97)
    v = adj.ring_idx[adj.ring_ptr[u]]
    forced = np.stack([u, v], axis=1)
    pm = _check_every_level(V, F, forced=forced)
    assert pm.n_base_vertices <= 0.035 * len(V)


def test_bad_faces_are_refused():
    V = np.zeros((3, 3))
    with pytest.raises(pmwm.MeshError):
        build_progressive_mesh(V, np.array([[0, 1, 1]]), base_vertices=3)
    with pytest.raises(pmwm.MeshError):
        build_progressive_mesh(V, np.array([[0, 1, 5]]), base_vertices=3)


@pytest.mark.slow
def test_a_moved_mesh_takes_the_progressive_mesh_of_the_unmoved_one_with_its_own_positions(bunny):
    """``with_positions``: the embedders build the progressive mesh of the unmarked mesh and put the
    marked positions in; every level keeps its faces and takes the new positions, and the file
    stores them exactly."""
    V, F = bunny
    pm, _ = build_progressive_mesh(V, F, base_vertices=int(0.03 * len(V)))
    rng = np.random.default_rng(5)
    X = (V + rng.normal(scale=1e-4, size=V.shape)).astype(np.float32).astype(np.float64)
    moved = with_positions(pm, X)
    order = pm.vertex_order
    back = from_bytes(to_bytes(moved))
    for k in [0, pm.n_records // 3, pm.n_records]:
        Vk, Fk = moved.decode(records=k)
        assert np.array_equal(Fk, pm.decode(records=k)[1])
        assert np.array_equal(Vk, X[order[: len(Vk)]])
        assert np.array_equal(back.decode(records=k)[0], Vk)
    with pytest.raises(ValueError, match="one position per vertex"):
        with_positions(pm, X[:-1])
