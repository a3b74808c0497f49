"""Mesh file I/O: exact round trips, welding, triangulation, clean errors, atomic writes."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from pmwm import meshio
from pmwm.errors import MeshError, OutputExistsError, PmwmError
from pmwm.atomic import atomic_output, atomic_write_bytes
from pmwm.meshio import read_mesh, weld, write_marked, write_mesh

import meshes

PACKAGED_BUNNY = Path(meshio.__file__).parent / "data" / "bunny.off"


def _mesh(seed: int = 0, n: int = 60, m: int = 100, float32: bool = True):
    """Random vertices (float32-exact if asked) with varied magnitudes and non-degenerate faces."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-6, 4, size=(n, 1))
    if float32:
        v = v.astype(np.float32).astype(np.float64)
    f = rng.integers(0, n - 1, size=(m, 3))  # the last vertex stays unreferenced
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    return v, f.astype(np.int64)


def _triangles(v, f):
    """Order-independent view of the geometry: the sorted list of triangles as 9 coordinates."""
    tri = v[f].reshape(len(f), 9)
    return tri[np.lexsort(tri.T[::-1])]


# ---------------------------------------------------------------- round trips


@pytest.mark.parametrize("ext", [".ply", ".off", ".obj"])
def test_write_read_keeps_vertex_order_faces_and_float32_values(tmp_path, ext):
    v, f = _mesh(1)
    path = tmp_path / f"m{ext}"
    write_mesh(path, v, f)
    src = read_mesh(path)
    assert np.array_equal(src.vertices, v)  # bit-exact, same order, unreferenced vertex kept
    assert np.array_equal(src.faces, f)
    assert src.float32
    assert np.array_equal(src.source_to_canonical, np.arange(len(v)))


@pytest.mark.parametrize("ext", [".off", ".obj"])
def test_text_formats_keep_float64_exactly(tmp_path, ext):
    v, f = _mesh(2, float32=False)
    v[0] = (1e-300, -0.0, 123456789.123456789)
    path = tmp_path / f"m{ext}"
    write_mesh(path, v, f)
    src = read_mesh(path)
    assert np.array_equal(src.vertices, v)
    assert not src.float32


@pytest.mark.parametrize("ext", [".ply", ".glb", ".stl"])
def test_binary_formats_store_float32(tmp_path, ext):
    v, f = _mesh(3, float32=False)
    path = tmp_path / f"m{ext}"
    write_mesh(path, v, f)
    src = read_mesh(path)
    assert src.float32
    expected = v.astype(np.float32).astype(np.float64)
    assert np.array_equal(_triangles(src.vertices, src.faces), _triangles(expected, f))


@pytest.mark.parametrize("ext", [".stl", ".glb", ".gltf"])
def test_stl_and_gltf_round_trip_the_same_geometry_after_weld(tmp_path, ext):
    v, f = _mesh(4)
    path = tmp_path / f"m{ext}"
    write_mesh(path, v, f)
    src = read_mesh(path)
    assert np.array_equal(_triangles(src.vertices, src.faces), _triangles(v, f))
    if ext == ".stl":  # a triangle soup: welded back to the shared, referenced vertices
        assert len(src.vertices) == len(np.unique(f))
    else:  # glTF stores indexed float32 vertices: order and unreferenced vertices kept
        assert np.array_equal(src.vertices, v)
        assert np.array_equal(src.faces, f)


def test_stl_soup_is_welded_with_a_warning(tmp_path):
    v, f = _mesh(5)
    path = tmp_path / "m.stl"
    write_mesh(path, v, f)
    src = read_mesh(path)
    assert len(src.source.vertices) == 3 * len(f)
    assert any("welded" in w for w in src.warnings)
    assert np.array_equal(src.vertices[src.source_to_canonical], src.source.vertices)


