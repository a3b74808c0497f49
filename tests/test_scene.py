"""Scenes of several objects: marked with one key (or pass phrase), written back with everything
else they held, read from the scene and from each object taken out alone; bad scenes refused with one
line and nothing written."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

import pmwm
from pmwm import wording
from pmwm.cli import main
from pmwm.scene import read_asset, read_keys, read_objects, union_bound, verify_objects

from meshes import blob, cad_part, mesh_file, pinched_torus

PAYLOAD = "ACME"


# ----------------------------------------------------------------------------- building test scenes


def _embed(src, out, key=None, *more, seed: int = 3, payload=PAYLOAD, quiet: bool = True) -> int:
    """The exit code of ``pmwm embed --seed SEED SRC -o OUT [--key KEY] [--payload PAYLOAD] MORE... [-q]``."""
    args = ["embed", "--seed", str(seed), str(src), "-o", str(out)]
    args += ["--key", str(key)] if key is not None else []
    args += ["--payload", payload] if payload is not None else []
    return main(args + [str(m) for m in more] + (["-q"] if quiet else []))


def _glb_parts(data: bytes) -> tuple[dict, bytes]:
    """(JSON document, BIN chunk) of a GLB file."""
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + n])
    m = struct.unpack_from("<I", data, 20 + n)[0]
    return doc, data[28 + n : 28 + n + m]


def _glb(doc: dict, body: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body += b"\0" * (-len(body) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(body), 0x004E4942) + body
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def scene_glb(path, extra_node: bool = True) -> None:
    """A GLB of two named objects under a parent node: a textured organic shape (UVs, an image texture,
    a material) and a CAD part with vertex colours, a rotation and a translation; extras on nodes and
    meshes; a third node instancing the part's mesh again (one mesh, two nodes)."""
    V1, F1 = blob()
    V2, F2 = cad_part()
    uv = (V1[:, :2] - V1[:, :2].min(0)) / np.ptp(V1[:, :2], axis=0)
    from PIL import Image

    image = Image.fromarray((np.arange(16 * 16 * 3) % 251).astype(np.uint8).reshape(16, 16, 3))
    horse = trimesh.Trimesh(V1, F1, process=False, visual=trimesh.visual.TextureVisuals(uv=uv, image=image))
    colours = np.tile(np.array([[200, 30, 40, 255]], np.uint8), (len(V2), 1))
    part = trimesh.Trimesh(V2, F2, process=False, vertex_colors=colours)
    scene = trimesh.Scene()
    scene.add_geometry(horse, node_name="Horse", geom_name="HorseMesh")
    T = trimesh.transformations.rotation_matrix(0.5, [0, 0, 1])
    T[:3, 3] = [2.0, 0.5, -1.0]
    scene.add_geometry(part, node_name="Part", geom_name="PartMesh", transform=T)
    doc, body = _glb_parts(trimesh.exchange.gltf.export_glb(scene, include_normals=True))
    names = [n.get("name") for n in doc["nodes"]]
    horse_i, part_i = names.index("Horse"), names.index("Part")
    for node in doc["nodes"]:
        node.get("children", []).clear() if node.get("name") not in ("Horse", "Part") else None
        node.pop("children", None) if not node.get("children") else None
    doc["nodes"].append({"name": "Rig", "children": [horse_i, part_i], "extras": {"rig": True}})
    doc["nodes"][horse_i]["extras"] = {"owner": "studio", "lod": 0}
    roots = [len(doc["nodes"]) - 1]
    if extra_node:
        doc["nodes"].append({"name": "PartCopy", "mesh": doc["nodes"][part_i]["mesh"], "translation": [0, 3, 0]})
        roots.append(len(doc["nodes"]) - 1)
    doc["scenes"][doc.get("scene", 0)]["nodes"] = roots
    doc["meshes"][0]["extras"] = {"note": "kept"}
    with open(path, "wb") as fh:
        fh.write(_glb(doc, body))


def _moved_bytes(doc: dict) -> np.ndarray:
    """(len(buffer),) bool: the bytes of the POSITION and NORMAL accessors of every mesh."""
    n = doc["buffers"][0]["byteLength"]
    mask = np.zeros(n, bool)
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            for name in ("POSITION", "NORMAL"):
                if name in prim["attributes"]:
                    acc = doc["accessors"][prim["attributes"][name]]
                    bv = doc["bufferViews"][acc["bufferView"]]
                    start = bv.get("byteOffset", 0) + acc.get("byteOffset", 0)
                    stride = bv.get("byteStride") or 12
                    for k in range(acc["count"]):
                        mask[start + k * stride : start + k * stride + 12] = True
    return mask


def _without_minmax(doc: dict) -> dict:
    doc = json.loads(json.dumps(doc))
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            acc = doc["accessors"][prim["attributes"]["POSITION"]]
            acc.pop("min", None), acc.pop("max", None)
    return doc


