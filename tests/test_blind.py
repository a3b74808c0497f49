"""The blind scheme: a pass phrase and the suspect mesh read the payload, with an exact p-value;
no key file; the same pass phrase over many meshes; the command line and its errors."""

from __future__ import annotations

import contextlib
import json
import dataclasses
from dataclasses import replace
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshes
import pmwm
from pmwm import attacks as A
from pmwm.errors import MeshError, PayloadError
from pmwm.features import vertex_areas
from pmwm.meshio import read_mesh, write_mesh
from pmwm.schemes import blind
from pmwm.schemes.blind import crop, frames, plan, radial, word
from pmwm.schemes.blind.config import READER

BUNNY = Path(pmwm.__file__).parent / "data" / "bunny.off"
PHRASE = "correct horse battery staple"
SECRET = word.derive_secret(PHRASE)


@contextlib.contextmanager
def calls_of(fn):
    """The names of the threads in which ``fn`` was called while the context was open (a profile hook on
    this thread and on the threads started meanwhile: the code is observed, not replaced)."""
    code, where = fn.__code__, []

    def hook(frame, event, arg):
        if event == "call" and frame.f_code is code:
            where.append(threading.current_thread().name)

    sys.setprofile(hook)
    threading.setprofile(hook)
    try:
        yield where
    finally:
        sys.setprofile(None)
        threading.setprofile(None)


@pytest.fixture(scope="module")
def bunny():
    m = trimesh.load(BUNNY, process=False)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="module")
def marked(bunny):
    v, f = bunny
    return pmwm.embed(v, f, pmwm.EmbedOptions(scheme="blind-histogram", payload="Acme", passphrase=PHRASE, seed=3))


def bitstring(n: int, seed: int) -> str:
    return "".join(map(str, np.random.default_rng(seed).integers(0, 2, n)))