def test_obj_quads_and_ngons_are_triangulated(tmp_path):
    path = tmp_path / "quads.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nv 3 0.5 0\nf 1 2 3 4\nf 2 5 6 3\nf 5 7 6\n")
    src = read_mesh(path)
    assert src.faces.shape == (5, 3)
    assert len(src.vertices) == 7
    tri = src.vertices[src.faces]
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert np.isclose(areas.sum(), 1 + 1 + 0.5)  # two unit squares and a triangle, no overlap
    assert (areas > 0).all()


def test_degenerate_faces_are_dropped_with_a_warning(tmp_path):
    path = tmp_path / "degen.obj"
    # vertices 3 and 4 share a position, so the last face collapses after welding
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 1 0\nf 1 2 3\nf 2 3 4\n")
    src = read_mesh(path)
    assert src.faces.tolist() == [[0, 1, 2]]
    assert any("degenerate" in w for w in src.warnings)


def test_multi_mesh_glb_scene_is_concatenated(tmp_path):
    box = trimesh.creation.box()
    ball = trimesh.creation.icosphere(subdivisions=1)
    ball.apply_translation([3.0, 0.0, 0.0])
    path = tmp_path / "scene.glb"
    trimesh.Scene([box, ball]).export(path)
    src = read_mesh(path)
    assert len(src.vertices) == len(box.vertices) + len(ball.vertices)
    assert len(src.faces) == len(box.faces) + len(ball.faces)
    assert any("scene of 2 meshes" in w for w in src.warnings)
    assert src.vertices[:, 0].max() > 3.5  # the translated ball is where the scene put it


# ---------------------------------------------------------------- UV seams


def _tube_obj(path: Path, k: int = 6, rings: int = 3) -> np.ndarray:
    """An open tube whose UV seam splits one column of vertices; returns the k*rings positions."""
    ang = 2 * np.pi * np.arange(k) / k
    pos = np.array([(np.cos(a), np.sin(a), float(r)) for r in range(rings) for a in ang])
    uv = np.array([(c / k, r / (rings - 1)) for r in range(rings) for c in range(k + 1)])
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in pos.tolist()]
    lines += [f"vt {a!r} {b!r}" for a, b in uv.tolist()]
    for r in range(rings - 1):
        for c in range(k):
            quad_v = [r * k + c, r * k + (c + 1) % k, (r + 1) * k + (c + 1) % k, (r + 1) * k + c]
            quad_t = [r * (k + 1) + c, r * (k + 1) + c + 1, (r + 1) * (k + 1) + c + 1, (r + 1) * (k + 1) + c]
            lines.append("f " + " ".join(f"{a + 1}/{t + 1}" for a, t in zip(quad_v, quad_t)))
    path.write_text("\n".join(lines) + "\n")
    return pos


def _boundary_edge_count(faces: np.ndarray) -> int:
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int((counts == 1).sum())


def test_uv_seam_obj_is_welded_into_the_connected_surface(tmp_path):
    k, rings = 6, 3
    path = tmp_path / "tube.obj"
    pos = _tube_obj(path, k, rings)
    src = read_mesh(path)
    assert len(src.source.vertices) == (k + 1) * rings  # trimesh split the seam column
    assert len(src.vertices) == k * rings
    assert {tuple(p) for p in src.vertices} == {tuple(p) for p in pos}
    assert _boundary_edge_count(src.faces) == 2 * k  # only the two rims: the seam is closed
    assert _boundary_edge_count(np.asarray(src.source.faces)) == 2 * k + 2 * (rings - 1)


def test_write_marked_keeps_uvs_vertex_count_and_moves_seam_copies_together(tmp_path):
    path = tmp_path / "tube.obj"
    _tube_obj(path)
    src = read_mesh(path)
    rng = np.random.default_rng(7)
    marked = src.vertices + rng.normal(scale=1e-3, size=src.vertices.shape)
    out = tmp_path / "tube_marked.obj"
    write_marked(out, src, marked)
    back = read_mesh(out)
    assert len(back.source.vertices) == len(src.source.vertices)
    assert np.array_equal(back.source.visual.uv, src.source.visual.uv)
    assert np.array_equal(back.source.faces, src.source.faces)
    assert np.array_equal(back.source.vertices, marked[src.source_to_canonical])
    assert np.array_equal(back.vertices, marked)  # same canonical order, exact positions
    assert np.array_equal(back.faces, src.faces)