@pytest.fixture(scope="module")
def marked_glb(tmp_path_factory):
    d = tmp_path_factory.mktemp("glb")
    scene_glb(d / "scene.glb")
    rc = _embed(d / "scene.glb", d / "marked.glb", d / "k.json", seed=5)
    assert rc == 0
    return d


# ----------------------------------------------------------------------------- glTF


def test_glb_keeps_every_byte_but_positions_and_normals(marked_glb):
    doc0, bin0 = _glb_parts((marked_glb / "scene.glb").read_bytes())
    doc1, bin1 = _glb_parts((marked_glb / "marked.glb").read_bytes())
    assert _without_minmax(doc0) == _without_minmax(doc1)  # names, hierarchy, transforms, materials, extras
    assert len(bin0) == len(bin1)
    a0, a1 = np.frombuffer(bin0, np.uint8), np.frombuffer(bin1, np.uint8)
    moved = _moved_bytes(doc0)
    assert np.array_equal(a0[~moved], a1[~moved])  # UVs, colours, indices, the image: the same bytes
    assert (a0[moved] != a1[moved]).any()  # and the mark is in
    for mesh in doc1["meshes"]:  # min/max describe the new positions
        acc = doc1["accessors"][mesh["primitives"][0]["attributes"]["POSITION"]]
        bv = doc1["bufferViews"][acc["bufferView"]]
        pos = np.frombuffer(bin1, "<f4", acc["count"] * 3, bv.get("byteOffset", 0) + acc.get("byteOffset", 0))
        assert np.array_equal(pos.reshape(-1, 3).min(0), np.float32(acc["min"]))


def test_glb_normals_turn_with_the_surface(marked_glb):
    doc, body = _glb_parts((marked_glb / "marked.glb").read_bytes())
    asset = read_asset(marked_glb / "marked.glb")
    for obj, mesh in zip(asset.objects, doc["meshes"]):
        acc = doc["accessors"][mesh["primitives"][0]["attributes"]["NORMAL"]]
        bv = doc["bufferViews"][acc["bufferView"]]
        n = np.frombuffer(body, "<f4", acc["count"] * 3, bv.get("byteOffset", 0)).reshape(-1, 3)
        fresh = pmwm.features.vertex_normals(obj.vertices, obj.faces)[obj.source_to_canonical]
        assert np.allclose(np.linalg.norm(n, axis=1), 1, atol=1e-5)
        assert np.median(np.sum(n * fresh, axis=1)) > 0.999


def test_one_mesh_of_two_nodes_is_one_object(marked_glb):
    asset = read_asset(marked_glb / "scene.glb")
    assert [o.name for o in asset.objects] == ["Horse", "PartMesh"]  # the part's mesh has two nodes