def test_text_payload_read_with_the_pass_phrase_alone(marked):
    v = pmwm.verify(marked.vertices, marked.faces, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.mode == "blind"
    # all 32 check bits; the union bound over 2 kinds x 1024 Chase candidates per frame read (own, and
    # refined if it moved), of the one length the mark's energy names
    assert v.detail.frames in (1, 2) and v.detail.chase_bits == 10
    assert v.p_value == pytest.approx(plan.histogram_p_value(v.detail.frames * 2 * 1024 * 2.0**-32))
    assert v.p_value < 1e-6
    assert v.detail.payload_kind == "text" and v.detail.payload_bits == 32


def test_wrong_pass_phrase_and_unmarked_mesh_are_not_marked(bunny, marked):
    assert not pmwm.verify(marked.vertices, marked.faces, passphrase=PHRASE + "!").marked
    v = pmwm.verify(*bunny, passphrase=PHRASE)
    assert not v.marked and v.payload is None


def test_a_verdict_that_reads_no_mark_carries_neither_the_payload_nor_its_bits(bunny, marked):
    """Not marked: no payload text, no bits, no word in the detail, nothing in the JSON, whatever candidate
    the check bits chose; marked: the payload is confirmed by its check bits, bits and text."""
    stats = blind.bin_statistics(marked.vertices, marked.faces)
    high = blind.decide(stats, SECRET, p_threshold=1e-30)  # the marked copy, read against a threshold it misses
    assert not high.marked and high.p_value < 1e-6
    for v in (
        high,
        pmwm.verify(marked.vertices, marked.faces, passphrase=PHRASE + "!"),
        pmwm.verify(*bunny, passphrase=PHRASE),
    ):
        assert (v.payload, v.bits, v.payload_confirmed) == (None, "", False)
        assert v.detail.word is v.detail.word_read is v.detail.payload_kind is None
        d = v.to_dict()
        assert (d["payload"], d["bits"], d["payload_confirmed"]) == (None, None, False)
        assert "01000001011000110110110101100101" not in repr(v) + str(d)  # "Acme"'s bits
    v = pmwm.verify(marked.vertices, marked.faces, passphrase=PHRASE)
    assert v.marked and v.payload_confirmed and v.payload == "Acme" and v.bits == "01000001011000110110110101100101"
    assert v.to_dict()["bits"] == v.bits and v.to_dict()["payload_confirmed"] is True


def test_a_pass_phrase_scheme_returns_no_key_and_takes_none(marked):
    """The blind embed returns no key (nothing to keep but the pass phrase); a key naming the blind scheme is
    refused; a key and a pass phrase together, or neither, are refused."""
    assert marked.key is None and 0.03 <= marked.strength <= 0.2
    assert pmwm.SCHEMES["blind"].keying == pmwm.SCHEMES["blind-histogram"].keying == pmwm.PASS_PHRASE
    assert {s.keying for n, s in pmwm.SCHEMES.items() if not n.startswith("blind")} == {pmwm.KEY_FILE}
    other = pmwm.embed(*meshes.blob(), pmwm.EmbedOptions(payload="Acme", seed=1, progressive=False)).key
    blind_key = dataclasses.replace(other, scheme="blind-histogram")
    with pytest.raises(pmwm.KeyFileError, match="pass phrase"):
        pmwm.verify(marked.vertices, marked.faces, blind_key)
    with pytest.raises(PayloadError, match="not both"):
        pmwm.verify(marked.vertices, marked.faces, other, passphrase=PHRASE)
    with pytest.raises(PayloadError, match="pass phrase"):
        pmwm.verify(marked.vertices, marked.faces)
    with pytest.raises(PayloadError, match="non-empty pass phrase"):
        pmwm.verify(marked.vertices, marked.faces, passphrase="")


def test_a_bad_suspect_read_with_the_pass_phrase_raises_and_leaves_no_thread(marked):
    """The secret is derived in a worker beside the reading (``blind.verify``): a suspect the
    reading refuses raises its MeshError, and the worker is gone when it does."""
    V = marked.vertices.copy()
    V[3] = np.nan
    with pytest.raises(MeshError):
        pmwm.verify(V, marked.faces, passphrase=PHRASE)
    assert not [t for t in threading.enumerate() if t.name.startswith("pmwm-background")]


@pytest.mark.parametrize(
    "attack",
    [
        lambda v, f: A.similarity(v, f, seed=4),
        lambda v, f: A.reorder(v, f, seed=5),
        lambda v, f: A.quantize(v, f, bits=10),
        lambda v, f: A.noise_benchmark(v, f, 0.003, seed=6),
    ],
    ids=["similarity", "reorder", "quantize10", "noise0.3%"],
)
def test_whole_payload_survives(marked, attack):
    v = pmwm.verify(*attack(marked.vertices, marked.faces), passphrase=PHRASE)
    assert v.marked and v.payload == "Acme"


@pytest.mark.parametrize(
    "attack",
    [
        lambda v, f: A.smooth_laplacian(v, f, lam=0.1, iterations=8, seed=0),
        lambda v, f: A.noise_benchmark(v, f, 0.01, seed=2),
    ],
    ids=["smoothing8", "noise1%"],
)
def test_refined_frame_reads_what_the_own_frame_loses(marked, attack):
    """These attacks move the suspect's frame by a fraction of a bin; read in its own frame alone the
    payload is lost, the key-free frame refinement finds it, with p still below 1e-6 (the smoothed copy
    reads with its smoothing undone too: left out here, the refinement alone)."""
    config = READER.without("unsmoothed")
    V, F = attack(marked.vertices, marked.faces)
    stats = blind.bin_statistics(V, F, config)
    own_only = blind.decide(stats.own_frame(), SECRET)
    assert not (own_only.marked and own_only.payload == "Acme")
    v = blind.verify(V, F, PHRASE, config=config)
    assert v.marked and v.payload == "Acme" and v.detail.frame == "refined" and v.p_value < 1e-6


def test_the_edge_preserving_push_reads_what_r_to_the_k_lost(marked):
    """The push r + beta sin^2(pi r) leaves the bins' edges alone: the bunny's payload survives 10
    smoothing iterations, and 0.5 % noise in the suspect's own frame (Cho's r**k lost both)."""
    V, F = A.smooth_laplacian(marked.vertices, marked.faces, lam=0.1, iterations=10, seed=0)
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme"
    V, F = A.noise_benchmark(marked.vertices, marked.faces, 0.005, seed=1)
    stats = blind.bin_statistics(V, F)
    own_only = blind.decide(stats.own_frame(), SECRET)
    assert own_only.marked and own_only.payload == "Acme"


@pytest.mark.parametrize("ranks", [(8, 9), (10, 11), (10,)], ids=["9th+10th", "11th+12th", "11th"])
def test_the_search_corrects_the_most_likely_errors_even_beyond_the_ten_least_reliable_bits(marked, ranks):
    """Wrong bits whose flip is among the 1024 most likely patterns (least total reliability) are
    corrected with p < 1e-6: the 9th and 10th least reliable, as Chase's search of the 10 least
    reliable did, and the 11th and 12th, which it could not."""
    stats = blind.bin_statistics(marked.vertices, marked.faces).own_frame()
    n = stats.n_word
    assert n == 32 + word.CHECK_BITS  # "Acme": 32 payload bits, the length the energy names
    stat, share = stats.words[n][0].copy(), stats.shares[n][0]
    _, score = blind.word_read(stat, SECRET, n, share)
    bit_of_bin, _ = word.layout(SECRET, n, len(stat))
    wrong = np.argsort(np.abs(score), kind="stable")[list(ranks)]
    flip = np.zeros(n, np.uint8)
    flip[wrong] = 1
    assert (word.likely_flips(np.abs(score), 1024) == flip).all(axis=1).any()  # among the patterns tried
    stat[np.isin(bit_of_bin, wrong)] *= -1  # the same reliabilities, those bits read wrong
    words, shares = dict(stats.words), dict(stats.shares)
    words[n], shares[n] = stat[None], share[None]
    v = blind.decide(blind.Statistics(words, n, ("own",), ("own",), shares), SECRET)
    assert v.detail.word_read != v.detail.word
    assert v.marked and v.payload == "Acme" and v.p_value == pytest.approx(2 * 1024 * 2.0**-32)


def test_the_most_likely_flips_are_the_lightest_sets_of_bits():
    """``word.likely_flips`` lists the sets of least total reliability, lightest first, each once."""
    import itertools

    rng = np.random.default_rng(5)
    for N, K in ((6, 64), (12, 100), (40, 1024)):
        w = np.abs(rng.normal(size=N))
        w[rng.integers(0, N)] = 0.0  # an erasure: free to flip
        got = word.likely_flips(w, K)
        assert got.shape == (min(K, 2**N), N) and not got[0].any()
        assert len({row.tobytes() for row in got}) == len(got)  # each set once
        cost = got @ w
        assert np.all(np.diff(cost) >= -1e-12)  # lightest first
        if N <= 12:  # against every subset
            every = np.sort([w[list(c)].sum() for k in range(N + 1) for c in itertools.combinations(range(N), k)])
            assert np.allclose(cost, every[: len(cost)])
    # a bit read with certainty (infinite reliability) is never flipped before the others
    got = word.likely_flips(np.array([0.3, np.inf, 0.1, 0.2]), 8)
    assert not got[:, 1].any() and len({row.tobytes() for row in got}) == 8


def test_a_word_read_bins_off_in_a_neighbour_frame_counts_every_frame_in_its_p_value(marked):
    """The crop frame's neighbours (lo one and two bins off either way) are read too: a word found only in
    one of them is read, with 8 Chase bits instead of 10 so that 6 frames x 2 kinds x 2^8 candidates keep
    the best p-value below 1e-6 (7.2e-7); a wrong pass phrase reads nothing in any of them."""
    stats = blind.bin_statistics(marked.vertices, marked.faces).own_frame()
    n = stats.n_word
    right = stats.words[n][0]
    shifted = np.roll(right, 2)  # the same bins read two bins off: the word shifted by two bins
    words = dict(stats.words)
    words[n] = np.stack([shifted, shifted, right, np.roll(right, 1), np.roll(right, 3), np.roll(right, 4)])
    names = ("own", "crop", "crop-2", "crop-1", "crop+1", "crop+2")
    stages = ("own",) + ("crop",) * 5
    v = blind.decide(blind.Statistics(words, n, names, stages), SECRET)
    assert v.marked and v.payload == "Acme" and v.detail.frame == "crop-2" and v.detail.frame_index == 2
    assert v.detail.chase_bits == 8 and v.p_value == pytest.approx(6 * 2 * 256 * 2.0**-32) and v.p_value < 1e-6
    wrong = blind.decide(blind.Statistics(words, n, names, stages), word.derive_secret(PHRASE + "!"))
    assert not wrong.marked
    assert [plan.chase_bits(k) for k in (1, 2, 3, 4, 5, 6)] == [10, 10, 9, 9, 8, 8]


def test_a_reserve_frame_reads_with_what_the_budget_leaves_and_the_others_keep_their_chase_bits(marked):
    """A copy on a coarse grid is also read in reserve frames (the plan's "reserve" stage, paid from what the
    others leave): the frames read in full keep 2^10 candidates, each reserve reading gets what P_BEST leaves
    (49 beside 2 frames), and the p-value
    counts them all. A word the full frames lose and a reserve frame holds with a weak bit wrong is read
    there, p < 1e-6; a wrong pass phrase reads nothing."""
    stats = blind.bin_statistics(marked.vertices, marked.faces).own_frame()
    n = stats.n_word
    right, share = stats.words[n][0], stats.shares[n][0]
    _, score = blind.word_read(right, SECRET, n, share)
    bit_of_bin, _ = word.layout(SECRET, n, len(right))
    order = np.argsort(np.abs(score), kind="stable")
    weak = right.copy()
    weak[bit_of_bin == order[5]] *= -1  # its sixth least reliable bit read wrong
    got, weak_score = blind.word_read(weak, SECRET, n, share)
    truth = blind.word_read(right, SECRET, n, share)[0]
    assert (got != truth).sum() == 1
    assert ((got ^ word.likely_flips(np.abs(weak_score), 49)) == truth).all(axis=1).any()  # among the 49 tried
    lost = right.copy()
    lost[np.isin(bit_of_bin, order[::3])] *= -1  # a third of the bits wrong: beyond any search
    words, shares = dict(stats.words), dict(stats.shares)
    words[n], shares[n] = np.stack([lost, lost, weak, lost]), np.stack([share] * 4)
    names = ("own", "refined", "denoised", "denoised-refined")
    stages = ("own", "refined", "reserve", "reserve")
    v = blind.decide(blind.Statistics(words, n, names, stages, shares), SECRET)
    assert v.marked and v.payload == "Acme" and v.detail.frame == "denoised" and v.detail.reserve_frames == 2
    assert v.detail.chase_bits == 10 and v.detail.candidates == plan.reserve_candidates(2, 2) == 49
    assert v.p_value == pytest.approx(2 * (2 * 1024 + 2 * 49) * 2.0**-32) and v.p_value < 1e-6
    wrong = blind.decide(blind.Statistics(words, n, names, stages, shares), word.derive_secret(PHRASE + "!"))
    assert not wrong.marked and wrong.p_value >= 2 * (2 * 1024 + 2 * 49) * 2.0**-32
    assert plan.reserve_candidates(1, 2) == 561


def test_every_reading_the_plan_allows_keeps_all_check_bits_right_below_1e_6():
    """The stages' shares of the budget (``plan.STAGES``: shared frames split it, the reserve takes what they
    leave) keep every reading the plan can make within it: any number of frames of each stage up to what it
    declares, the union bound over all their candidates times 2^-32 (all 32 check bits right) stays below
    P_BEST = 1e-6, and every shared frame read is read (one candidate per kind at least)."""
    import itertools

    frame_stages = [s for s in plan.STAGES if s.pays != plan.MESH]
    assert [s.name for s in frame_stages][0] == "own"
    for counts in itertools.product(*(range(len(s.frames) + 1) for s in frame_stages)):
        read = [s.name for s, k in zip(frame_stages, counts) for _ in range(k)]
        if not read:
            continue
        per_frame = plan.candidates(read)
        assert plan.union_bound(read) == 2 * sum(per_frame)
        assert plan.p_value(2.0**-word.CHECK_BITS, read) < plan.P_BEST
        shared = [c for c, s in zip(per_frame, read) if plan.stage(s).pays == plan.SHARED]
        assert all(c == 2 ** plan.chase_bits(len(shared)) >= 1 for c in shared)  # each shared frame is read
    assert plan.candidates(["own", "refined", "reserve", "reserve"]) == [1024, 1024, 49, 49]
    assert plan.candidates(["own"] + ["crop"] * 5) == [256] * 6
    with pytest.raises(ValueError):
        plan.candidates(["own", "coarse"])


@pytest.mark.parametrize("copy", ["marked", "8-bit", "crop", "noise 0.95 %"])
def test_a_verdicts_p_value_is_the_union_bound_over_the_stages_it_read(marked, copy):
    """Whatever stages a reading takes, its frames are the ones their stages declare and the verdict's
    p-value is ``plan.p_value`` over those stages: the union bound times the best candidate's tail."""
    V, F = {
        "marked": lambda v, f: (v, f),
        "8-bit": lambda v, f: A.quantize(v, f, bits=8),
        "crop": lambda v, f: A.crop_plane(v, f, fraction=0.1, seed=1),
        "noise 0.95 %": lambda v, f: A.noise_benchmark(v, f, 0.0095, seed=0),
    }[copy](marked.vertices, marked.faces)
    stats = blind.bin_statistics(V, F)
    assert all(name in plan.stage(stage).frames for name, stage in zip(stats.frame_names, stats.frame_stages))
    order = [s.name for s in plan.STAGES]
    assert [order.index(s) for s in stats.frame_stages] == sorted(order.index(s) for s in stats.frame_stages)
    v = blind.decide(stats, SECRET)
    assert v.marked and v.payload == "Acme"
    assert v.p_value == plan.p_value(pmwm.metrics.binomial_tail(v.matches, word.CHECK_BITS), stats.frame_stages)
    assert v.detail.frames == len(stats.frame_stages) and v.detail.reserve_frames == stats.frame_stages.count("reserve")
    wrong = blind.decide(stats, word.derive_secret(PHRASE + "!"))
    assert wrong.p_value == plan.p_value(pmwm.metrics.binomial_tail(wrong.matches, word.CHECK_BITS), stats.frame_stages)


def test_a_stage_the_configuration_leaves_out_is_not_read(marked):
    """``ReaderConfig.stages`` chooses the stages: without "refined" the marked bunny is read in its own frame
    alone, and with 1 frame its p-value halves; a name the plan does not have is refused."""
    stats = blind.bin_statistics(marked.vertices, marked.faces)
    assert stats.frame_stages == ("own", "refined")
    alone = blind.bin_statistics(marked.vertices, marked.faces, READER.without("refined"))
    assert alone.frame_stages == ("own",)
    v = blind.decide(alone, SECRET)
    assert v.marked and v.payload == "Acme" and v.p_value == pytest.approx(2 * 1024 * 2.0**-32)
    with pytest.raises(ValueError, match="no stage"):
        replace(READER, stages=("own", "sharpened"))


def test_the_docs_list_the_reading_plan_as_the_code_has_it():
    """docs/schemes/blind.md, "The reading plan": the table of ``plan.table`` with the reader's defaults, so the
    two cannot drift."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "schemes" / "blind.md").read_text()
    assert "\n".join(plan.table(READER)) in doc


def test_a_copy_on_a_coarse_grid_is_read_in_reserve_denoised_frames_too(marked):
    """Only a suspect on a coarse grid gets the denoised frames as reserve frames (when its bins show no blur,
    which gives them in full): the marked bunny as it is has none, its 8-bit copy both reserve frames, and
    still reads, its p-value counting their candidates."""
    plain = blind.bin_statistics(marked.vertices, marked.faces)
    assert "reserve" not in plain.frame_stages and not any(name.startswith("denoised") for name in plain.frame_names)
    V, F = A.quantize(marked.vertices, marked.faces, bits=8)
    assert frames.on_grid(V)
    stats = blind.bin_statistics(V, F)
    # its bins show no blur (that would give the denoised frames in full): they come as reserve frames
    assert stats.frame_names[-2:] == ("denoised", "denoised-refined") and stats.frame_stages[-2:] == ("reserve",) * 2
    v = blind.decide(stats, SECRET)
    assert v.marked and v.payload == "Acme" and v.p_value < 1e-6
    assert v.p_value == plan.p_value(pmwm.metrics.binomial_tail(32, 32), stats.frame_stages)


def test_bin_margins_give_every_bin_the_same_signal_to_noise():
    # alpha * sqrt(median count / count): a bin with a quarter of the vertices gets twice the margin
    m = radial.bin_margins(np.array([100.0, 100.0, 25.0, 400.0, 1.0, 0.0]))
    assert m.tolist() == [1.0, 1.0, 2.0, 0.5, radial.MARGIN_SPREAD[1], radial.MARGIN_SPREAD[1]]


@pytest.mark.parametrize(
    "attack",
    [
        lambda v, f: A.subdivide(v, f, "sqrt3"),
        lambda v, f: A.simplify(v, f, ratio=0.7, seed=1),
    ],
    ids=["sqrt3", "simplify70%"],
)
@pytest.mark.slow
def test_margins_by_bin_count_read_what_equal_margins_lost(marked, attack):
    """The bunny's bins hold 70 to 950 vertices; with the margin spread by count (at the same
    distortion budget) its payload survives sqrt3 subdivision and 70 % simplification, which left
    1 and 7 check bits wrong with one margin for all bins."""
    v = pmwm.verify(*attack(marked.vertices, marked.faces), passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.bit_errors == 0


def test_the_push_keeps_every_vertex_in_its_bin():
    r = np.linspace(0.0, 1.0, 100001)
    for beta in (-radial.BETA_MAX, -0.1, 0.1, radial.BETA_MAX):
        out = radial._push(r, np.full_like(r, beta))
        assert out[0] == 0.0 and out[-1] == 1.0
        assert np.all(np.diff(out) > 0)  # monotone: the order of the radii, and the bins, stay


def test_a_vertex_reaches_its_new_radius_moving_partly_along_the_surface():
    """Each vertex lands at the radius asked for; across its surface (its normal) it moves less than along
    its radius, by the share where the surface is oblique to the radius; without a normal, or with share 1,
    it moves along its radius."""
    rng = np.random.default_rng(2)
    V = rng.normal(size=(500, 3))
    centre = np.array([0.1, -0.2, 0.05])
    bv = radial.bin_vertices(V, radial.Frame(centre, 0.1, 5.0, 8))
    N = rng.normal(size=(500, 3))
    N /= np.linalg.norm(N, axis=1)[:, None]
    rho_new = bv.rho * (1.0 + rng.uniform(-0.02, 0.02, 500))
    X = radial.moved_to_radius(V, centre, bv, rho_new, N, 0.25)
    assert np.allclose(np.linalg.norm(X - centre, axis=1), rho_new, rtol=1e-12)
    along_radius = centre + bv.unit * rho_new[:, None]
    assert np.allclose(radial.moved_to_radius(V, centre, bv, rho_new, N, 1.0), along_radius)
    assert np.allclose(radial.moved_to_radius(V, centre, bv, rho_new, np.zeros_like(N), 0.25), along_radius)
    across = np.abs(np.einsum("ij,ij->i", X - V, N))
    across_radius = np.abs(np.einsum("ij,ij->i", along_radius - V, N))
    assert np.all(across <= 1.001 * across_radius + 1e-12)
    assert across.sum() < 0.6 * across_radius.sum()


@pytest.mark.slow
def test_the_push_marks_the_same_bins_with_less_distortion_moving_partly_along_the_surface(bunny):
    """At the same margin the bins read the same signs, and the surface is less distorted (the MRMS the
    calibration spends), when vertices move partly along it (radial.NORMAL_SHARE) than along their radius."""
    V, F = bunny
    signs = np.where(np.random.default_rng(5).random(64) < 0.5, 1, -1)
    along = radial.embed_signs(V, F, signs, 0.08)
    straight = radial.embed_signs(V, F, signs, 0.08, share=1.0)
    for X in (along, straight):
        fr, a = radial.frame_of(X, F, 64)
        stat, _ = radial.statistics_in(X, a, fr, [64])[0]
        assert np.array_equal(np.sign(stat), signs)
    d_along = pmwm.metrics.surface_distance(V, F, along, F, 20000, seed=1)[0]
    d_straight = pmwm.metrics.surface_distance(V, F, straight, F, 20000, seed=1)[0]
    assert d_along < 0.85 * d_straight


def test_frame_refinement_does_not_use_the_pass_phrase(marked):
    V, F = A.noise_benchmark(marked.vertices, marked.faces, 0.005, seed=1)
    stats = blind.bin_statistics(V, F)
    assert all(s.shape == (2, n) for n, s in stats.words.items())
    right = blind.decide(stats, SECRET)
    wrong = blind.decide(stats, word.derive_secret(PHRASE + "!"))
    assert right.marked and not wrong.marked and wrong.p_value > 1e-3


@pytest.mark.slow
def test_default_strength_spends_the_distortion_budget(bunny, marked):
    """Without a strength the margin is calibrated to MRMS ~TARGET_MRMS % of the bbox diagonal (rescaled
    twice: once left the blob 15 % short of it, twice 4 %); an explicit strength is used as given."""
    mrms = pmwm.metrics.surface_distance(*bunny, marked.vertices, marked.faces, 20000, seed=1)[0]
    assert mrms == pytest.approx(blind.TARGET_MRMS, rel=0.1)
    V, F = meshes.blob()
    cal = pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind-histogram", payload="x", passphrase=PHRASE, progressive=False)
    )
    mrms = pmwm.metrics.surface_distance(V, F, cal.vertices, cal.faces, 20000, seed=1)[0]
    assert mrms == pytest.approx(blind.TARGET_MRMS, rel=0.1)
    res = pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind-histogram", payload="x", passphrase=PHRASE, strength=0.1))
    assert res.strength == 0.1
    assert pmwm.verify(res.vertices, res.faces, passphrase=PHRASE).payload == "x"


@pytest.mark.slow
def test_a_plane_crop_reads_in_the_frame_of_the_cropped_copy(bunny, marked):
    """A 10 % plane crop moves the centroid by 5-20 bin widths: the own and refined frames lose the mark
    (no crop was read before the crop search). The crop search finds the frame from the cut (measured
    on the benchmark models: about 3 crops in 4), with p still below 1e-6; a wrong pass phrase or an
    unmarked cropped copy is never marked, and no wrong payload is ever reported."""
    read = 0
    for seed in range(6):
        V, F = A.crop_plane(marked.vertices, marked.faces, fraction=0.1, seed=seed)
        stats = blind.bin_statistics(V, F)
        assert not blind.decide(stats.own_frame(), SECRET).marked
        v = blind.decide(stats, SECRET)
        assert not v.marked or (v.payload == "Acme" and v.detail.frame.startswith("crop") and v.p_value < 1e-6)
        assert stats.frame_names == ("own", "crop", "crop-2", "crop-1", "crop+1", "crop+2")
        assert v.detail.chase_bits == 8
        read += v.marked
        assert not blind.decide(stats, word.derive_secret(PHRASE + "!")).marked
    assert read >= 4
    V, F = A.crop_plane(*bunny, fraction=0.1, seed=0)
    assert not pmwm.verify(V, F, passphrase=PHRASE).marked


@pytest.mark.slow
def test_a_stray_part_far_from_a_cropped_copy_leaves_its_reading_alone(marked):
    """A crop with a tiny triangle a million model sizes away (a stray part in a scan) is read in the same
    crop frame as without it: the crop search leaves out what no frame it tries reaches. Its histograms
    and FFTs would otherwise stretch to that distance (tens of GB for the candidates' counts)."""
    V, F = A.crop_plane(marked.vertices, marked.faces, fraction=0.1, seed=0)
    size = float(np.ptp(V, axis=0).max())
    far = V.mean(0) + np.array([1e6 * size, 0.0, 0.0])
    tri = far + 1e-7 * size * np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    Vs, Fs = np.vstack([V, tri]), np.vstack([F, len(V) + np.array([[0, 1, 2]])])
    want, got = pmwm.verify(V, F, passphrase=PHRASE), pmwm.verify(Vs, Fs, passphrase=PHRASE)
    assert want.marked and want.payload == "Acme" and want.detail.frame.startswith("crop")
    assert got.marked and got.payload == "Acme" and got.detail.frame == want.detail.frame
    assert got.p_value == pytest.approx(want.p_value, rel=1e-6)


@pytest.mark.slow
def test_a_cropped_copy_is_not_read_after_its_border_blew_up(marked):
    """Steps of smoothing undone amplify what smoothing never damped, a crop's zigzag border first (1.2
    times per step): past the count a smoothed copy needs, the mesh grows without bound and its own frame
    shows a large energy that is not the mark's. The reader stops where the bounding box has grown by 10 %
    (``UnsmoothConfig.growth``), so these crops of the bunny (20 % and 30 %, each read before after 75-84
    steps back, the bunny blown up) keep their crop frames."""
    for fraction, seed in ((0.2, 6), (0.2, 7), (0.3, 1)):
        V, F = A.crop_plane(marked.vertices, marked.faces, fraction=fraction, seed=seed)
        stats = blind.bin_statistics(V, F)
        assert stats.mesh == "suspect" and stats.frame_names[:2] == ("own", "crop")


def test_an_asset_cut_flat_before_marking_is_read_without_the_crop_search(bunny):
    """An asset with a planar cut of its own (a bust's base), marked and read intact, re-ordered or with
    0.3 % noise, shows the mark in full in its own frame: read there, without the crop search (over a
    second otherwise), at the p-value of a suspect without a cut. Its crops are still searched (the test
    above)."""
    V, F = A.crop_plane(*bunny, fraction=0.1, seed=7)
    res = pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind-histogram", payload="Flat", passphrase=PHRASE, seed=5, progressive=False)
    )
    assert crop.cut_planes(res.vertices, F, res.vertices.mean(0))  # the asset has a planar cut
    for X, G in [
        (res.vertices, F),
        A.reorder(res.vertices, F, seed=1),
        A.noise_benchmark(res.vertices, F, amplitude=0.003, seed=2),
    ]:
        with calls_of(crop.crop_frames) as searched:
            v = pmwm.verify(X, G, passphrase=PHRASE)
        assert not searched  # the crop search did not run
        assert v.marked and v.payload == "Flat" and v.detail.chase_bits == 10 and v.p_value < 1e-6