@pytest.mark.parametrize("ext", [".ply", ".glb"])
def test_write_marked_to_binary_formats_keeps_file_vertices_and_uvs(tmp_path, ext):
    path = tmp_path / "tube.obj"
    _tube_obj(path)
    src = read_mesh(path)
    marked = (src.vertices * 1.5).astype(np.float32).astype(np.float64)
    out = tmp_path / f"tube_marked{ext}"
    write_marked(out, src, marked)
    back = read_mesh(out)
    assert len(back.source.vertices) == len(src.source.vertices)
    assert np.array_equal(back.source.vertices, marked[src.source_to_canonical])
    assert np.allclose(back.source.visual.uv, src.source.visual.uv, atol=1e-6)
    assert np.array_equal(back.vertices, marked)


def test_write_marked_rejects_wrong_vertex_count(tmp_path):
    path = tmp_path / "tube.obj"
    _tube_obj(path)
    src = read_mesh(path)
    with pytest.raises(MeshError):
        write_marked(tmp_path / "out.obj", src, src.vertices[:-1])
    assert not (tmp_path / "out.obj").exists()


# ---------------------------------------------------------------- errors


def _error_cases(tmp_path: Path):
    ply_points = tmp_path / "points.ply"
    ply_points.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
    )
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    lines = tmp_path / "lines.obj"
    lines.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2 3\n")
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n")
    inf = tmp_path / "inf.off"
    inf.write_text("OFF\n3 1 0\n0 0 0\ninf 0 0\n1 1 0\n3 0 1 2\n")
    folder = tmp_path / "folder.obj"
    folder.mkdir()
    cases = {
        "point cloud": (ply_points, "no triangle mesh"),
        "empty": (empty, "no triangle mesh"),
        "lines only": (lines, "no triangle mesh"),
        "nan": (nan, "NaN"),
        "inf": (inf, "NaN"),
        "directory": (folder, "directory"),
        "missing": (tmp_path / "missing.ply", "does not exist"),
        "unknown extension": (tmp_path / "mesh.xyz", ".obj"),
    }
    garbage = np.random.default_rng(0).integers(0, 256, size=600, dtype=np.uint8).tobytes()
    for ext in (".ply", ".obj", ".stl", ".off", ".glb"):
        g = tmp_path / f"garbage{ext}"
        g.write_bytes(garbage)
        cases[f"garbage {ext}"] = (g, g.name)
    return cases


ERROR_CASES = [
    "point cloud",
    "empty",
    "lines only",
    "nan",
    "inf",
    "directory",
    "missing",
    "unknown extension",
    "garbage .ply",
    "garbage .obj",
    "garbage .stl",
    "garbage .off",
    "garbage .glb",
]


@pytest.mark.parametrize("case", ERROR_CASES)
def test_bad_inputs_raise_one_line_mesh_error(tmp_path, case):
    path, expected = _error_cases(tmp_path)[case]
    with pytest.raises(MeshError) as info:
        read_mesh(path)
    message = str(info.value)
    assert "\n" not in message
    assert expected in message
    assert path.name in message


def test_write_mesh_refuses_bad_arrays_and_unknown_extension(tmp_path):
    v, f = _mesh(8)
    with pytest.raises(MeshError, match=".ply"):
        write_mesh(tmp_path / "m.fbx", v, f)
    bad = v.copy()
    bad[3, 1] = np.nan
    with pytest.raises(MeshError):
        write_mesh(tmp_path / "m.obj", bad, f)
    with pytest.raises(MeshError):
        write_mesh(tmp_path / "m.obj", v, f + len(v))
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- atomic writing


