"""The blind scheme's keyed-waves carrier: what a user marks with a pass phrase reads back from copies they
may meet, a wrong phrase reads nothing, older marks of the baseline carrier still read, and what keyed waves
cannot carry is marked by the baseline carrier with a note saying so."""

from __future__ import annotations

import numpy as np
import pytest

import meshes
import pmwm
from pmwm import attacks
from pmwm import convcode
from pmwm.smoothing import cotangent_step
from pmwm.schemes.blind import plan, solid, waveread, waves, word
from pmwm.schemes.blind.detail import BlindDetail
from pmwm.schemes.blind.waveread import WavesDetail
from pmwm_bench import corpus

PHRASE = "a pass phrase only the studio knows"


@pytest.fixture(scope="module")
def shape():
    return corpus.generate("organic", 3, 8000)


@pytest.fixture(scope="module")
def marked(shape):
    V, F = shape
    return pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind", passphrase=PHRASE, payload="ACME-2026", progressive=False)
    )


def flat_disc(n: int = 70) -> tuple[np.ndarray, np.ndarray]:
    """A flat disc of about 3,700 vertices in the plane z = 0: an open sheet that bounds no solid."""
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    inside = (x**2 + y**2 <= 1.0).ravel()
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    F = F[inside[F].all(1)]
    used = np.unique(F)
    remap = np.full(n * n, -1)
    remap[used] = np.arange(len(used))
    return np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1)[used], remap[F]


def _reads(V, F, phrase=PHRASE):
    v = pmwm.verify(V, F, passphrase=phrase)
    return v.marked and v.payload == "ACME-2026" and isinstance(v.detail, WavesDetail) and v.p_value < 1e-6, v


def test_a_keyed_waves_mark_costs_at_most_its_budget_and_reads_as_written(shape, marked):
    V, F = shape
    assert marked.notes == () and marked.key is None
    assert 0 < marked.strength <= pmwm.schemes.blind.WAVES_BUDGET  # (the strength reported: the MRMS spent)
    mrms = pmwm.metrics.displaced_surface_distance(V, marked.vertices, F, 5000, seed=0)[0]
    assert mrms == pytest.approx(marked.strength)
    ok, v = _reads(marked.vertices.astype(np.float32), F)
    assert ok, v
    assert v.detail.mesh == "suspect" and v.bits and len(v.bits) == 72  # (9 bytes of text: the word fits them)


@pytest.mark.parametrize(
    "attack",
    [
        lambda V, F: attacks.reorder(*attacks.similarity(V, F, seed=5), seed=6),
        lambda V, F: attacks.similarity(V * np.array([-1.0, 1.0, 1.0]), F[:, ::-1], seed=7),  # mirrored
        lambda V, F: attacks.noise_benchmark(V, F, 0.001, seed=8),
        lambda V, F: attacks.quantize(V, F, bits=10),
        lambda V, F: attacks.simplify(V, F, ratio=0.5),
        lambda V, F: attacks.subdivide(V, F, "loop"),
    ],
    ids=["pose and order", "mirrored", "noise 0.1 %", "10-bit quantization", "50 % simplification", "Loop"],
)
def test_the_payload_reads_from_copies_a_user_may_meet(marked, shape, attack):
    ok, v = _reads(*attack(marked.vertices, shape[1]))
    assert ok, (v.p_value, v.detail)


def test_smoothing_is_undone_by_the_reader_and_said(marked, shape):
    ok, v = _reads(*attacks.smooth_laplacian(marked.vertices, shape[1], lam=0.5, iterations=5))
    assert ok, v
    assert v.detail.mesh.startswith("uniform:") and "undone" in v.detail.notes()[0]


