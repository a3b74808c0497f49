"""Cho et al. 2007 methods I and II: exact recovery, invariances, and what the embedding changes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from pmwm import attacks as A
from pmwm import cho
from pmwm.errors import KeyFileError, PayloadError
from pmwm.metrics import ber, vsnr

BUNNY = Path(cho.__file__).parent / "data" / "bunny.off"


@pytest.fixture(scope="module")
def bunny():
    m = trimesh.load(BUNNY, process=False)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


def random_bits(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 2, n).astype(np.uint8)


@pytest.fixture(scope="module", params=["I", "II"])
def marked(request, bunny):
    v, f = bunny
    bits = random_bits(64, seed=5)
    mv, key = cho.cho_embed(v, f, bits, method=request.param, alpha=0.05)
    return request.param, bits, mv, key


def test_unattacked_recovers_every_bit(marked, bunny):
    method, bits, mv, key = marked
    _, f = bunny
    assert key.method == method and key.n_bits == 64
    np.testing.assert_array_equal(cho.cho_extract(mv, f, key), bits)


def test_recovers_every_bit_after_similarity_and_reordering(marked, bunny):
    _, bits, mv, key = marked
    _, f = bunny
    for seed in range(3):
        v2, f2 = A.similarity(mv, f, seed=seed)
        v2, f2 = A.reorder(v2, f2, seed=seed + 10)
        np.testing.assert_array_equal(cho.cho_extract(v2, f2, key), bits)


def test_embedding_is_radial_small_and_keeps_the_extreme_vertices(marked, bunny):
    _, _, mv, _ = marked
    v, _ = bunny
    c = v.mean(axis=0)
    d, d2 = v - c, mv - c
    rho = np.linalg.norm(d, axis=1)
    # every vertex moved along its own direction from the centre
    np.testing.assert_allclose(np.cross(d, d2), 0.0, atol=1e-12 * rho.max() ** 2)
    for i in (np.argmin(rho), np.argmax(rho)):
        np.testing.assert_array_equal(mv[i], v[i])
    assert 45.0 < vsnr(v, mv) < 90.0  # imperceptible but not a no-op


def test_unmarked_mesh_does_not_read_as_the_payload(bunny):
    v, f = bunny
    bits = random_bits(64, seed=9)
    _, key = cho.cho_embed(v, f, bits, method="I")
    assert ber(cho.cho_extract(v, f, key), bits) > 0.2


@pytest.mark.parametrize("method", ["I", "II"])
def test_survives_light_benchmark_noise(bunny, method):
    v, f = bunny
    bits = random_bits(32, seed=2)
    mv, key = cho.cho_embed(v, f, bits, method=method)
    v2, f2 = A.noise_benchmark(mv, f, 0.0005, seed=1)
    assert ber(cho.cho_extract(v2, f2, key), bits) <= 0.1


def test_stronger_alpha_moves_vertices_more(bunny):
    v, f = bunny
    bits = random_bits(32, seed=3)
    weak, _ = cho.cho_embed(v, f, bits, alpha=0.02)
    strong, _ = cho.cho_embed(v, f, bits, alpha=0.08)
    assert vsnr(v, strong) < vsnr(v, weak)


def test_too_many_bits_for_the_mesh_is_a_payload_error():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 3, 3]])
    with pytest.raises(PayloadError, match="fewer bits"):
        cho.cho_embed(v, np.zeros((0, 3), int), "0101010101")


def test_bad_bits_are_rejected(bunny):
    v, f = bunny
    with pytest.raises(PayloadError):
        cho.cho_embed(v, f, "01x1")
    with pytest.raises(PayloadError):
        cho.cho_embed(v, f, [0, 2, 1])


def test_adapter_and_key_round_trip(bunny):
    v, f = bunny
    method = cho.cho_method("cho-2", alpha=0.06)
    assert method.method == "II" and method.name == "Cho II"
    bits = random_bits(16, seed=4)
    mv, key = method.embed(v, f, bits, seed=123)
    key2 = cho.ChoKey.from_dict(key.to_dict())
    assert key2 == key
    np.testing.assert_array_equal(method.extract(mv, f, key2), bits)
    with pytest.raises(KeyFileError):
        cho.ChoKey.from_dict({"method": "I"})
    with pytest.raises(ValueError):
        cho.cho_method("III")