def test_atomic_output_leaves_target_untouched_when_the_body_fails(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"original")
    with pytest.raises(RuntimeError):
        with atomic_output(target, force=True) as tmp:
            Path(tmp).write_bytes(b"partial")
            raise RuntimeError("boom")
    assert target.read_bytes() == b"original"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_atomic_output_refuses_existing_target_without_force(tmp_path):
    target = tmp_path / "out.ply"
    target.write_bytes(b"original")
    with pytest.raises(OutputExistsError, match="--force"):
        with atomic_output(target):
            pass
    v, f = _mesh(9)
    with pytest.raises(OutputExistsError):
        write_mesh(target, v, f)
    assert target.read_bytes() == b"original"
    write_mesh(target, v, f, force=True)
    assert np.array_equal(read_mesh(target).vertices, v)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.ply"]


def test_atomic_output_refuses_missing_folder(tmp_path):
    target = tmp_path / "no" / "such" / "out.obj"
    with pytest.raises(PmwmError, match="does not exist"):
        atomic_write_bytes(target, b"x")
    v, f = _mesh(10)
    with pytest.raises(PmwmError):
        write_mesh(target, v, f)
    assert not (tmp_path / "no").exists()


def test_atomic_write_bytes_writes_data_and_mode_and_leaves_no_temp_file(tmp_path):
    target = tmp_path / "secret.json"
    atomic_write_bytes(target, b'{"k": 1}', mode=0o600)
    assert target.read_bytes() == b'{"k": 1}'
    if os.name == "posix":
        assert target.stat().st_mode & 0o777 == 0o600
    atomic_write_bytes(target, b"new", force=True)
    assert target.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["secret.json"]


# ---------------------------------------------------------------- weld


def test_weld_merges_signed_zero_and_keeps_first_appearance_order():
    v = np.array([[1.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0], [-0.0, 0, 0], [2.0, 0, 0]])
    f = np.array([[0, 1, 4], [2, 3, 4]])
    w, wf, inv = weld(v, f)
    assert w[:, 0].tolist() == [1.0, 0.0, 2.0]
    assert inv.tolist() == [0, 1, 0, 1, 2]
    assert wf.tolist() == [[0, 1, 2], [0, 1, 2]]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(*[st.sampled_from([-1.0, -0.0, 0.0, 0.5, 2.0])] * 3), min_size=1, max_size=40))