def pymeshlab_cotangent(V, F, steps: int) -> np.ndarray:
    """pymeshlab's default smoothing (Laplacian, cotangent weights), ``steps`` times."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(V, np.float64), np.asarray(F, np.int32)))
    ms.apply_coord_laplacian_smoothing(stepsmoothnum=steps)
    return ms.current_mesh().vertex_matrix()


def test_the_readers_cotangent_step_is_meshlabs():
    V, F = corpus.generate("cad", 5, 4000)
    W = V
    for _ in range(3):
        W = cotangent_step(W, F)
    assert np.abs(W - pymeshlab_cotangent(V, F, 3)).max() < 1e-7 * np.ptp(V, axis=0).max()


def test_pymeshlabs_cotangent_smoothing_is_undone_by_the_reader(marked, shape):
    ok, v = _reads(pymeshlab_cotangent(marked.vertices, shape[1], 5), shape[1])
    assert ok, v
    assert v.detail.mesh.startswith("cotangent:")


def test_a_wrong_phrase_or_an_unmarked_mesh_reads_nothing_and_shows_no_payload(marked, shape):
    for V, phrase in ((marked.vertices, "another phrase"), (shape[0], PHRASE)):
        v = pmwm.verify(V, shape[1], passphrase=phrase)
        assert not v.marked and v.payload is None and v.bits == "" and v.p_value > 1e-3
        assert v.to_dict()["payload"] is None and not v.to_dict()["bits"]


def test_a_baseline_histogram_mark_still_reads_with_the_pass_phrase():
    V, F = meshes.bunny()
    res = pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind-histogram", passphrase=PHRASE, payload="OLD", progressive=False)
    )
    v = pmwm.verify(res.vertices, F, passphrase=PHRASE)
    assert v.marked and v.payload == "OLD" and isinstance(v.detail, BlindDetail)
    assert v.p_value < 1e-6 and v.p_threshold == 1e-6


def test_what_keyed_waves_cannot_carry_is_marked_by_the_baseline_and_said():
    Vo, Fo = flat_disc()  # an open sheet bounds no solid
    res = pmwm.embed(Vo, Fo, pmwm.EmbedOptions(scheme="blind", passphrase=PHRASE, payload="CAP", progressive=False))
    assert len(res.notes) == 1 and "bounds no volume" in res.notes[0] and "baseline histogram carrier" in res.notes[0]
    v = pmwm.verify(res.vertices, Fo, passphrase=PHRASE)
    assert v.marked and v.payload == "CAP" and isinstance(v.detail, BlindDetail)


def test_a_payload_neither_carrier_can_carry_is_refused_in_one_line_naming_both(shape):
    long_text = "a payload of 20 bytes"  # beyond the 12 bytes keyed waves carry
    with pytest.raises(pmwm.PayloadError) as err:
        pmwm.embed(*shape, pmwm.EmbedOptions(scheme="blind", passphrase=PHRASE, payload=long_text, progressive=False))
    msg = str(err.value)
    assert msg.startswith(
        "keyed waves can hold at most 12 bytes of text; this payload has 21, and the baseline carrier"
    )
    assert "\n" not in msg and "nothing written" in msg


def test_the_cli_prints_the_note_of_a_baseline_marking(tmp_path):
    import subprocess
    import sys

    src = meshes.write_off(tmp_path / "disc.off", *flat_disc())
    env = dict(__import__("os").environ, PMWM_PASSPHRASE=PHRASE)
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmwm",
            "embed",
            str(src),
            "-o",
            str(tmp_path / "m.ply"),
            "--scheme",
            "blind",
            "--payload",
            "CAP",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr
    assert "note: keyed waves mark a solid" in p.stderr and "blind-histogram" in p.stderr
    assert f"marked 32 bits in {src} " in p.stdout  # (the baseline pads "CAP" to 32 bits; no carriers to count)


def test_marking_leaves_the_solids_frame_where_it_was(shape, marked):
    before, after = solid.solid_frame(*shape), solid.solid_frame(marked.vertices, shape[1])
    assert np.linalg.norm(after.centre - before.centre) < 1e-5 * before.scale
    assert abs(after.scale / before.scale - 1) < 2e-5
    assert np.allclose(np.abs(np.diag(after.axes.T @ before.axes)), 1, atol=1e-5)


def test_the_two_carriers_share_the_false_positive_budget():
    """A verdict reads both carriers: keyed waves at most WAVES_SHARE of alpha, the histogram the rest."""
    h = waveread.hypotheses(1)
    assert h == 1 * (1 + 2 * len(waveread.UNDO_STEPS)) * len(waves.STEPS) * len(waveread.LENGTHS) * 2
    best = plan.waves_p_value(2.0**-waveread.CHECK_BITS, waveread.hypotheses(8))
    assert best < 1e-6  # a reading with every check bit right is marked even with all 8 sign choices
    assert plan.waves_p_value(0.5, h) == 1.0
    assert plan.histogram_p_value(9.99e-7) < 1e-6  # the histogram's best readings stay marked


def test_the_check_bits_of_each_carrier_are_its_own():
    secret = word.derive_secret(PHRASE)
    payload = np.random.default_rng(1).integers(0, 2, 64).astype(np.uint8)
    a = word.check_bits(secret, "bits", payload)
    b = word.check_bits(secret, "bits", payload, waveread.CHECK_BITS, waveread.CHECK_LABEL)
    assert len(a) == 32 and len(b) == 64 and not np.array_equal(a, b[:32])


@pytest.mark.parametrize("rate", ["1/2", "2/3", "3/4"])
def test_the_viterbi_decoder_reads_a_noisy_word_and_not_a_random_one(rate):
    """Soft decisions with Gaussian noise at 0.5 of the signal: every word read back; random scores give
    a word whose check bits (its last 64) match by chance only."""
    rng = np.random.default_rng(3)
    msgs = rng.integers(0, 2, (20, 136)).astype(np.uint8)
    coded = np.array([convcode.encode(m, rate) for m in msgs])
    assert coded.shape[1] == convcode.coded_length(136, rate)
    soft = 1.0 - 2.0 * coded + rng.normal(0, 0.5, coded.shape)
    assert np.array_equal(convcode.decode(soft, 136, rate), msgs)
    assert np.array_equal(convcode.decode(soft[0], 136, rate), msgs[0])  # one word alone
    noise = convcode.decode(rng.normal(size=coded.shape), 136, rate)
    assert (noise[:, 72:] == msgs[:, 72:]).mean() == pytest.approx(0.5, abs=0.1)
    with pytest.raises(ValueError, match="coded bits"):
        convcode.decode(soft[:, :-1], 136, rate)


def test_a_text_payload_takes_the_shortest_word_of_whole_bytes():
    for text, bits in (("A", 8), ("ACME-2026", 72), ("twelve bytes", 96)):
        payload, kind = word.payload_of(text, None, 0, None, waveread.LENGTHS)
        assert kind == "text" and len(payload) == bits and word.text_of(payload) == text
    assert waveread.coded_bits(72) < waveread.coded_bits(96) < waves.N_WAVES // 2