@pytest.mark.slow
def test_a_crop_whose_lost_centre_lies_off_the_familys_plane_is_read(marked):
    """The centre a crop took away can lie a bin width or more off the plane of the family the search
    follows (the cap's centroid off the hole's axis), too far for the mark to show on the plane: the search
    also follows copies of the family ``CropConfig.layers`` bin widths off its plane. Two bunny crops whose
    lost centre lies more than a bin width off it are read; with the plane alone, neither is
    (docs/decisions/081-blind-crop-frame-search.md)."""
    fr0, _ = radial.frame_of(marked.vertices, marked.faces, 64)
    width = (fr0.hi - fr0.lo) / 64
    crops = [A.crop_plane(marked.vertices, marked.faces, fraction=0.1, seed=seed) for seed in (71, 78)]
    for V, F in crops:
        fr, _ = radial.frame_of(V, F, 64)
        ((h, n),) = crop.cut_planes(V, F, fr.centre)
        normal = np.cross(h - fr.centre, n)  # of the family's plane (through the centroid, h and n)
        assert abs((fr0.centre - fr.centre) @ normal) / np.linalg.norm(normal) > width
        v = pmwm.verify(V, F, passphrase=PHRASE)
        assert v.marked and v.payload == "Acme" and v.detail.frame.startswith("crop")
    plane_alone = replace(READER, crop=replace(READER.crop, layers=(0.0,)))
    assert not any(blind.verify(V, F, PHRASE, config=plane_alone).payload == "Acme" for V, F in crops)