def test_the_scene_reads_marked_and_names_its_objects(marked_glb, capsys):
    capsys.readouterr()
    assert main(["verify", str(marked_glb / "marked.glb"), "--key", str(marked_glb / "k.json")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("MARKED") and "Horse, PartMesh" in out and f"payload: '{PAYLOAD}'" in out
    keys = read_keys(marked_glb / "k.json")
    objects = read_objects(marked_glb / "marked.glb")
    v = verify_objects(objects, keys)
    single = pmwm.verify(objects[0][1], objects[0][2], keys[0][1])
    assert v.p_value == union_bound(single.p_value, 2) == 2 * single.p_value  # two pairs tried
    assert [f[0] for f in v.detail.found] == ["Horse", "PartMesh"]
    assert any("Horse, PartMesh" in value for _, value in wording.rows(v))
    assert main(["verify", str(marked_glb / "scene.glb"), "--key", str(marked_glb / "k.json")]) == 1


@pytest.mark.parametrize("world", [False, True])
def test_each_object_taken_out_alone_reads_marked(marked_glb, tmp_path, world):
    """Each object re-exported alone as PLY (in its own frame, or placed in the world by its node's
    transform) reads with the scene's key, the union bound paid over the object keys."""
    for name, V, F in read_objects(marked_glb / "marked.glb"):
        if world:  # the part's node transform (the registration finds the pose)
            R = trimesh.transformations.rotation_matrix(0.5, [0, 0, 1])[:3, :3]
            V = V @ R.T + np.array([2.0, 0.5, -1.0])
        path = tmp_path / f"{name}.ply"
        pmwm.write_mesh(path, V, F)
        v = verify_objects(read_objects(path), read_keys(marked_glb / "k.json"))
        assert v.marked and v.p_value < 1e-12, (name, wording.lines(v))
        assert world or v.payload == PAYLOAD
        assert [f[1] for f in v.detail.found] == [name]


def test_a_key_of_one_mesh_reads_as_before(tmp_path):
    """A key file of one mesh reads as a scene key of one object, and one object with one key is read
    by ``pmwm.verify`` itself: the same verdict, no correction."""
    V, F = cad_part()
    res = pmwm.embed(V, F, pmwm.EmbedOptions(payload=PAYLOAD, seed=1, progressive=False))
    pmwm.write_key(tmp_path / "k.json", res.key)
    ((name, key),) = read_keys(tmp_path / "k.json")
    assert name == "" and key.to_json() == res.key.to_json()
    v = verify_objects([("part", res.vertices, F)], [(name, key)])
    assert v.to_dict() == pmwm.verify(res.vertices, F, key).to_dict() and v.payload == PAYLOAD
    assert type(v.detail).__name__ != "SceneDetail"


def test_a_pass_phrase_marks_every_object(tmp_path, capsys):
    """The blind scheme: one pass phrase, no key file; the scene is marked when every object is (the
    largest object p-value, no union bound), and each object alone reads marked."""
    path = tmp_path / "two.glb"
    s = trimesh.Scene()
    s.add_geometry(trimesh.Trimesh(*cad_part(), process=False), node_name="A", geom_name="A")
    s.add_geometry(trimesh.Trimesh(*pinched_torus(), process=False), node_name="B", geom_name="B")
    s.export(path)
    pp = tmp_path / "pp"
    pp.write_text("a pass phrase for the scene\n")
    assert _embed(path, tmp_path / "m.glb", None, "--scheme", "blind", "--passphrase-file", pp) == 0
    assert not any(p.name.endswith(".json") for p in tmp_path.iterdir())  # no key file
    capsys.readouterr()
    assert main(["verify", str(tmp_path / "m.glb"), "--passphrase-file", str(pp)]) == 0
    out = capsys.readouterr().out
    assert "mark read in 2 of 2 objects: A, B" in out and f"payload: '{PAYLOAD}'" in out
    objects = read_objects(tmp_path / "m.glb")
    v = verify_objects(objects, passphrase="a pass phrase for the scene")
    alone = [pmwm.verify(V, F, passphrase="a pass phrase for the scene") for _, V, F in objects]
    assert all(a.marked for a in alone) and v.p_value == max(a.p_value for a in alone)
    assert main(["verify", str(path), "--passphrase-file", str(pp)]) == 1  # the scene before marking


# ----------------------------------------------------------------------------- OBJ


def _rows(fmt: str, a: np.ndarray) -> str:
    return "".join(fmt % tuple(r) for r in a.tolist())


def scene_obj(path) -> None:
    """An OBJ of two objects: a textured shape (v with vertex colours, vt, vn, faces v/vt/vn, a material
    library, smoothing) and a part in a group (faces v//vn, negative indices for its last faces)."""
    V1, F1 = blob()
    V2, F2 = cad_part()
    n1 = pmwm.features.vertex_normals(V1, F1)
    n2 = pmwm.features.vertex_normals(V2, F2)
    uv = (V1[:, :2] - V1[:, :2].min(0)) / np.ptp(V1[:, :2], axis=0)
    k1 = len(V1)
    colours = np.tile([0.8, 0.1, 0.2], (k1, 1))
    text = [
        "# two objects\n",
        "mtllib scene.mtl\n",
        "o Horse\n",
        _rows("v %r %r %r %.3f %.3f %.3f\n", np.hstack([V1, colours])),
        _rows("vt %.6f %.6f\n", uv),
        _rows("vn %.6f %.6f %.6f\n", n1),
        "usemtl skin\n",
        "s 1\n",
        _rows("f %d/%d/%d %d/%d/%d %d/%d/%d\n", np.repeat(F1 + 1, 3, axis=1)),
        "o Part\n",
        "g part_group\n",
        _rows("v %r %r %r\n", V2),
        _rows("vn %.6f %.6f %.6f\n", n2),
        "usemtl metal\n",
        "s off\n",
        _rows("f %d//%d %d//%d %d//%d\n", np.repeat(F2[:-10] + 1 + k1, 2, axis=1)),
        _rows("f %d//%d %d//%d %d//%d\n", np.repeat(F2[-10:] - len(V2), 2, axis=1)),
    ]
    path.write_text("".join(text))
    (path.parent / "scene.mtl").write_text("newmtl skin\nKd 0.8 0.6 0.5\nnewmtl metal\nKd 0.5 0.5 0.5\n")


def test_obj_keeps_objects_groups_materials_and_uvs(tmp_path, capsys):
    scene_obj(tmp_path / "scene.obj")
    out = tmp_path / "out"
    out.mkdir()
    assert _embed(tmp_path / "scene.obj", out / "m.obj", out / "k.json", seed=2) == 0
    before = (tmp_path / "scene.obj").read_bytes().splitlines()
    after = (out / "m.obj").read_bytes().splitlines()
    assert len(before) == len(after)
    kind = [line.split()[0] if line.strip() else b"" for line in before]
    same = [a == b for a, b in zip(before, after)]
    assert all(s for s, k in zip(same, kind) if k not in (b"v", b"vn", b"mtllib"))  # o, g, usemtl, vt, f, s
    assert [a for a, k in zip(after, kind) if k == b"mtllib"] == [b"mtllib ../scene.mtl"]  # found from out/
    assert sum(not s for s, k in zip(same, kind) if k == b"v") > 1000
    assert all(a.split()[4:] == b.split()[4:] for a, b, k in zip(before, after, kind) if k == b"v")  # colours
    assert [o.name for o in read_asset(out / "m.obj").objects] == ["Horse", "Part"]
    capsys.readouterr()
    assert main(["verify", str(out / "m.obj"), "--key", str(out / "k.json")]) == 0
    assert "mark read in 2 of 2 objects: Horse, Part" in capsys.readouterr().out
    keys = read_keys(out / "k.json")
    for name, V, F in read_objects(out / "m.obj"):  # each object alone, as an OFF
        pmwm.write_mesh(tmp_path / f"{name}.off", V, F)
        v = verify_objects(read_objects(tmp_path / f"{name}.off"), keys)
        assert v.marked and v.payload == PAYLOAD and [f[1] for f in v.detail.found] == [name]


def test_obj_of_groups_sharing_vertices_is_one_mesh(tmp_path):
    """Groups that are material sections of one mesh (their faces share vertices) are one object: the
    file is read as one mesh, as before."""
    V, F = cad_part()
    half = len(F) // 2
    text = (
        _rows("v %r %r %r\n", V)
        + "g top\n"
        + _rows("f %d %d %d\n", F[:half] + 1)
        + "g bottom\n"
        + _rows("f %d %d %d\n", F[half:] + 1)
    )
    (tmp_path / "one.obj").write_text(text)
    assert read_asset(tmp_path / "one.obj") is None
    ((name, V2, F2),) = read_objects(tmp_path / "one.obj")
    assert len(V2) == len(V) and len(F2) == len(F)


# ----------------------------------------------------------------------------- refused


def _refused(capsys, tmp_path, scene, words: str) -> None:
    out = tmp_path / "marked" / scene.name
    out.parent.mkdir(exist_ok=True)
    capsys.readouterr()
    rc = main(["embed", "--seed", "3", str(scene), "-o", str(out), "--key", str(tmp_path / "marked" / "k.json"), "-q"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("pmwm: error: ") and err.count("\n") == 1 and words in err, err
    assert list(out.parent.iterdir()) == []  # nothing written


def _edited(tmp_path, name: str, edit) -> object:
    scene_glb(tmp_path / "base.glb", extra_node=False)
    doc, body = _glb_parts((tmp_path / "base.glb").read_bytes())
    body = edit(doc, body) or body
    path = tmp_path / name
    path.write_bytes(_glb(doc, body))
    return path


def test_draco_compressed_scene_is_refused(tmp_path, capsys):
    def draco(doc, body):
        doc["extensionsUsed"] = ["KHR_draco_mesh_compression"]
        doc["meshes"][0]["primitives"][0]["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0}}

    _refused(capsys, tmp_path, _edited(tmp_path, "draco.glb", draco), "KHR_draco_mesh_compression")


def test_empty_node_is_refused(tmp_path, capsys):
    def empty(doc, body):
        doc["meshes"].append({"name": "Nothing", "primitives": []})
        doc["nodes"].append({"name": "Empty", "mesh": len(doc["meshes"]) - 1})

    _refused(capsys, tmp_path, _edited(tmp_path, "empty.glb", empty), "no primitive")


def test_mesh_without_triangles_is_refused(tmp_path, capsys):
    def lines(doc, body):
        prim = dict(doc["meshes"][0]["primitives"][0], mode=1)
        prim.pop("indices", None)
        doc["meshes"].append({"name": "Wire", "primitives": [prim]})
        doc["nodes"].append({"name": "Wire", "mesh": len(doc["meshes"]) - 1})

    _refused(capsys, tmp_path, _edited(tmp_path, "lines.glb", lines), "no triangle")


def test_meshes_sharing_positions_are_refused(tmp_path, capsys):
    def shared(doc, body):
        doc["meshes"].append({"name": "Twin", "primitives": [dict(doc["meshes"][0]["primitives"][0])]})
        doc["nodes"].append({"name": "Twin", "mesh": len(doc["meshes"]) - 1})

    _refused(capsys, tmp_path, _edited(tmp_path, "twin.glb", shared), "share their positions")


def test_gltf_with_missing_buffer_file_is_refused(tmp_path, capsys):
    scene_glb(tmp_path / "base.glb", extra_node=False)
    doc, body = _glb_parts((tmp_path / "base.glb").read_bytes())
    doc["buffers"][0]["uri"] = "scene.bin"
    (tmp_path / "scene.gltf").write_text(json.dumps(doc))
    _refused(capsys, tmp_path, tmp_path / "scene.gltf", "scene.bin is missing")


def test_gltf_with_external_buffer_is_written_with_its_own(tmp_path, capsys):
    """A .gltf whose buffer is a separate file: the marked .gltf gets its own .bin; its image and any
    other external file are still found from the output's folder."""
    scene_glb(tmp_path / "base.glb", extra_node=False)
    doc, body = _glb_parts((tmp_path / "base.glb").read_bytes())
    doc["buffers"][0]["uri"] = "scene.bin"
    (tmp_path / "scene.bin").write_bytes(body)
    (tmp_path / "scene.gltf").write_text(json.dumps(doc))
    out = tmp_path / "out"
    out.mkdir()
    assert _embed(tmp_path / "scene.gltf", out / "m.gltf", out / "k.json") == 0
    assert sorted(p.name for p in out.iterdir()) == ["k.json", "m.bin", "m.gltf"]
    assert (tmp_path / "scene.bin").read_bytes() == body  # the input untouched
    assert json.loads((out / "m.gltf").read_text())["buffers"][0]["uri"] == "m.bin"
    capsys.readouterr()
    assert main(["verify", str(out / "m.gltf"), "--key", str(out / "k.json")]) == 0


def test_a_scene_goes_back_to_its_own_format(tmp_path, capsys):
    scene_glb(tmp_path / "s.glb", extra_node=False)
    capsys.readouterr()
    assert _embed(tmp_path / "s.glb", tmp_path / "m.ply", tmp_path / "k.json", payload=None, quiet=False) == 2
    assert "use -o NAME.glb" in capsys.readouterr().err
    assert not (tmp_path / "m.ply").exists() and not (tmp_path / "k.json").exists()


def test_morph_targets_are_kept_and_the_mesh_marked_at_rest(tmp_path, capsys):
    """A mesh with a morph target: marked in its rest positions, the target's deltas and weights kept."""

    def morph(doc, body):
        prim = doc["meshes"][0]["primitives"][0]
        count = doc["accessors"][prim["attributes"]["POSITION"]]["count"]
        delta = np.tile(np.float32([0.0, 0.01, 0.0]), (count, 1)).tobytes()
        body = body + b"\0" * (-len(body) % 4)
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(body), "byteLength": len(delta)})
        doc["accessors"].append(
            {
                "bufferView": len(doc["bufferViews"]) - 1,
                "componentType": 5126,
                "count": count,
                "type": "VEC3",
                "min": [0, 0.01, 0],
                "max": [0, 0.01, 0],
            }
        )
        prim["targets"] = [{"POSITION": len(doc["accessors"]) - 1}]
        doc["meshes"][0]["weights"] = [0.5]
        doc["buffers"][0]["byteLength"] = len(body) + len(delta)
        return body + delta

    path = _edited(tmp_path, "morph.glb", morph)
    capsys.readouterr()
    assert _embed(path, tmp_path / "m.glb", tmp_path / "k.json", quiet=False) == 0
    assert "marked at rest" in capsys.readouterr().err
    doc0, bin0 = _glb_parts(path.read_bytes())
    doc1, bin1 = _glb_parts((tmp_path / "m.glb").read_bytes())
    assert _without_minmax(doc0) == _without_minmax(doc1)
    moved = _moved_bytes(doc0)
    a0, a1 = np.frombuffer(bin0, np.uint8), np.frombuffer(bin1, np.uint8)
    assert np.array_equal(a0[~moved], a1[~moved])  # the target's deltas among them
    assert main(["verify", str(tmp_path / "m.glb"), "--key", str(tmp_path / "k.json")]) == 0


def test_obj_empty_object_is_refused(tmp_path, capsys):
    V, F = cad_part()
    text = "o Part\n" + _rows("v %r %r %r\n", V) + _rows("f %d %d %d\n", F + 1) + "o Empty\nv 0 0 0\n"
    (tmp_path / "e.obj").write_text(text + "o Cube\nv 9 9 9\nv 9 9 8\nv 9 8 9\nv 9 8 8\nf -4 -3 -2 -1\n")
    _refused(capsys, tmp_path, tmp_path / "e.obj", "'Empty' has no face")


def test_obj_polygons_are_fans_and_kept_as_written(tmp_path):
    """Quads and negative indices: the canonical mesh takes each polygon as a triangle fan, the file keeps
    the polygon line as written."""
    text = (
        "o A\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
        "o B\nv 5 0 0\nv 6 0 0\nv 6 1 0\nv 5 1 0\nv 5.5 0.5 1\nf -5 -4 -3 -2\nf -5 -4 -1\n"
    )
    (tmp_path / "q.obj").write_text(text)
    a, b = read_asset(tmp_path / "q.obj").objects
    assert a.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert b.faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 4]] and len(b.vertices) == 5
    moved = [a.vertices + 0.125, b.vertices]
    read_asset(tmp_path / "q.obj").write(str(tmp_path / "m.obj"), moved)
    out = (tmp_path / "m.obj").read_text().splitlines()
    assert out[1] == "v 0.125 0.125 0.125" and out[5] == "f 1 2 3 4" and out[6:] == text.splitlines()[6:]


def _interleaved_glb(path) -> None:
    """A GLB by hand: the part's positions and normals interleaved in one buffer view (stride 24), the
    torus's in their own views, indices of two widths."""
    parts, views, accessors, meshes, nodes = [], [], [], [], []

    def view(data: bytes, stride=None) -> int:
        offset = sum(len(p) for p in parts)
        parts.append(data + b"\0" * (-len(data) % 4))
        views.append(
            {"buffer": 0, "byteOffset": offset, "byteLength": len(data)} | ({"byteStride": stride} if stride else {})
        )
        return len(views) - 1

    def accessor(v, offset, ctype, count, kind, **more) -> int:
        accessors.append(
            {"bufferView": v, "byteOffset": offset, "componentType": ctype, "count": count, "type": kind} | more
        )
        return len(accessors) - 1

    for name, (V, F), itype in (("Part", cad_part(), ("<u4", 5125)), ("Torus", pinched_torus(), ("<u2", 5123))):
        N = pmwm.features.vertex_normals(V, F).astype("<f4")
        P = V.astype("<f4")
        if name == "Part":
            v = view(np.hstack([P, N]).tobytes(), stride=24)
            pos = accessor(v, 0, 5126, len(V), "VEC3", min=P.min(0).tolist(), max=P.max(0).tolist())
            nrm = accessor(v, 12, 5126, len(V), "VEC3")
        else:
            pos = accessor(view(P.tobytes()), 0, 5126, len(V), "VEC3", min=P.min(0).tolist(), max=P.max(0).tolist())
            nrm = accessor(view(N.tobytes()), 0, 5126, len(V), "VEC3")
        ind = accessor(view(F.astype(itype[0]).tobytes()), 0, itype[1], F.size, "SCALAR")
        meshes.append(
            {"name": name + "Mesh", "primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": ind}]}
        )
        nodes.append({"name": name, "mesh": len(meshes) - 1})
    body = b"".join(parts)
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": nodes,
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(body)}],
    }
    path.write_bytes(_glb(doc, body))


