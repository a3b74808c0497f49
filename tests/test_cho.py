"""Cho et al. 2007 methods I and II as schemes "cho1" and "cho2" behind pmwm.embed / pmwm.verify:
exact recovery, invariances, the key file, and what the embedding changes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

import pmwm
from pmwm import attacks as A
from pmwm.errors import KeyFileError, PayloadError
from pmwm.metrics import ber, vsnr

BUNNY = Path(pmwm.__file__).parent / "data" / "bunny.off"


@pytest.fixture(scope="module")
def bunny():
    m = trimesh.load(BUNNY, process=False)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


def random_bits(n: int, seed: int) -> str:
    return "".join(map(str, np.random.default_rng(seed).integers(0, 2, n)))


def cho_embed(v, f, bits, scheme="cho1", alpha=None, seed=1):
    return pmwm.embed(v, f, pmwm.EmbedOptions(bits=bits, scheme=scheme, strength=alpha, seed=seed))


@pytest.fixture(scope="module", params=["cho1", "cho2"])
def marked(request, bunny):
    v, f = bunny
    bits = random_bits(64, seed=5)
    return request.param, bits, cho_embed(v, f, bits, request.param)


def test_unattacked_recovers_every_bit_and_the_progressive_mesh(marked, bunny):
    scheme, bits, res = marked
    _, f = bunny
    assert res.key.scheme == scheme and res.key.n_bits == 64 and res.key.strength == 0.05
    v = pmwm.verify(res.vertices, f, res.key)
    assert v.bits == bits and v.marked and v.mode == "blind"
    assert pmwm.verify_pm(res.pm, res.key).bits == bits  # the full level of the progressive mesh


def test_recovers_every_bit_after_similarity_and_reordering(marked, bunny):
    _, bits, res = marked
    _, f = bunny
    for seed in range(3):
        v2, f2 = A.similarity(res.vertices, f, seed=seed)
        v2, f2 = A.reorder(v2, f2, seed=seed + 10)
        assert pmwm.verify(v2, f2, res.key).bits == bits


def test_key_file_round_trip_and_damage(marked, bunny, tmp_path):
    scheme, bits, res = marked
    _, f = bunny
    path = tmp_path / "k.json"
    pmwm.write_key(path, res.key)
    key = pmwm.read_key(path)
    assert key.scheme == scheme and key.data == res.key.data
    assert pmwm.verify(res.vertices, f, key).bits == bits
    doc = json.loads(path.read_text())
    doc["extra"]["method"] = "II" if scheme == "cho1" else "I"  # says one method, holds the other
    path.write_text(json.dumps(doc))
    with pytest.raises(KeyFileError, match="damaged"):
        pmwm.read_key(path)
    del doc["extra"]["alpha"]
    path.write_text(json.dumps(doc))
    with pytest.raises(KeyFileError, match="alpha"):
        pmwm.read_key(path)


def test_embedding_is_radial_small_and_keeps_the_extreme_vertices(marked, bunny):
    _, _, res = marked
    v, _ = bunny
    mv = res.vertices
    c = v.mean(axis=0)
    d, d2 = v - c, mv - c
    rho = np.linalg.norm(d, axis=1)
    moved = np.linalg.norm(mv - v, axis=1) > 1e-6 * rho.max()
    # every vertex that moved did so along its own direction from the centre (float32 rounding aside)
    sin = np.linalg.norm(np.cross(d[moved], d2[moved]), axis=1) / (rho[moved] * np.linalg.norm(d2[moved], axis=1))
    assert sin.max() < 1e-5
    for i in (np.argmin(rho), np.argmax(rho)):
        np.testing.assert_allclose(mv[i], v[i], rtol=1e-7, atol=1e-7 * rho.max())
    assert 45.0 < vsnr(v, mv) < 90.0  # imperceptible but not a no-op


def test_unmarked_mesh_reads_as_chance(bunny):
    v, f = bunny
    res = cho_embed(v, f, random_bits(64, seed=9))
    verdict = pmwm.verify(v, f, res.key)
    assert not verdict.marked and verdict.p_value > 1e-3 and ber(verdict.bits, random_bits(64, seed=9)) > 0.2


@pytest.mark.parametrize("scheme", ["cho1", "cho2"])
def test_survives_light_benchmark_noise(bunny, scheme):
    v, f = bunny
    bits = random_bits(32, seed=2)
    res = cho_embed(v, f, bits, scheme)
    v2, f2 = A.noise_benchmark(res.vertices, f, 0.0005, seed=1)
    assert ber(pmwm.verify(v2, f2, res.key).bits, bits) <= 0.1


def test_stronger_alpha_moves_vertices_more(bunny):
    v, f = bunny
    bits = random_bits(32, seed=3)
    weak = cho_embed(v, f, bits, alpha=0.02)
    strong = cho_embed(v, f, bits, alpha=0.08)
    assert vsnr(v, strong.vertices) < vsnr(v, weak.vertices)


def test_too_many_bits_for_the_mesh_is_a_payload_error():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 3, 3]])
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])
    with pytest.raises(PayloadError, match="fewer bits"):
        cho_embed(v, f, "0101010101")


def test_bad_bits_and_alpha_are_rejected(bunny):
    v, f = bunny
    with pytest.raises(PayloadError):
        cho_embed(v, f, "01x1")
    with pytest.raises(PayloadError):
        cho_embed(v, f, [0, 2, 1])
    with pytest.raises(PayloadError, match="alpha"):
        cho_embed(v, f, "0110", alpha=0.6)