@pytest.mark.slow
def test_a_30_percent_crop_whose_lost_centre_lies_far_off_the_familys_plane_is_read(marked):
    """A 30 % crop can leave the lost centre several bin widths off the family's plane (up to 5 on the
    benchmark models): the search follows copies of the family up to 3.6 bin widths either side. Two
    posed 30 % crops of the bunny whose lost centre lies more than 1.8 bin widths off the plane are read
    with the whole payload; with copies up to 1.8 bin widths (the former search), neither is."""
    crops = []
    for seed in (1, 11):
        Vs, Fs = A.similarity(marked.vertices, marked.faces, seed=seed)
        fr0, _ = radial.frame_of(Vs, Fs, 64)  # the marked mesh's frame, posed
        V, F = A.crop_plane(Vs, Fs, fraction=0.3, seed=seed)
        fr, _ = radial.frame_of(V, F, 64)
        ((h, n),) = crop.cut_planes(V, F, fr.centre)
        normal = np.cross(h - fr.centre, n)
        off = abs((fr0.centre - fr.centre) @ normal) / np.linalg.norm(normal)
        assert off > 1.8 * (fr.hi - fr.lo) / 64
        v = pmwm.verify(V, F, passphrase=PHRASE)
        assert v.marked and v.payload == "Acme" and v.detail.frame.startswith("crop") and v.p_value < 1e-6
        crops.append((V, F))
    nearer = replace(READER, crop=replace(READER.crop, layers=(-1.8, -0.9, 0.0, 0.9, 1.8)))
    assert not any(blind.verify(V, F, PHRASE, config=nearer).payload == "Acme" for V, F in crops)


@pytest.mark.slow
def test_a_frame_found_for_one_length_is_read_at_the_length_of_most_energy(marked):
    """The search for the longer word can find the shorter mark's own bins (lo and bin width): read with
    the longer word's count, those bins hold the mark and the bins beyond it, so the frame is read at
    every length and the length of most excess energy wins (``frames.best_length``). Here the search for 96
    bins is given the 64-bin mark's frame (the frame its own search found, extended to 96 bins) and the search
    for 64 bins a frame that holds no mark: the payload is still read, at 64 bins (each length read in its own
    frame read 96 bins there, and nothing)."""
    V, F = A.crop_plane(marked.vertices, marked.faces, fraction=0.1, seed=1)
    assert pmwm.verify(V, F, passphrase=PHRASE).payload == "Acme"
    area = vertex_areas(V, F)
    own, a = radial.frame_of_areas(V, area, 1)
    counts = [L + word.CHECK_BITS for L in word.PAYLOAD_BITS]
    g = crop.crop_frames(V, a, area, own, crop.cut_planes(V, F, own.centre), [64, 96])[0]  # the 64-bin mark's
    assert g.n_bins == 64
    swapped = [
        radial.Frame(own.centre + 40 * g.width, own.lo, own.hi, 64),
        radial.Frame(g.centre, g.lo, g.lo + 96 * g.width, 96),
    ]
    _, j, f = frames.best_length(V, a, swapped, counts, [0, 1])
    assert counts[j] == 64 and f.n_bins == 64
    stat, share = radial.statistics_in(V, a, f, [64])[0]
    v = blind.decide(blind.Statistics({64: stat[None]}, 64, ("crop",), ("crop",), {64: share[None]}), SECRET)
    assert v.marked and v.payload == "Acme"


@pytest.fixture(scope="module")
def small_marked(bunny):
    """The bunny simplified to 13,935 vertices (about the Venus head's count), marked."""
    V, F = A.simplify(*bunny, ratio=0.6)
    return pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind-histogram", payload="Acme", passphrase=PHRASE, seed=3, progressive=False)
    )


@pytest.mark.parametrize("scheme", ["loop", "sqrt3", "catmull-clark"])
@pytest.mark.slow
def test_a_subdivided_copy_is_read_on_the_coarse_mesh_under_it(small_marked, scheme):
    """One step of Loop, sqrt(3) or Catmull-Clark subdivision (and a new order) smooths a mesh this small
    so much that its own reading loses the payload; the coarse mesh solved from the new vertices reads
    it."""
    V, F = A.reorder(*A.subdivide(small_marked.vertices, small_marked.faces, scheme), seed=2)
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.detail.mesh == scheme and v.p_value < 1e-6
    # (a Loop copy reads with smoothing undone too)
    v = blind.verify(V, F, PHRASE, config=READER.without("coarse", "unsmoothed"))
    assert not (v.marked and v.payload == "Acme") and v.detail.mesh == "suspect"