def test_interleaved_buffers_are_patched_in_place(tmp_path, capsys):
    _interleaved_glb(tmp_path / "i.glb")
    assert _embed(tmp_path / "i.glb", tmp_path / "m.glb", tmp_path / "k.json") == 0
    doc0, bin0 = _glb_parts((tmp_path / "i.glb").read_bytes())
    doc1, bin1 = _glb_parts((tmp_path / "m.glb").read_bytes())
    assert _without_minmax(doc0) == _without_minmax(doc1)
    moved = _moved_bytes(doc0)
    a0, a1 = np.frombuffer(bin0, np.uint8), np.frombuffer(bin1, np.uint8)
    assert np.array_equal(a0[~moved], a1[~moved]) and (a0[moved] != a1[moved]).any()
    capsys.readouterr()
    assert main(["verify", str(tmp_path / "m.glb"), "--key", str(tmp_path / "k.json"), "--json"]) == 0
    objects = json.loads(capsys.readouterr().out)["objects"]
    assert [r["object"] for r in objects["read"]] == ["Part", "Torus"] and objects["pairs_tried"] == 2


def test_gltf_with_embedded_buffers(tmp_path, capsys):
    """A .gltf whose buffers are data: URIs: written back as a .gltf of the same kind."""
    s = trimesh.Scene()
    s.add_geometry(trimesh.Trimesh(*cad_part(), process=False), node_name="A", geom_name="A")
    s.add_geometry(trimesh.Trimesh(*pinched_torus(), process=False), node_name="B", geom_name="B")
    (tmp_path / "s.gltf").write_bytes(trimesh.exchange.gltf.export_gltf(s, embed_buffers=True)["model.gltf"])
    assert _embed(tmp_path / "s.gltf", tmp_path / "m.gltf", tmp_path / "k.json") == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.json", "m.gltf", "s.gltf"]
    assert json.loads((tmp_path / "m.gltf").read_text())["buffers"][0]["uri"].startswith("data:")
    capsys.readouterr()
    assert main(["verify", str(tmp_path / "m.gltf"), "--key", str(tmp_path / "k.json")]) == 0
    assert "mark read in 2 of 2 objects: A, B" in capsys.readouterr().out


