"""Bad input gets a clear error or a documented fallback; nothing of the key leaks into outputs."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import pmwm
from pmwm import EmbedOptions, embed, verify

import meshes


@pytest.fixture(scope="module")
def fandisk():
    """A CAD-like part: flat faces and sharp creases."""
    return meshes.cad_part()


def _embed_ok(V, F):
    res = embed(V, F, EmbedOptions(seed=1))
    v = verify(res.vertices, F, res.key)
    assert v.marked and v.bit_errors == 0
    Vd, Fd = res.pm.decode()
    assert np.array_equal(Vd, res.vertices[res.pm.vertex_order])
    return res


def test_single_triangle_is_refused_with_the_way_out():
    with pytest.raises(pmwm.PayloadError, match="fewer bits"):
        embed(np.eye(3), np.array([[0, 1, 2]]), EmbedOptions(seed=1))


@pytest.mark.slow
def test_nonmanifold_edge_falls_back_to_locking_it(fandisk):
    V, F = fandisk
    e = F[0, :2]
    fin = V[e].mean(0) + [0, 0, 1.0]
    V2 = np.vstack([V, fin])
    F2 = np.vstack([F, [[e[0], e[1], len(V)]]])
    res = _embed_ok(V2, F2)
    # the vertices of the non-manifold edge are neither carriers nor removed
    assert not set(e.tolist()) & set(res.carriers.tolist())
    assert set(e.tolist()) <= set(res.pm.vertex_order[: res.pm.n_base_vertices].tolist())


@pytest.mark.slow
def test_duplicate_and_loose_vertices_survive_unchanged(fandisk):
    V, F = fandisk
    rng = np.random.default_rng(0)
    extra = np.vstack([V[:50], rng.random((30, 3))])  # duplicates of used vertices, and loose points
    V2 = np.vstack([V, extra])
    res = _embed_ok(V2, F)
    assert np.array_equal(res.vertices[len(V) :], extra.astype(np.float32).astype(np.float64))


@pytest.mark.slow
def test_zero_area_faces(fandisk):
    V, F = fandisk
    V2 = V.copy()
    V2[F[5, 0]] = V2[F[5, 1]]  # two faces collapse to zero area
    _embed_ok(V2, F)


@pytest.mark.parametrize("scale", [1e-20, 1e20])
@pytest.mark.slow
def test_tiny_and_huge_but_representable_coordinates(fandisk, scale):
    V, F = fandisk
    _embed_ok(V * scale, F)


@pytest.mark.parametrize(
    "vertices, faces, match",
    [
        (np.zeros((0, 3)), np.zeros((0, 3), int), "empty"),
        (np.eye(3), np.zeros((0, 3), int), "empty"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]), np.array([[0, 1, 2]]), "NaN"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.inf, 0, 0]]), np.array([[0, 1, 2]]), "NaN or infinite"),
        (np.eye(3) * 1e35, np.array([[0, 1, 2]]), "rescale"),
        (np.eye(3), np.array([[0, 1, 3]]), "outside"),
        (np.eye(3), np.array([[0, 1, 2, 0]]), "triangles"),
    ],
)
def test_bad_arrays_get_one_line_errors(vertices, faces, match):
    with pytest.raises(pmwm.MeshError, match=match) as err:
        embed(vertices, faces, EmbedOptions(seed=1))
    assert "\n" not in str(err.value)


def _sha(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


@pytest.mark.slow
def test_verify_never_modifies_its_inputs_and_outputs_hold_no_key(tmp_path):
    mesh = tmp_path / "cow.off"
    mesh.write_bytes(meshes.mesh_file("blob.off").read_bytes())
    out, key, pmf = tmp_path / "m.ply", tmp_path / "k.json", tmp_path / "m.pmwm"
    run = [sys.executable, "-m", "pmwm"]
    subprocess.run(
        run
        + [
            "embed",
            str(mesh),
            "-o",
            str(out),
            "--key",
            str(key),
            "--pm",
            str(pmf),
            "--bits",
            "1" * 16 + "0" * 16,
            "--seed",
            "9",
            "-q",
        ],
        check=True,
    )
    assert (os.stat(key).st_mode & 0o777) == 0o600
    before = {p: (_sha(p), os.stat(p).st_mode, os.stat(p).st_mtime_ns) for p in (out, key, pmf, mesh)}
    for suspect in (out, pmf, mesh):
        subprocess.run(run + ["verify", str(suspect), "--key", str(key), "--json"], capture_output=True)
    after = {p: (_sha(p), os.stat(p).st_mode, os.stat(p).st_mtime_ns) for p in (out, key, pmf, mesh)}
    assert before == after
    doc = json.loads(key.read_text())
    secret = doc["secret"].encode()
    for f in (out, pmf):
        blob = f.read_bytes()
        assert secret not in blob and secret.upper() not in blob
        assert bytes.fromhex(doc["secret"]) not in blob
        assert doc["bits"].encode() not in blob