def test_weld_properties(rows):
    v = np.array(rows, dtype=np.float64)
    f = np.arange(3 * (len(v) // 3)).reshape(-1, 3)
    w, wf, inv = weld(v, f)
    assert np.array_equal(w[inv], v + 0.0)  # every vertex maps to its own position
    assert len(np.unique(w + 0.0, axis=0)) == len(w)  # no duplicates left
    first = np.array([np.flatnonzero(inv == i)[0] for i in range(len(w))])
    assert (np.diff(first) > 0).all()  # numbered by first appearance
    assert np.array_equal(wf, inv[f])


def test_weld_is_exact_when_the_hash_collides(monkeypatch):
    v, f = _mesh(11, n=200)
    v = np.vstack([v, v[::3]])  # exact duplicates
    expected = weld(v, f)
    monkeypatch.setattr(meshio, "_row_hash", lambda bits: np.zeros(len(bits), dtype=np.uint64))
    got = weld(v, f)
    for a, b in zip(expected, got):
        assert np.array_equal(a, b)
    assert len(got[0]) == 200


# ---------------------------------------------------------------- the test meshes


@pytest.mark.parametrize(
    "path, n_vertices, n_faces",
    [
        (meshes.mesh_file("open_cap.off"), 11_140, 22_090),  # CRLF line ends, trailing spaces
        (meshes.mesh_file("blob.off"), 2_906, 5_808),  # an edge count in the header, runs of spaces
        (PACKAGED_BUNNY, 34_835, 69_666),
    ],
    ids=["open_cap.off", "blob.off", "bunny.off"],
)
def test_data_meshes_read_with_their_documented_counts(path, n_vertices, n_faces):
    src = read_mesh(path)
    assert src.vertices.shape == (n_vertices, 3)
    assert src.faces.shape == (n_faces, 3)
    assert src.warnings == []


# ---------------------------------------------------------------- plain files read and written without trimesh


def _plain_variants(tmp_path):
    """Plain OFF and PLY files (read without trimesh) and near-plain ones (read by trimesh)."""
    v, f = meshes.blob()
    paths = []
    for name, (V, F) in {"blob": (v, f), "f64": (v + 1e-9 * np.arange(len(v))[:, None], f)}.items():
        for ext in (".off", ".ply"):
            paths.append(tmp_path / f"{name}{ext}")
            write_mesh(paths[-1], V, F)
    text = (tmp_path / "f64.off").read_text()
    for name, body in {
        "crlf": text.replace("\n", "\r\n"),
        "tabs": text.replace(" ", "\t"),
        "blank": text.replace("\n", "\n\n"),
        "comment": "# c\n" + text,
        "quad": text.replace("\n3 ", "\n4 0 ", 1),
        "coff": "C" + text,
    }.items():
        paths.append(tmp_path / f"{name}.off")
        paths[-1].write_text(body)
    ply = (tmp_path / "blob.ply").read_bytes()
    for name, body in {
        "double": ply,
        "colour": ply.replace(b"property float z\n", b"property float z\nproperty uchar red\n"),
    }.items():
        paths.append(tmp_path / f"{name}.ply")
        if name == "double":
            head, rest = ply.split(b"end_header\n")
            vb = np.frombuffer(rest, "<f4", 3 * len(v)).astype("<f8").tobytes()
            body = head.replace(b"float", b"double") + b"end_header\n" + vb + rest[12 * len(v) :]
        else:
            head, rest = body.split(b"end_header\n")
            vb = np.frombuffer(rest, "<f4", 3 * len(v)).reshape(-1, 3)
            rec = np.zeros(len(v), [("p", "<f4", (3,)), ("r", "u1")])
            rec["p"] = vb
            body = head + b"end_header\n" + rec.tobytes() + rest[12 * len(v) :]
        paths[-1].write_bytes(body)
    return paths


def test_plain_files_read_and_write_exactly_as_through_trimesh(tmp_path, monkeypatch):
    paths = _plain_variants(tmp_path)
    fast = [read_mesh(p) for p in paths]
    assert sum(isinstance(s.source, meshio.PlainMesh) for s in fast) >= 8  # most went the plain way
    fast_bytes = []
    for i, s in enumerate(fast):
        write_marked(tmp_path / f"fast{i}.ply", s, s.vertices * 1.5)
        fast_bytes.append((tmp_path / f"fast{i}.ply").read_bytes())
    monkeypatch.setattr(meshio, "_read_plain", lambda data, ext: None)  # everything through trimesh
    monkeypatch.setattr(meshio, "_ply_bytes", lambda v, f: meshio._export_trimesh(meshio._trimesh(v, f), ".ply"))
    for i, (p, s) in enumerate(zip(paths, fast)):
        t = read_mesh(p)
        assert np.array_equal(s.vertices, t.vertices) and s.vertices.dtype == t.vertices.dtype
        assert np.array_equal(s.faces, t.faces) and s.faces.dtype == t.faces.dtype
        assert np.array_equal(s.source_to_canonical, t.source_to_canonical)
        assert np.array_equal(np.asarray(s.source.vertices, float), np.asarray(t.source.vertices, float))
        assert (s.float32, s.warnings) == (t.float32, t.warnings)
        write_marked(tmp_path / f"slow{i}.ply", t, t.vertices * 1.5)
        assert (tmp_path / f"slow{i}.ply").read_bytes() == fast_bytes[i]


def test_write_mesh_ply_bytes_are_trimeshs(tmp_path):
    v, f = _mesh(4)
    write_mesh(tmp_path / "a.ply", v, f)
    expected = trimesh.exchange.ply.export_ply(
        trimesh.Trimesh(v, f, process=False), encoding="binary", vertex_normal=False
    )
    assert (tmp_path / "a.ply").read_bytes() == expected