def test_marked_glb_loads_in_a_consumer_with_its_texture_and_uvs(marked_glb):
    """trimesh (a consumer that knows nothing of pmwm) loads the marked scene with the same nodes,
    transforms, UVs and texture image as the original."""
    a = trimesh.load(marked_glb / "scene.glb", process=False)
    b = trimesh.load(marked_glb / "marked.glb", process=False)
    assert sorted(a.graph.nodes_geometry) == sorted(b.graph.nodes_geometry)
    for node in a.graph.nodes_geometry:
        assert np.array_equal(a.graph[node][0], b.graph[node][0])
    ga, gb = a.geometry["HorseMesh"], b.geometry["HorseMesh"]
    assert np.array_equal(ga.visual.uv, gb.visual.uv)
    image = (np.asarray(g.visual.material.baseColorTexture) for g in (ga, gb))
    assert np.array_equal(*image)
    assert 0 < np.abs(ga.vertices - gb.vertices).max() < 0.01 * np.ptp(ga.vertices, axis=0).max()


def test_skinned_mesh_is_marked_in_its_bind_pose(tmp_path, capsys):
    def skin(doc, body):
        mat = np.eye(4, dtype="<f4").tobytes()
        body = body + b"\0" * (-len(body) % 4)
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(body), "byteLength": len(mat)})
        doc["accessors"].append(
            {"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126, "count": 1, "type": "MAT4"}
        )
        doc["nodes"].append({"name": "Bone"})
        horse = next(n for n in doc["nodes"] if n.get("name") == "Horse")
        horse["skin"] = 0
        doc["skins"] = [{"joints": [len(doc["nodes"]) - 1], "inverseBindMatrices": len(doc["accessors"]) - 1}]
        doc["buffers"][0]["byteLength"] = len(body) + len(mat)
        return body + mat

    path = _edited(tmp_path, "skin.glb", skin)
    capsys.readouterr()
    assert _embed(path, tmp_path / "m.glb", tmp_path / "k.json", quiet=False) == 0
    assert "Horse: skinned; marked in its bind pose" in capsys.readouterr().err
    assert _without_minmax(_glb_parts(path.read_bytes())[0]) == _without_minmax(
        _glb_parts((tmp_path / "m.glb").read_bytes())[0]
    )


@pytest.mark.slow
def test_a_scene_flattened_into_one_mesh_reads_marked(marked_glb):
    """The whole marked scene re-exported as one mesh (every object in world coordinates, concatenated):
    no object key has its connectivity, every key is tried, and the mark is read."""
    src = pmwm.read_mesh(marked_glb / "marked.glb")
    v = verify_objects([("flat", src.vertices, src.faces)], read_keys(marked_glb / "k.json"))
    assert v.marked and v.payload == PAYLOAD and v.detail.tried == 2


def test_a_glb_of_one_mesh_is_marked_in_place_with_a_key_of_one_mesh(tmp_path, capsys):
    """One mesh in a GLB: marked in place too (its texture and UVs kept byte for byte), its key the key
    file of one mesh; written to PLY it is read as one mesh, as before."""
    V, F = blob()
    uv = (V[:, :2] - V[:, :2].min(0)) / np.ptp(V[:, :2], axis=0)
    trimesh.Trimesh(V, F, process=False, visual=trimesh.visual.TextureVisuals(uv=uv)).export(tmp_path / "one.glb")
    assert _embed(tmp_path / "one.glb", tmp_path / "m.glb", tmp_path / "k.json", seed=1) == 0
    assert json.loads((tmp_path / "k.json").read_text())["format"] == "pmwm-key"
    doc0, bin0 = _glb_parts((tmp_path / "one.glb").read_bytes())
    doc1, bin1 = _glb_parts((tmp_path / "m.glb").read_bytes())
    moved = _moved_bytes(doc0)
    assert _without_minmax(doc0) == _without_minmax(doc1)
    assert np.array_equal(np.frombuffer(bin0, np.uint8)[~moved], np.frombuffer(bin1, np.uint8)[~moved])
    capsys.readouterr()
    assert (
        main(
            ["verify", str(tmp_path / "m.glb"), "--key", str(tmp_path / "k.json"), "--report", str(tmp_path / "r.html")]
        )
        == 0
    )  # one mesh, one key: the report as before
    assert f"payload: '{PAYLOAD}'" in capsys.readouterr().out and (tmp_path / "r.html").is_file()
    assert _embed(tmp_path / "one.glb", tmp_path / "m.ply", tmp_path / "k2.json", payload=None) == 0


def test_a_report_reads_one_mesh_with_one_key(marked_glb, tmp_path, capsys):
    capsys.readouterr()
    assert (
        main(
            [
                "verify",
                str(marked_glb / "marked.glb"),
                "--key",
                str(marked_glb / "k.json"),
                "--report",
                str(tmp_path / "r.html"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.startswith("pmwm: error: --report reads one mesh") and not (tmp_path / "r.html").exists()


# ----------------------------------------------------------------------------- fingerprinting


def test_a_scene_is_fingerprinted_and_traced_from_the_scene_or_one_object(tmp_path, capsys):
    """One copy per recipient in the scene's own format (everything but positions and normals kept), a
    registry per object; the copy traced to its recipient from the whole scene and from one object alone;
    a second run skips the copies delivered intact."""
    scene_glb(tmp_path / "s.glb", extra_node=False)
    (tmp_path / "r.csv").write_text("id\nalice\nbob\ncarol\n")
    out, key = tmp_path / "out", tmp_path / "fp.key.json"
    args = [
        "fingerprint",
        str(tmp_path / "s.glb"),
        "--key",
        str(key),
        "--recipients",
        str(tmp_path / "r.csv"),
        "--out",
        str(out),
        "--seed",
        "3",
        "-q",
    ]
    assert main(args) == 0
    assert sorted(p.name for p in out.iterdir()) == ["alice.glb", "bob.glb", "carol.glb", "registry.json"]
    doc0, bin0 = _glb_parts((tmp_path / "s.glb").read_bytes())
    doc1, bin1 = _glb_parts((out / "bob.glb").read_bytes())
    moved = _moved_bytes(doc0)
    assert _without_minmax(doc0) == _without_minmax(doc1)
    assert np.array_equal(np.frombuffer(bin0, np.uint8)[~moved], np.frombuffer(bin1, np.uint8)[~moved])
    trace = ["trace", "--key", str(key), "--registry", str(out / "registry.json")]
    capsys.readouterr()
    assert main([trace[0], str(out / "bob.glb"), *trace[1:]]) == 0
    assert capsys.readouterr().out.startswith("TRACED to bob:")
    name, V, F = read_objects(out / "carol.glb")[1]
    pmwm.write_mesh(tmp_path / "part.ply", V, F)  # one object taken out alone
    assert main([trace[0], str(tmp_path / "part.ply"), *trace[1:]]) == 0
    assert capsys.readouterr().out.startswith("TRACED to carol:")
    assert main([trace[0], str(tmp_path / "s.glb"), *trace[1:]]) == 1  # the scene as it was: no one
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(args[:-1]) == 0
    assert "0 copies written" in capsys.readouterr().out
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.slow
def test_the_catalogue_takes_a_scene_beside_a_mesh(tmp_path):
    """On a local Dask cluster: a scene's copies in its format, traced from one object alone; a mesh's as
    before; a second run writes nothing and changes nothing."""
    from pmwm.fingerprint import read_fingerprint_key, read_registry, trace
    from pmwm.fingerprint.catalogue import run_catalogue
    from pmwm.fingerprint.scene import read_any_fingerprint_key, read_scene_registry, trace_objects

    scene_glb(tmp_path / "s.glb", extra_node=False)
    assets = [str(tmp_path / "s.glb"), str(mesh_file("blob.off"))]
    ids = ["u1", "u2", "u3"]
    opts = pmwm.fingerprint.FingerprintOptions(seed=5)
    res = run_catalogue(assets, ids, tmp_path / "a", options=opts, n_workers=1, batch=2)
    assert not res.failed and res.written == 6
    assert sorted(p.name for p in (tmp_path / "a" / "s").iterdir()) == ["registry.json", "u1.glb", "u2.glb", "u3.glb"]
    (_, V, F) = read_objects(tmp_path / "a" / "s" / "u2.glb")[0]
    sfk = read_any_fingerprint_key(tmp_path / "a" / "s.key.json")
    r = trace_objects([("alone", V, F)], sfk, read_scene_registry(tmp_path / "a" / "s" / "registry.json"))
    assert [a.recipient for a in r.accused] == ["u2"]
    src = pmwm.read_mesh(tmp_path / "a" / "blob" / "u3.ply")
    fk = read_fingerprint_key(tmp_path / "a" / "blob.key.json")
    reg = read_registry(tmp_path / "a" / "blob" / "registry.json")
    assert [a.recipient for a in trace(src.vertices, src.faces, fk, reg).accused] == ["u3"]
    tree = {p: p.read_bytes() for p in sorted((tmp_path / "a").rglob("*")) if p.is_file()}
    again = run_catalogue(assets, ids, tmp_path / "a", options=opts, n_workers=1)
    assert again.written == 0 and again.skipped == 6
    assert {p: p.read_bytes() for p in sorted((tmp_path / "a").rglob("*")) if p.is_file()} == tree


@pytest.mark.parametrize(
    "objects",
    [None, [], [{"name": "a"}], [{"name": 3, "key": {}}], ["not an object"]],
)
def test_a_damaged_scene_key_is_refused_in_one_line(tmp_path, objects):
    """A scene key (or scene fingerprinting key) whose objects are missing or malformed: a KeyFileError that
    names the file, for both readers."""
    from pmwm.fingerprint.scene import SCENE_KEY_FORMAT as FP_FORMAT
    from pmwm.fingerprint.scene import VERSION as FP_VERSION
    from pmwm.fingerprint.scene import read_any_fingerprint_key
    from pmwm.scene.asset import SCENE_KEY_FORMAT, SCENE_KEY_VERSION

    doc = {"format": SCENE_KEY_FORMAT, "version": SCENE_KEY_VERSION}
    fp = {"format": FP_FORMAT, "version": FP_VERSION}
    if objects is not None:
        doc["objects"] = fp["objects"] = objects
    (tmp_path / "k.json").write_text(json.dumps(doc))
    (tmp_path / "f.json").write_text(json.dumps(fp))
    with pytest.raises(pmwm.KeyFileError, match="k.json is damaged"):
        read_keys(tmp_path / "k.json")
    with pytest.raises(pmwm.KeyFileError, match="f.json is damaged"):
        read_any_fingerprint_key(tmp_path / "f.json")