@pytest.mark.slow
def test_two_steps_of_subdivision_are_undone_one_at_a_time(small_marked):
    V, F = A.subdivide(*A.subdivide(small_marked.vertices, small_marked.faces, "sqrt3"), "loop")
    v = pmwm.verify(*A.reorder(V, F, seed=1), passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.detail.mesh == "sqrt3 + loop"


@pytest.mark.slow
def test_an_interpolating_subdivision_is_read_on_the_original_vertices_it_kept(small_marked):
    """A 1-to-4 step that keeps the original vertices where they are and puts the new ones off the
    edges' midpoints (as butterfly does): solved as Loop's (the better fit of the two rules), the coarse
    mesh is smoothed; the original vertices as the copy has them read the payload."""
    M, MF = small_marked.vertices, small_marked.faces
    V, F = A.subdivide(M, MF, "midpoint")
    n0, c = len(M), M.mean(0)
    out = V[n0:] - c
    edge = np.mean(np.linalg.norm(M[MF[:, 1]] - M[MF[:, 0]], axis=1))
    V[n0:] += 0.2 * edge * out / np.linalg.norm(out, axis=1)[:, None]
    assert frames.coarse_mesh(V, F).rule == "loop"
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.detail.mesh == "1-to-4"


@pytest.mark.parametrize("scheme", ["loop", "catmull-clark"])
@pytest.mark.parametrize("attack", [None, lambda v, f: A.quantize(v, f, bits=7)], ids=["intact", "quantize7"])
@pytest.mark.slow
def test_a_subdivided_mesh_marked_as_it_is_is_read_as_it_is(bunny, attack, scheme):
    """A mesh that is itself a subdivision (a modeller's output), marked: the mark is on every vertex,
    so the suspect, not the coarse mesh under it, shows it (intact: in full view, no coarse mesh looked
    for; quantized to 7 bits: its coarse mesh, solved or as it is, shows no more energy per vertex, far
    from the factor ``ReaderConfig.coarse_gain`` that a subdivided copy's shows; the suspect is read, as it is or a few
    steps smoothed)."""
    V, F = A.subdivide(*A.simplify(*bunny, ratio=0.8), scheme)
    res = pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind-histogram", payload="Acme", passphrase=PHRASE, seed=4, progressive=False)
    )
    S = (res.vertices, res.faces) if attack is None else attack(res.vertices, res.faces)
    own = frames.read_statistics_frames(*S, [L + word.CHECK_BITS for L in word.PAYLOAD_BITS])
    assert (own.energy >= READER.full_view) == (attack is None)
    assert frames.coarse_mesh(*S).rule == scheme  # the structure is there either way
    v = pmwm.verify(*S, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.detail.mesh in ("suspect", f"smoothing:-{READER.denoise.steps}")


def test_cut_planes_find_the_plane_of_a_crop():
    V, F = meshes.blob()
    assert crop.cut_planes(V, F, V.mean(0)) == []  # closed: nothing was cut
    Vc, Fc = A.crop_plane(V, F, fraction=0.2, seed=7)
    d = np.random.default_rng(7).standard_normal(3)  # crop_plane's direction for this seed
    d /= np.linalg.norm(d)
    planes = crop.cut_planes(Vc, Fc, Vc.mean(0))
    assert len(planes) == 1
    h, n = planes[0]
    assert n @ d > 0.99  # pointing away from what is left, towards what was cut
    assert abs(h @ d - (Vc @ d).max()) < 0.02 * np.ptp(V @ d)  # on the cut


def test_weighted_quantiles_of_many_rows():
    """The smallest value whose cumulative weight reaches q of the total, per row, also where the lowest
    values of a row weigh nothing."""
    rng = np.random.default_rng(1)
    rho, w, q = rng.random((3, 500)), rng.random(500), np.array([[0.02], [0.05], [0.3]])
    w[np.argsort(rho[0])[:100]] = 1e-9  # the lowest values of row 0 weigh nothing
    got = radial.weighted_quantiles(rho, w, q)[:, 0]
    for b in range(3):
        order = np.argsort(rho[b])
        cw = np.cumsum(w[order])
        assert got[b] == rho[b][order][np.flatnonzero(cw >= q[b, 0] * w.sum())[0]]
    assert radial.weighted_quantiles(rho[:1], w, [[0.0, 1.0]])[0].tolist() == [rho[0].min(), rho[0].max()]


@pytest.mark.parametrize(
    "end, quantiles, seed", [("low", (0.0, 0.01, 0.02, 0.05, 0.3), 2), ("high", (1.0, 0.99, 0.98, 0.95, 0.7), 3)]
)
@pytest.mark.slow
def test_a_quantile_from_the_values_at_one_end_equals_the_one_from_all(end, quantiles, seed):
    """``low_quantile`` sorts only the smallest values, ``high_quantile`` only the largest (a frame's ends,
    on every frame the reader measures): the same value as ``weighted_quantiles``, with ties (also across
    the values sorted and those not), weightless values, and a quantile the values at that end cannot hold
    (all are then sorted)."""
    quantile = radial.low_quantile if end == "low" else radial.high_quantile
    rng = np.random.default_rng(seed)
    for trial in range(300):
        n = int(rng.integers(1, 20000))
        x = rng.random(n)
        if trial % 2:
            x = np.round(x * rng.integers(1, 300))  # many ties
        w = rng.random(n) * (rng.random(n) < 0.8)
        if trial % 7 == 0:  # the half at that end weighs nothing: the full sort is needed
            w[np.argsort(x)[: n // 2] if end == "low" else np.argsort(x)[n // 2 :]] = 0.0
        if not w.sum() > 0:
            continue
        q = float(rng.choice(quantiles))
        assert quantile(x, w, q) == radial.weighted_quantiles(x[None], w, [q])[0, 0]


def test_scale_energies_match_the_energy_of_each_frame():
    """The cumulative-histogram energies equal a direct binning wherever the bins' edges fall on cells."""
    rng = np.random.default_rng(0)
    V = rng.normal(size=(3000, 3))
    a = (rng.random(3000) > 0.1).astype(float)
    centres = rng.normal(size=(2, 3)) * 0.1
    rho = np.linalg.norm(V[None] - centres[:, None], axis=2)
    lo, widths, phases = np.array([0.25, 0.5]), np.array([0.03125, 0.0625]), np.array([0.0, 0.5])
    got = radial.scale_energies(rho, a, lo, widths, phases, 32)
    for b, w, p in np.ndindex(2, 2, 2):
        start = lo[b] + phases[p] * widths[w]
        want = radial.energies(V, a, centres[b][None], np.array([start]), np.array([start + 32 * widths[w]]), 32)
        assert got[b, w, p] == pytest.approx(want[0], rel=1e-9)


def test_radii_in_phase_find_the_width_of_evenly_spaced_radii():
    """``radial.in_phase`` gives, per row of distances, the width at which they add up in phase, within
    its band, and the power |sum exp(2 pi i rho / w)|^2 there: radii bunched every 0.013 (a jitter of a
    tenth of that) read 0.013 to within 0.2 % and nearly n^2; uniform radii nothing near it."""
    rng = np.random.default_rng(5)
    n, w0 = 20000, 0.013
    bunched = 0.4 + w0 * (rng.integers(0, 200, n) + 0.1 * rng.standard_normal(n))
    uniform = rng.uniform(0.4, 0.4 + 200 * w0, n)
    power, width = radial.in_phase(np.stack([bunched, uniform]), 0.6 * w0 / 16, 0.6 * w0, 1.6 * w0, 8)
    assert width[0] == pytest.approx(w0, rel=2e-3)
    assert 0.7 < np.sqrt(power[0]) / n <= 1.0  # (a jitter of w0 / 10 keeps exp(-2 pi^2 / 100) = 0.82)
    assert np.sqrt(power[1]) / n < 0.05


def test_a_marked_meshs_radii_add_up_in_phase_at_its_bin_width(bunny, marked):
    """What the crop search's screening and width fit rely on: whatever the word, the push makes a
    marked mesh's radii from its centre add up in phase at its bin width (the bins' cos(2 pi r) rises
    for bits 0 and 1 alike), far above an unmarked mesh's; and a centre a few bin widths off shows
    much less of it."""
    M = 64
    fr, _ = radial.frame_of(marked.vertices, marked.faces, M)
    w = (fr.hi - fr.lo) / M

    def phase(V, centre):
        rho = np.linalg.norm(V - centre, axis=1)[None]
        power, width = radial.in_phase(rho, 0.6 * w / 16, 0.6 * w, 1.6 * w, 8)
        return np.sqrt(power[0]) / len(V), width[0]

    z, width = phase(marked.vertices, fr.centre)
    assert width == pytest.approx(w, rel=5e-3) and z > 0.08
    assert phase(bunny[0], fr.centre)[0] < 0.25 * z  # the same mesh unmarked
    assert phase(marked.vertices, fr.centre + np.array([3 * w, 0.0, 0.0]))[0] < 0.5 * z


def test_distances_to_many_centres_are_exact_in_the_callers_precision():
    """``radial.distances`` (every search's distances, without a matrix product) gives each point's
    distance to each centre, rows by centre, in float64 to rounding and in float32 (the screening's)
    to a few parts in 10 million of the distance."""
    rng = np.random.default_rng(5)
    P, C = rng.normal(size=(500, 3)) * 40, rng.normal(size=(7, 3))
    want = np.linalg.norm(P[None] - C[:, None], axis=2)
    got = radial.distances(P, C)
    assert got.shape == (7, 500) and got.dtype == np.float64
    np.testing.assert_allclose(got, want, rtol=1e-14)
    got32 = radial.distances(P.astype(np.float32), C.astype(np.float32))
    assert got32.dtype == np.float32
    np.testing.assert_allclose(got32, want, rtol=5e-7, atol=1e-5)


def test_crop_search_scores_are_the_energy_of_the_best_frame():
    """Each candidate centre's coarse score is the largest energy of the frames it tries, lo the cell of
    the area quantile 2 % / (1 - lam): equal to a direct binning where the bins' edges fall on cells."""
    rng = np.random.default_rng(2)
    P = rng.normal(size=(3000, 3))
    area = rng.random(3000)
    C, lam = rng.normal(size=(3, 3)) * 0.1, np.array([0.0, 0.2, 0.35])
    width, n_bins, cells = 0.04, 32, 16
    # each candidate's own widths, edges on cells of width / 16 (the smallest of the batch)
    widths, phases = width * np.array([[1.0, 1.5], [1.25, 2.0], [1.75, 1.0]]), np.array([0.0, 0.25, 0.5])
    got = crop._coarse(P, area, C, lam, widths, n_bins, phases, cells)
    cell = width / cells
    for b in range(3):
        rho = np.linalg.norm(P - C[b], axis=1)
        q = radial.weighted_quantiles(rho[None], area, [[radial.QUANTILES[0] / (1 - lam[b])]])[0, 0]
        lo = rho.min() + np.floor((q - rho.min()) / cell) * cell
        want = max(
            radial.energies(
                P, np.ones(3000), C[b][None], np.array([lo + p * w]), np.array([lo + (p + n_bins) * w]), n_bins
            )[0]
            for w in widths[b]
            for p in phases
        )
        assert got[b] == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize("ext", [".obj", ".ply", ".stl", ".glb"])
def test_whole_payload_survives_re_export(marked, tmp_path, ext):
    path = tmp_path / f"copy{ext}"
    write_mesh(str(path), marked.vertices, marked.faces)
    m = read_mesh(str(path))
    v = pmwm.verify(m.vertices, m.faces, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme"


def test_one_pass_phrase_many_meshes_each_its_own_payload(bunny):
    v, f = bunny
    copies = {}
    for name, (V, F) in {"bunny": (v, f), "cap": meshes.open_cap()}.items():
        res = pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind-histogram", passphrase=PHRASE, n_bits=32))
        copies[name] = res
    payloads = {n: "".join(map(str, r.bits.tolist())) for n, r in copies.items()}
    assert payloads["bunny"] != payloads["cap"]  # a fresh random payload per mesh
    for name, res in copies.items():
        got = pmwm.verify(res.vertices, res.faces, passphrase=PHRASE)
        assert got.marked and got.bits == payloads[name] and got.detail.payload_kind == "bits"


@pytest.mark.parametrize("n", word.PAYLOAD_BITS[:3])
@pytest.mark.slow
def test_explicit_bits_of_every_length_read_back_or_are_refused(bunny, n):
    """Never silently unreadable: an embed returns a mark that reads back, or refuses in one line (the
    shortest payload is always accepted on the bunny)."""
    bits = bitstring(n, n)
    try:
        res = pmwm.embed(
            *bunny, pmwm.EmbedOptions(scheme="blind-histogram", bits=bits, passphrase=PHRASE, base_ratio=0.5)
        )
    except PayloadError as exc:
        assert n > word.PAYLOAD_BITS[0] and "does not read back" in str(exc) and "\n" not in str(exc)
        return
    got = pmwm.verify(res.vertices, res.faces, passphrase=PHRASE)
    assert got.marked and got.bits == bits and got.payload is None


@pytest.mark.slow
def test_false_positive_rate_is_at_most_alpha():
    """Unmarked meshes and wrong pass phrases: the p-value is a valid one (P(p <= a) <= a)."""
    shapes = [meshes.blob(), meshes.cad_part(), meshes.pinched_torus()]
    rng = np.random.default_rng(11)
    ps = []
    for i in range(150):
        V, F = shapes[i % len(shapes)]
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        ps.append(pmwm.verify(V @ R.T * rng.uniform(0.5, 2), F, passphrase=f"wrong {i}").p_value)
    ps = np.array(ps)
    assert not np.any(ps < 1e-6)
    assert np.mean(ps <= 0.1) <= 0.1 + 3 * np.sqrt(0.1 * 0.9 / len(ps))


def test_progressive_mesh_full_level_reads(marked):
    got = pmwm.verify_pm(marked.pm, passphrase=PHRASE)
    assert got.marked and got.payload == "Acme"


def test_bad_input_gives_one_clear_error(bunny):
    v, f = bunny
    with pytest.raises(PayloadError, match="pass phrase"):
        pmwm.embed(v, f, pmwm.EmbedOptions(scheme="blind-histogram", payload="x"))
    with pytest.raises(PayloadError, match="pass phrase"):
        pmwm.embed(v, f, pmwm.EmbedOptions(scheme="blind-histogram", payload="x", passphrase=""))
    with pytest.raises(PayloadError, match="at most 28 bytes"):
        pmwm.embed(v, f, pmwm.EmbedOptions(scheme="blind-histogram", payload="x" * 30, passphrase=PHRASE))
    with pytest.raises(PayloadError, match="32, 64, 96, 224"):
        pmwm.embed(v, f, pmwm.EmbedOptions(scheme="blind-histogram", bits="0101", passphrase=PHRASE))
    with pytest.raises(PayloadError, match="below 0.5"):
        pmwm.embed(v, f, pmwm.EmbedOptions(scheme="blind-histogram", payload="x", passphrase=PHRASE, strength=0.6))
    with pytest.raises(MeshError):
        pmwm.verify(np.zeros((3, 3)), np.array([[0, 1, 2]]), passphrase=PHRASE)


# --------------------------------------------------------------------------- command line


def run(*args, env=None, cwd=None):
    full = dict(os.environ, PYTHONPATH=str(Path(pmwm.__file__).parent.parent))
    full.pop("PMWM_PASSPHRASE", None)
    full.update(env or {})
    return subprocess.run(
        [sys.executable, "-m", "pmwm", *map(str, args)], capture_output=True, text=True, env=full, cwd=cwd, timeout=300
    )


@pytest.mark.slow
def test_cli_embed_and_verify_with_a_pass_phrase_file_write_no_key(tmp_path):
    src = tmp_path / "cap.off"
    meshes.write_off(src, *meshes.open_cap())
    phrase = tmp_path / "phrase.txt"
    phrase.write_text("a long secret phrase\n")
    out = tmp_path / "marked.ply"
    p = run(
        "embed",
        src,
        "-o",
        out,
        "--scheme",
        "blind",
        "--passphrase-file",
        phrase,
        "--payload",
        "Studio X",
        "--pm",
        tmp_path / "m.pmwm",
    )
    assert p.returncode == 0, p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["cap.off", "m.pmwm", "marked.ply", "phrase.txt"]
    assert "a long secret phrase" not in p.stdout + p.stderr
    v = run("verify", out, "--passphrase-file", phrase)
    assert v.returncode == 0 and "MARKED" in v.stdout and "'Studio X'" in v.stdout
    assert "a long secret phrase" not in v.stdout + v.stderr
    env = run("verify", out, "--json", env={"PMWM_PASSPHRASE": "a long secret phrase"})
    assert env.returncode == 0 and '"payload": "Studio X"' in env.stdout
    wrong = run("verify", out, env={"PMWM_PASSPHRASE": "another phrase"})
    assert wrong.returncode == 1 and "not marked" in wrong.stdout


@pytest.mark.slow
def test_cli_errors(tmp_path):
    src = tmp_path / "blob.off"
    meshes.write_off(src, *meshes.blob())
    p = run("embed", src, "-o", tmp_path / "m.ply", "--scheme", "blind")
    assert p.returncode == 2 and "pass phrase" in p.stderr and "Traceback" not in p.stderr
    p = run(
        "embed",
        src,
        "-o",
        tmp_path / "m.ply",
        "--scheme",
        "blind",
        "--key",
        tmp_path / "k.json",
        env={"PMWM_PASSPHRASE": "x"},
    )
    assert p.returncode == 2 and "omit --key" in p.stderr
    p = run("embed", src, "-o", tmp_path / "m.ply")
    assert p.returncode == 2 and "--key" in p.stderr
    p = run("verify", src)
    assert p.returncode == 2 and "pass phrase" in p.stderr
    p = run("verify", src, "--passphrase-file", tmp_path / "missing.txt")
    assert p.returncode == 2 and "pass-phrase file" in p.stderr


def test_bench_method_reads_its_bits(bunny):
    from pmwm_bench.methods import SchemeMethod

    method = SchemeMethod("pmwm-blind")
    bits = np.random.default_rng(9).integers(0, 2, 32)
    marked, key = method.embed(*bunny, bits, seed=4)
    assert method.extract(*A.reorder(marked, bunny[1], seed=1), key) == "".join(map(str, bits))


def test_equalizing_the_radial_neighbours_reads_what_the_plain_reading_loses(marked):
    """Noise of 0.95 % spills each bin's pushed vertices into its radial neighbours: read bin by bin,
    more bits come out wrong than the search can correct; with the neighbours' interference removed
    (``radial.equalized``, no pass phrase involved) the whole payload reads, p < 1e-6."""
    V, F = A.noise_benchmark(marked.vertices, marked.faces, 0.0095, seed=0)
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.p_value < 1e-6
    # (the suspect's own frames alone: no denoised frames)
    plain = blind.verify(V, F, PHRASE, config=replace(READER.without("denoised"), equalize=False))
    assert not (plain.marked and plain.payload == "Acme")


@pytest.mark.parametrize("copy", ["bunny quantized to 7 bits", "14,000 vertices, 0.95 % noise"])
def test_a_noisy_copy_is_read_after_a_few_steps_of_smoothing(marked, small_marked, copy):
    """7-bit quantization of the bunny and 0.95 % noise of a 14,000-vertex copy move every vertex by a good
    part of a bin: read as they are, the bins lose the payload; after a few steps of Laplacian smoothing
    (``frames.with_denoised``, key-free) the "denoised" frames read it, p < 1e-6 with their frames counted
    in the union bound."""
    if copy.startswith("bunny"):
        V, F = A.quantize(marked.vertices, marked.faces, bits=7)
    else:
        V, F = A.noise_benchmark(small_marked.vertices, small_marked.faces, 0.0095, seed=3)
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.detail.frame.startswith("denoised")
    assert v.detail.mesh == f"smoothing:-{READER.denoise.steps}"
    assert blind.mesh_read(v.detail.mesh) == "read after 3 steps of Laplacian smoothing (0.1 each) against noise"
    assert v.detail.frames in (2, 3, 4) and v.detail.chase_bits == plan.chase_bits(v.detail.frames)
    assert v.p_value == pytest.approx(plan.histogram_p_value(v.detail.frames * 2 * 2.0**v.detail.chase_bits * 2.0**-32))
    assert v.p_value < 1e-6
    plain = blind.verify(V, F, PHRASE, config=READER.without("denoised", "reserve"))  # (the same frames)
    assert not (plain.marked and plain.payload == "Acme")


@pytest.mark.parametrize("case", [3, 29, 34])
@pytest.mark.slow
def test_a_noisy_copy_is_read_in_a_denoised_frame_searched_on_every_vertex(bunny, case):
    """The bundled bunny marked at the fixed margin DEFAULT_ALPHA (weaker than the calibrated default), then
    0.5 % noise: read in its "denoised" frames refined on all of its 34,835 vertices
    (``DenoiseConfig.refine_sample``), the whole payload; refined on the 17,418 of the other frames'
    sample (``radial.REFINE_SAMPLE``), not: its bins are blurred, and the sample's own noise moves the
    frame off the mark."""
    v, f = bunny
    phrase = f"case {case}"
    res = pmwm.embed(
        v,
        f,
        pmwm.EmbedOptions(
            scheme="blind-histogram",
            passphrase=phrase,
            payload="studio",
            seed=case,
            strength=blind.DEFAULT_ALPHA,
            progressive=False,
        ),
    )
    V, F = A.noise_benchmark(res.vertices, f, amplitude=0.005, seed=case)
    got = pmwm.verify(V, F, passphrase=phrase)
    assert got.marked and got.payload == "studio" and got.detail.frame == "denoised-refined"
    sampled = blind.verify(
        V, F, phrase, config=replace(READER, denoise=replace(READER.denoise, refine_sample=radial.REFINE_SAMPLE))
    )
    assert not (sampled.marked and sampled.payload == "studio")


def _errors(bits: np.ndarray, want: np.ndarray) -> int:
    return int(np.sum(bits != want))


@pytest.mark.slow
def test_a_copy_on_a_coarse_grid_not_read_is_guessed_in_its_smoothed_copy(bunny):
    """The bundled bunny marked at the fixed margin DEFAULT_ALPHA, then quantized to 7 bits: no whole payload
    is read, and the verdict's guess (chosen without the pass phrase) comes from the copy smoothed by the count
    of steps that shows the most mark energy (``frames.guess_statistics``). Over three phrases it errs on fewer
    bits of the word written than the hard decisions of the copy as it is, which are the guess without the
    smoothing (``DenoiseConfig.guess_steps`` emptied)."""
    v, f = bunny
    smoothed_errors, plain_errors = 0, 0
    for case in (3, 5, 6):
        phrase = f"guess test {case}"
        res = pmwm.embed(
            v,
            f,
            pmwm.EmbedOptions(
                scheme="blind-histogram",
                payload="Acme",
                passphrase=phrase,
                seed=case,
                strength=blind.DEFAULT_ALPHA,
                progressive=False,
            ),
        )
        secret = word.derive_secret(phrase)
        want = word.word_of(secret, "text", word.payload_of("Acme", None, 0, None)[0])
        V, F = A.quantize(res.vertices, f, bits=7)
        assert frames.on_grid(V) and not frames.on_grid(res.vertices)
        assert not pmwm.verify(V, F, passphrase=phrase).marked
        guess, mesh = blind.guess_word(blind.bin_statistics(V, F), secret)
        assert mesh.startswith("smoothing:-")
        smoothed_errors += _errors(guess, want)
        no_steps = replace(READER, denoise=replace(READER.denoise, guess_steps=()))
        plain, plain_mesh = blind.guess_word(blind.bin_statistics(V, F, no_steps), secret)
        assert plain_mesh == "suspect"
        plain_errors += _errors(plain, want)
    assert smoothed_errors < plain_errors


@pytest.mark.slow
def test_cli_prints_no_payload_bits_when_it_reads_no_mark(bunny, tmp_path):
    """``pmwm verify`` of a copy on a coarse grid that it cannot read: not marked (exit 1), "no payload read",
    and no payload bits at all (neither a candidate the check bits chose nor a guess), in words or in JSON."""
    v, f = bunny
    res = pmwm.embed(
        v,
        f,
        pmwm.EmbedOptions(
            scheme="blind-histogram",
            payload="Acme",
            passphrase="guess test 3",
            seed=3,
            strength=blind.DEFAULT_ALPHA,
            progressive=False,
        ),
    )
    path = meshes.write_off(tmp_path / "q7.off", *A.quantize(res.vertices, f, bits=7))
    got = run("verify", path, env={"PMWM_PASSPHRASE": "guess test 3"})
    assert got.returncode == 1 and got.stdout.splitlines()[0].startswith("not marked: ")
    assert got.stdout.splitlines()[-1] == "no payload read" and "payload bits" not in got.stdout
    assert not any(len(w) >= 32 and set(w) <= {"0", "1"} for w in got.stdout.split())
    js = json.loads(run("verify", path, "--json", env={"PMWM_PASSPHRASE": "guess test 3"}).stdout)
    assert (js["marked"], js["payload_confirmed"], js["bits"], js["payload"]) == (False, False, None, None)


def test_the_guess_is_the_own_frames_hard_decisions_and_never_in_a_verdict(bunny, marked):
    """A suspect off any grid that shows no mark is guessed in its own frame: the hard decisions of that
    frame (``word_read``), whatever the check bits matched; the verdict itself holds no word."""
    V, F = A.noise_benchmark(marked.vertices, marked.faces, amplitude=0.02, seed=1)
    assert not frames.on_grid(V)
    stats = blind.bin_statistics(V, F)
    v = blind.decide(stats, SECRET)
    assert not v.marked and v.bits == "" and v.detail.word is None
    guess, mesh = blind.guess_word(stats, SECRET)
    own, _ = blind.word_read(stats.words[stats.n_word][0], SECRET, stats.n_word, stats.shares[stats.n_word][0])
    assert mesh == stats.mesh and np.array_equal(guess, own)


def test_a_grid_is_coarse_at_12_bits_or_fewer_and_only_on_the_copys_own_axes(marked):
    """``frames.on_grid``: quantized to 12 bits or fewer per axis, yes; to 13 bits, as marked, or quantized and
    then rotated, no."""
    V, F = marked.vertices, marked.faces
    assert frames.on_grid(A.quantize(V, F, bits=7)[0]) and frames.on_grid(A.quantize(V, F, bits=12)[0])
    assert not frames.on_grid(A.quantize(V, F, bits=13)[0]) and not frames.on_grid(V)
    turned = A.quantize(V, F, bits=7)[0] @ np.array([[0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]])
    assert not frames.on_grid(turned)


def test_a_blurred_readings_denoised_frames_are_measured_in_a_worker_with_the_same_result(marked):
    """A copy whose bins show the blur (the bunny quantized to 7 bits) has its denoised frames measured in a
    worker thread beside the unsmoothing scan (``frames.denoised_frames``): the same statistics, frames and
    verdict as measured in the caller's thread, and no thread outlives the reading."""
    V, F = A.quantize(marked.vertices, marked.faces, bits=7)
    before = threading.active_count()
    with calls_of(frames.denoised_frames) as where:
        beside = blind.bin_statistics(V, F)
    assert threading.active_count() == before
    assert len(where) == 1 and where[0].startswith("pmwm-background")
    assert any(n.startswith("denoised") for n in beside.frame_names)
    with calls_of(frames.denoised_frames) as where:
        alone = blind.bin_statistics(V, F, replace(READER, workers=False))
    assert where == [threading.current_thread().name]
    assert alone.frame_names == beside.frame_names and alone.n_word == beside.n_word
    for n in alone.words:
        np.testing.assert_array_equal(alone.words[n], beside.words[n])
        np.testing.assert_array_equal(alone.shares[n], beside.shares[n])
    a, b = blind.decide(alone, SECRET), blind.decide(beside, SECRET)
    assert (a.marked, a.bits, a.p_value, a.detail.frame) == (b.marked, b.bits, b.p_value, b.detail.frame)
    assert a.marked and a.payload == "Acme"


def test_the_equalizer_recovers_signs_blurred_into_their_neighbours_and_leaves_clean_bins_alone():
    rng = np.random.default_rng(2)
    s = rng.choice([-1.0, 1.0], 64)
    nb = np.r_[0.0, s[:-1]] + np.r_[s[1:], 0.0]
    blurred = 0.035 * s - 0.014 * nb + rng.normal(0, 0.008, 64)  # a Venus head after 8-bit quantization
    assert np.sum(np.sign(blurred) != s) >= 5
    assert np.sum(np.sign(radial.equalized(blurred)) != s) == 0
    clean = 0.1 * s + rng.normal(0, 0.015, 64)  # no interference: returned as it is, NaN (empty) kept
    clean[3] = np.nan
    assert radial.equalized(clean) is clean


def _interfering(rng: np.random.Generator, s: np.ndarray) -> np.ndarray:
    """Bin statistics in standard errors as 8-bit quantization leaves the Venus head's (64 bins): each
    neighbour's sign pulls a bin the other way by 0.43 of its own, and the noise is half the mark."""
    nb = np.r_[0.0, s[:-1]] + np.r_[s[1:], 0.0]
    return 0.035 * s - 0.015 * nb + rng.normal(0, 0.019, len(s))


def test_the_equalizer_judges_the_interference_once_the_signs_have_settled():
    """A sixth of the hard decisions wrong hide most of the interference from a fit on them (c / g
    about -0.2 where it is -0.43): judged there, most of these readings were left as they were. Fitted
    again on the signs the model finds, until they settle, the equalizer removes it: about 7 % of the
    signs wrong against 12 % read as they are (9.4 % when judged on the hard decisions)."""
    wrong = raw = 0
    for seed in range(60):
        rng = np.random.default_rng(seed)
        s = rng.choice([-1.0, 1.0], 64)
        x = _interfering(rng, s)
        raw += int(np.sum(np.sign(x) != s))
        wrong += int(np.sum(np.sign(radial.equalized(x)) != s))
    assert raw > 0.11 * 60 * 64
    assert wrong < 0.082 * 60 * 64


def test_the_word_is_equalized_in_standard_errors():
    """The margins grow as 1 / sqrt(count) (``radial.bin_margins``), so in bin means the mark and its
    interference differ from bin to bin while in standard errors they are alike, as the equalizer's
    model has them: ``word_read`` equalizes the statistics times sqrt(share). With counts from 90 to
    1,000 over the bins, 7 % of the bits come out wrong (11 % when the bin means were equalized)."""
    secret = word.derive_secret(PHRASE)
    bit_of_bin, scramble = word.layout(secret, 64, 64)
    n = 300 * np.exp(1.2 * np.sin(np.linspace(0, 3 * np.pi, 64)))  # a smooth histogram
    share = n / n.sum()
    wrong = 0
    for seed in range(60):
        rng = np.random.default_rng(100 + seed)
        w = rng.integers(0, 2, 64).astype(np.uint8)
        s = np.where((w ^ scramble)[bit_of_bin] == 1, 1.0, -1.0)
        stat = np.sqrt(np.median(n) / n) * _interfering(rng, s)  # bin means: the margins' spread
        got, _ = blind.word_read(stat, secret, 64, share)
        wrong += int(np.sum(got != w))
    assert wrong < 0.09 * 60 * 64


def test_the_check_is_the_keyed_hash_a_marked_mesh_was_written_with():
    """The check bits are the first 32 bits of SHA-256(secret, kind, payload): a mesh marked before must
    stay readable, so the hash's input is fixed here byte for byte; many payloads at once give each
    one's check, and a different kind, secret or payload length a different one."""
    import hashlib

    secret = word.derive_secret(PHRASE)
    rng = np.random.default_rng(5)
    for L in word.PAYLOAD_BITS:
        P = rng.integers(0, 2, (7, L)).astype(np.uint8)
        many = word.check_bits(secret, "bits", P)
        assert many.shape == (7, word.CHECK_BITS) and many.dtype == np.uint8
        for row, got in zip(P, many):
            tag = hashlib.sha256(
                f"{secret}:blind-check:bits:".encode() + np.packbits(row).tobytes() + L.to_bytes(2, "little")
            ).digest()
            want = np.unpackbits(np.frombuffer(tag[:4], np.uint8))
            assert np.array_equal(got, want) and np.array_equal(word.check_bits(secret, "bits", row), want)
        assert not np.array_equal(word.check_bits(secret, "text", P), many)
        assert not np.array_equal(word.check_bits(word.derive_secret(PHRASE + "!"), "bits", P), many)
    assert not np.array_equal(
        word.check_bits(secret, "bits", np.zeros(32, np.uint8)), word.check_bits(secret, "bits", np.zeros(64, np.uint8))
    )


def test_the_equalizer_finds_the_most_likely_signs():
    import itertools

    rng = np.random.default_rng(0)
    for M in (2, 3, 6, 11):
        for _ in range(20):
            x, g = rng.normal(size=M), rng.uniform(0.1, 1.0)
            c = -rng.uniform(0.0, 0.5) * g

            def cost(s):
                s = np.array(s)
                return np.sum((x - g * s - c * (np.r_[0.0, s[:-1]] + np.r_[s[1:], 0.0])) ** 2)

            best = min(itertools.product([-1.0, 1.0], repeat=M), key=cost)
            assert np.array_equal(radial._most_likely_signs(x, g, c), np.array(best))


def test_a_blind_embedding_keeps_nothing_of_the_mesh_but_the_pass_phrase_reads_it():
    """No key at all: two different meshes marked with the same pass phrase and payload (one with its
    progressive mesh) return no key, and the pass phrase alone reads both marks."""
    for (V, F), pm in ((meshes.blob(), True), (meshes.cad_part(), False)):
        res = pmwm.embed(
            V,
            F,
            pmwm.EmbedOptions(
                scheme="blind-histogram", passphrase=PHRASE, payload="Acme", strength=0.1, progressive=pm
            ),
        )
        assert (res.pm is not None) == pm and res.key is None and res.strength == 0.1
        assert pmwm.verify(res.vertices, res.faces, passphrase=PHRASE).payload == "Acme"


def test_the_marking_search_finds_the_same_steps_whatever_its_guess():
    """The push's step per bin is searched from a guess (the bin mean is linear in the push): a right
    guess settles it at once, a wrong one (too high, too low, out of range) must still give the step
    the plain bisection gives, including 0 and 'none reaches' (j_max); one a few steps off settles in a few
    more readings (the steps from it double until they bracket the answer)."""
    rng = np.random.default_rng(3)
    M = 40
    j_max = rng.integers(0, 3000, M)
    least = rng.integers(0, 3400, M)  # beyond j_max: no step reaches the target
    reads = []

    def reached(j):
        reads.append(1)
        return j >= least

    reads.clear()
    want = radial._least_step(reached, j_max)
    plain = len(reads)
    assert np.array_equal(want, np.minimum(least, j_max))
    for guess in (
        np.minimum(least, j_max),
        least + rng.integers(1, 50, M),
        least - rng.integers(1, 50, M),
        rng.integers(-100, 4000, M),
        np.zeros(M, np.int64),
        j_max,
    ):
        assert np.array_equal(radial._least_step(reached, j_max, guess), want)
    reads.clear()
    radial._least_step(reached, j_max, np.minimum(least, j_max))
    assert len(reads) == 2 < plain  # a right guess: two readings
    for off in (1, -1, 5, -5):  # a guess a few steps off: a few readings more, not a bisection of the range
        reads.clear()
        assert np.array_equal(radial._least_step(reached, j_max, np.minimum(least, j_max) + off), want)
        assert len(reads) <= 8 < plain


def test_the_exponent_search_finds_the_exponents_of_the_plain_bisection():
    """Bins beyond the push's reach get Cho's exponent, searched from a Newton guess: the exponents must
    be those the plain bisection finds, for targets reached near k = 1, far from it, and out of reach."""
    rng = np.random.default_rng(11)
    M = 48
    b = rng.integers(-1, M, 20000)
    r = np.where(b >= 0, rng.random(len(b)) ** rng.uniform(0.5, 2.0, M)[np.maximum(b, 0)], 0.0)
    a = np.ones(len(b))
    one = rng.random(M) < 0.5
    gap = rng.uniform(0.02, 0.7, M)  # up to 0.7 from the middle: some targets outside (0, 1)
    targets = np.where(one, 0.5 + gap, 0.5 - gap)
    got = radial._solve_k(r, b, a, M, one, targets)
    j_max = np.where(
        one, int(np.floor((1.0 - radial.K_GRID) / radial.K_GRID)), int(round(50.0 / radial.K_GRID))
    ).astype(np.int64)
    bb = np.maximum(b, 0)
    means = radial.BinMeans(b, a, M)

    def k_of(j):
        return np.where(one, 1.0 - j * radial.K_GRID, 1.0 + j * radial.K_GRID)

    want = k_of(radial._least_step(lambda j: radial._meets(means, r ** k_of(j)[bb], one, targets), j_max))
    assert np.array_equal(got, want)
    assert np.sum(np.abs(want - 1.0) > 0.5) >= 5 and np.sum(want == k_of(j_max)) >= 3  # far and out of reach


def test_the_equalizer_reads_each_sign_with_its_neighbours_summed_out():
    """``radial._posterior_odds`` against every sign sequence of a short word: the log posterior odds of
    each bin's sign under the interference model, an empty bin's sign 0 (it spills nothing)."""
    import itertools

    rng = np.random.default_rng(4)
    for M in (2, 3, 7):
        for _ in range(10):
            g, c, var = rng.uniform(0.5, 1.0), -rng.uniform(0.0, 0.5), rng.uniform(0.05, 0.5)
            x = rng.normal(size=M)
            empty = rng.random(M) < 0.2
            free = np.flatnonzero(~empty)
            logp = {}
            for signs in itertools.product([-1.0, 1.0], repeat=len(free)):
                s = np.zeros(M)
                s[free] = signs
                nb = np.r_[0.0, s[:-1]] + np.r_[s[1:], 0.0]
                logp[signs] = -np.sum(((x - g * s - c * nb) ** 2)[~empty]) / (2 * var)
            want = np.zeros(M)
            for k, j in enumerate(free):
                plus = np.logaddexp.reduce([lp for sg, lp in logp.items() if sg[k] > 0])
                minus = np.logaddexp.reduce([lp for sg, lp in logp.items() if sg[k] < 0])
                want[j] = plus - minus
            assert np.allclose(radial._posterior_odds(x, empty, g, c, var), want, atol=1e-9)
    # without interference the equalizer's output is the statistic itself
    x = np.array([0.1, -0.05, 0.2, np.nan, -0.3])
    assert np.allclose(
        radial._posterior_odds(np.nan_to_num(x), np.isnan(x), 0.7, 0.0, 0.04) * 0.04 / 1.4, np.nan_to_num(x)
    )


def test_crop_candidates_keep_the_first_point_of_each_lattice_cell():
    """``crop._spread`` keeps, in ascending order, exactly the first point (in input order) of every
    occupied lattice cell (cells centred on the lattice points, negative coordinates included), and
    nothing of an empty set."""
    rng = np.random.default_rng(5)
    D = rng.normal(size=(2000, 3)) * 3.0 - 1.0
    spacing = 0.9
    got = crop._spread(D, spacing)
    cells = [tuple(c) for c in np.round(D / spacing).astype(np.int64).tolist()]
    first: dict = {}
    for i, c in enumerate(cells):
        first.setdefault(c, i)
    assert got.tolist() == sorted(first.values())
    assert crop._spread(np.zeros((0, 3)), spacing).tolist() == []


@pytest.mark.slow
def test_cli_says_when_it_read_the_mesh_under_a_subdivided_copy(small_marked, tmp_path):
    path = meshes.write_off(tmp_path / "loop.off", *A.subdivide(small_marked.vertices, small_marked.faces, "loop"))
    v = run("verify", path, env={"PMWM_PASSPHRASE": PHRASE})
    assert v.returncode == 0 and "MARKED" in v.stdout and "'Acme'" in v.stdout
    assert "read on the mesh it was subdivided from: loop undone" in v.stdout
    plain = run(
        "verify",
        meshes.write_off(tmp_path / "m.off", small_marked.vertices, small_marked.faces),
        env={"PMWM_PASSPHRASE": PHRASE},
    )
    assert plain.returncode == 0 and "'Acme'" in plain.stdout and "subdivision" not in plain.stdout


@pytest.mark.parametrize(
    "lam,iterations", [(0.1, 30), (0.1, 50), (0.25, 6)], ids=["30x0.1", "50x0.1", "Blender-Smooth-0.5x6"]
)
@pytest.mark.slow
def test_a_smoothed_copy_is_read_with_its_smoothing_undone(marked, lam, iterations):
    """Uniform Laplacian smoothing (the benchmark's, lambda 0.1, and Blender's Smooth modifier, lambda =
    factor / 2) blurs the radii beyond reading, but leaves the mark in the copy; the reader takes the
    smoothing back step by step (``frames.unsmoothing``, key-free) and reads the payload."""
    V, F = A.smooth_laplacian(marked.vertices, marked.faces, lam=lam, iterations=iterations)
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert v.marked and v.payload == "Acme" and v.p_value < 1e-6
    steps = int(v.detail.mesh.split("smoothing:")[1])
    assert lam * iterations <= 0.1 * steps <= 1.5 * lam * iterations
    plain = blind.verify(V, F, PHRASE, config=READER.without("unsmoothed"))
    assert not (plain.marked and plain.payload == "Acme")


def test_an_unmarked_smoothed_mesh_stays_unmarked(bunny):
    V, F = A.smooth_laplacian(*bunny, lam=0.1, iterations=30)
    v = pmwm.verify(V, F, passphrase=PHRASE)
    assert not v.marked and v.detail.mesh == "suspect"


@pytest.mark.slow
def test_cli_says_when_it_read_a_smoothed_copy_with_its_smoothing_undone(marked, tmp_path):
    path = meshes.write_off(
        tmp_path / "smooth.off", *A.smooth_laplacian(marked.vertices, marked.faces, lam=0.1, iterations=30)
    )
    v = run("verify", path, env={"PMWM_PASSPHRASE": PHRASE})
    assert v.returncode == 0 and "MARKED" in v.stdout and "'Acme'" in v.stdout
    assert "steps of Laplacian smoothing (0.1 each) undone" in v.stdout


@pytest.mark.slow
def test_a_fresh_process_reads_a_cropped_copy_without_scipys_graph_module(marked, tmp_path):
    """The cut planes' boundary loops are labelled in numpy (``adjacency.component_labels``):
    ``scipy.sparse.csgraph`` is 0.09 s of a fresh process's imports, and `pmwm verify` of a cropped copy
    (the crop search) no longer loads it."""
    from test_background import _fresh_process

    write_mesh(tmp_path / "cut.ply", *A.crop_plane(marked.vertices, marked.faces, fraction=0.1, seed=1))
    code = (
        "import sys, pmwm\n"
        "from pmwm.meshio import read_mesh\n"
        f"m = read_mesh({str(tmp_path / 'cut.ply')!r})\n"
        f"v = pmwm.verify(m.vertices, m.faces, passphrase={PHRASE!r})\n"
        "assert v.marked and v.payload == 'Acme' and v.detail.frame.startswith('crop'), v.detail\n"
        "assert 'scipy.sparse.csgraph' not in sys.modules\n"
    )
    _fresh_process(code)


@pytest.mark.slow
def test_a_small_cut_suspect_is_read_without_importing_scipy_sparse(tmp_path):
    """``pmwm verify`` of a small suspect cut by a plane and not read (the bundled bunny's half, unmarked:
    the crop search, then the subdivision and smoothing looks) needs no scipy.sparse, whose first import
    costs a fresh process 0.11-0.17 s (``adjacency.boundary_edges``, ``adjacency.numpy_sparse``); a larger
    one still uses it, with the same answer (``test_smoothing``)."""
    from test_background import _fresh_process

    write_mesh(tmp_path / "half.ply", *A.crop_plane(*meshes.bunny(), 0.5, seed=2))
    code = (
        "import sys, pmwm\n"
        "from pmwm.meshio import read_mesh\n"
        f"m = read_mesh({str(tmp_path / 'half.ply')!r})\n"
        "v = pmwm.verify(m.vertices, m.faces, passphrase='a phrase')\n"
        "assert not v.marked and v.detail.frame.startswith('crop'), v.detail\n"
        "assert 'scipy.sparse' not in sys.modules\n"
    )
    _fresh_process(code)


@pytest.mark.slow
def test_an_unmarked_small_mesh_is_cleared_without_importing_scipy_sparse(tmp_path):
    """``pmwm verify`` of the bundled bunny, unmarked, with a pass phrase: not marked, after the subdivision
    look (its components in numpy, ``subdivision._components``) and the smoothing scan, in a fresh process
    that never imports scipy.sparse (its first import costs 0.11-0.17 s)."""
    from test_background import _fresh_process

    code = (
        "import sys, pmwm\n"
        "from pmwm.meshio import read_mesh\n"
        f"m = read_mesh({str(BUNNY)!r})\n"
        "v = pmwm.verify(m.vertices, m.faces, passphrase='a phrase')\n"
        "assert not v.marked and v.detail.frame in ('own', 'refined'), v.detail\n"
        "assert 'scipy.sparse' not in sys.modules\n"
    )
    _fresh_process(code)
