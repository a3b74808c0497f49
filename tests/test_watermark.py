"""Embedding and blind verification: bits recovered, reordering and cropping survived, no false positives."""

from __future__ import annotations

import numpy as np
import pytest

import pmwm
from pmwm import attacks
from pmwm import EmbedOptions, ber_per_level, embed, verify, verify_pm

import meshes


@pytest.fixture(scope="module")
def marked(bunny):
    V, F = bunny
    return V, F, embed(V, F, EmbedOptions(payload="ACME 2026", seed=11, scheme="paper"))


def test_all_bits_recovered_unattacked(marked):
    V, F, res = marked
    v = verify(res.vertices, F, res.key)
    assert v.marked and v.bit_errors == 0 and v.payload == "ACME 2026"
    assert v.mode == "index" and v.carriers_found == v.carriers_total == 72
    assert v.p_value < 1e-20 and v.correlation == 1.0
    # only the carriers moved
    moved = np.flatnonzero(np.any(np.abs(res.vertices - V) > 1e-6, axis=1))
    assert set(moved.tolist()) == set(res.carriers.tolist())


def test_reordered_vertices_and_faces(marked):
    _, F, res = marked
    V2, F2 = attacks.reorder(res.vertices, F, seed=3)
    assert not np.array_equal(V2, res.vertices)
    v = verify(V2, F2, res.key)
    assert v.mode == "position" and v.marked and v.bit_errors == 0 and v.payload == "ACME 2026"


@pytest.mark.parametrize("crop", [attacks.crop_paper, attacks.crop_plane])
def test_cropped_ten_percent(marked, crop):
    _, F, res = marked
    V2, F2 = crop(res.vertices, F, 0.10, seed=5)
    assert len(V2) < 0.91 * len(res.vertices)
    v = verify(V2, F2, res.key)
    assert v.marked and v.p_value < 1e-6
    # every carrier that is still there reads right; the lost ones are erasures
    assert v.carriers_found < v.carriers_total or v.bit_errors == 0
    assert v.matches >= v.carriers_found


def test_watermark_read_at_intermediate_levels(marked):
    _, _, res = marked
    levels = ber_per_level(res.pm, res.key)
    n_full = res.pm.n_vertices
    report = ", ".join(f"{n}v:{b:.2f}" for _, n, b in levels)
    print(f"BER per LoD: {report}")
    assert levels[-1][2] == 0.0
    # every level with at least a third of the vertices reads every bit, and no level
    # (down to the 3 % base mesh) loses more than a fifth of them
    assert all(b == 0.0 for _, n, b in levels if n >= n_full / 3)
    assert max(b for _, _, b in levels) <= 0.2
    # and the mark is already significant on the base mesh: carriers are never collapsed
    base = verify_pm(res.pm, res.key, records=0)
    assert base.carriers_found == base.carriers_total
    assert base.matches > base.carriers_total * 0.75


def test_unmarked_original_is_not_marked(marked):
    V, F, res = marked
    v = verify(V, F, res.key)
    assert not v.marked and v.p_value > 1e-3


def test_wrong_key_is_not_marked(marked):
    _, F, res = marked
    other = embed(*meshes.bunny(), EmbedOptions(payload="ACME 2026", seed=12, scheme="paper"))
    v = verify(res.vertices, F, other.key)
    assert not v.marked


@pytest.mark.slow
def test_same_seed_reproduces_and_bits_roundtrip():
    V, F = meshes.cad_part()
    a = embed(V, F, EmbedOptions(bits="1011001110001111", seed=4))
    b = embed(V, F, EmbedOptions(bits="1011001110001111", seed=4))
    assert np.array_equal(a.vertices, b.vertices) and a.key.to_json() == b.key.to_json()
    v = verify(a.vertices, F, a.key)
    assert v.bits == "1011001110001111"
    c = embed(V, F, EmbedOptions(bits="1011001110001111", seed=5))
    assert not np.array_equal(np.sort(a.carriers), np.sort(c.carriers))


@pytest.mark.slow
def test_random_payload_default_64_bits():
    V, F = meshes.cad_part()
    res = embed(V, F, EmbedOptions(seed=1))
    assert len(res.bits) == 64
    assert verify(res.vertices, F, res.key).matches == 64


def test_too_many_bits_for_a_small_mesh():
    V, F = meshes.blob()
    with pytest.raises(pmwm.PayloadError, match="fewer bits"):
        embed(V, F, EmbedOptions(n_bits=2000, seed=1))


@pytest.mark.parametrize(
    "opts",
    [
        EmbedOptions(payload="x", bits="01"),
        EmbedOptions(bits="01a"),
        EmbedOptions(payload=""),
        EmbedOptions(strength=-1),
        EmbedOptions(base_ratio=0),
    ],
)
def test_bad_options(opts):
    V, F = meshes.blob()
    with pytest.raises(pmwm.PmwmError):
        embed(V, F, opts)


def test_marked_file_roundtrip_ply(tmp_path, marked):
    _, F, res = marked
    path = tmp_path / "m.ply"
    pmwm.write_mesh(path, res.vertices, F)
    src = pmwm.read_mesh(path)
    assert np.array_equal(src.vertices, res.vertices)  # float32 storage is exact
    assert verify(src.vertices, src.faces, res.key).bit_errors == 0


@pytest.mark.parametrize("ext", [".obj", ".ply", ".stl", ".off", ".glb"])
def test_reexported_copies_verify(tmp_path, marked, ext):
    """A copy re-exported to any supported format (STL and GLB lose the vertex order) still verifies."""
    _, F, res = marked
    path = tmp_path / f"copy{ext}"
    pmwm.write_mesh(path, res.vertices, F)
    src = pmwm.read_mesh(path)
    v = verify(src.vertices, src.faces, res.key)
    assert v.marked and v.bit_errors == 0 and v.payload == "ACME 2026"


def test_noisy_copy_in_the_marked_order_is_read_by_index(marked):
    """Uniform noise of 0.01 of the max norm moves carriers by more than a quarter of an edge, but the
    copy keeps the marked faces: carriers are read by index, every bit right. Re-ordered as well, the
    copy is still searched by position."""
    _, F, res = marked
    for seed in range(3):
        v = verify(*attacks.noise_paper(res.vertices, F, amplitude=0.01, seed=seed), res.key)
        assert (v.mode, v.detail.carriers) == ("index", "faces fingerprint") and v.bit_errors == 0
    noisy = attacks.noise_paper(res.vertices, F, amplitude=0.01, seed=1)
    v = verify(*attacks.reorder(*noisy, seed=2), res.key)
    assert v.mode == "position" and v.matches > 0.7 * v.carriers_total


def test_noisy_levels_of_detail_are_read_by_index(marked):
    """The progressive mesh's numbering: its full level by the fingerprint, a coarser one (whose
    faces the key cannot know) because its carriers sit near their places."""
    _, _, res = marked
    full = res.pm.decode()
    v = verify(*attacks.noise_paper(*full, amplitude=0.005, seed=4), res.key)
    assert (v.mode, v.detail.carriers) == ("index", "faces fingerprint") and v.bit_errors == 0
    coarse = res.pm.decode(records=res.pm.n_records // 2)
    v = verify(*attacks.noise_paper(*coarse, amplitude=0.005, seed=4), res.key)
    assert (v.mode, v.detail.carriers) == ("index", "near their places") and v.marked


def test_keys_without_a_fingerprint_still_read_by_index_when_carriers_are_in_place(marked):
    """Keys written before the fingerprint (empty fields) fall back to the position test."""
    import dataclasses

    _, F, res = marked
    old = dataclasses.replace(res.key, faces_fingerprint="", pm_faces_fingerprint="")
    v = verify(*attacks.noise_paper(res.vertices, F, amplitude=0.002, seed=0), old)
    assert (v.mode, v.detail.carriers) == ("index", "near their places") and v.bit_errors == 0


def test_the_faces_fingerprint_is_its_documented_hash():
    """Key files hold the faces' SHA-256 (each triangle rotated to start at its first smallest index, the
    rows in lexicographic order, little-endian int64), so keys written before must keep matching: the
    fingerprint equals that definition computed plainly (degenerate rows and indices past the packed
    path's 21 bits included), whatever the order and rotation of the triangles, and not for flipped ones."""
    import hashlib

    from pmwm.key import face_fingerprint

    def plain(F):
        G = np.take_along_axis(F, (np.argmin(F, axis=1)[:, None] + np.arange(3)) % 3, axis=1)
        return hashlib.sha256(np.ascontiguousarray(G[np.lexsort(G.T[::-1])], dtype="<i8").tobytes()).hexdigest()

    rng = np.random.default_rng(5)
    for n, top in ((0, 5), (1, 3), (400, 6), (3000, 1 << 23)):
        F = rng.integers(0, top, (n, 3))
        F[: n // 8, 1] = F[: n // 8, 0]  # rows with a repeated index
        F[n // 8 : n // 4, 2] = F[n // 8 : n // 4, 1]
        assert face_fingerprint(F) == plain(F)
        E = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]  # (a triangle's own rotations)
        shuffled = np.roll(E[rng.permutation(len(E))], rng.integers(0, 3), axis=1)
        assert face_fingerprint(shuffled) == face_fingerprint(E)
    V, F = meshes.blob()
    assert face_fingerprint(F) == plain(F) != face_fingerprint(F[:, ::-1])


@pytest.mark.parametrize("scheme", ["robust", "blind", "cho1"])
@pytest.mark.slow
def test_without_a_progressive_mesh_the_same_mesh_is_marked_and_read(scheme, tmp_path):
    """``EmbedOptions(progressive=False)`` skips the build: no ``pm``, the very same marked mesh as with
    it, and the key (its progressive numbering the mesh's own) reads the mark, through a key file too."""
    V, F = meshes.open_cap()
    phrase = "a pass phrase" if scheme == "blind" else None
    runs = {
        p: embed(V, F, EmbedOptions(payload="Acme", seed=4, scheme=scheme, passphrase=phrase, progressive=p))
        for p in (True, False)
    }
    assert runs[True].pm is not None and runs[False].pm is None
    assert np.array_equal(runs[True].vertices, runs[False].vertices)
    key = runs[False].key
    if scheme == "blind":  # (no key: the pass phrase reads it)
        assert key is None
        v = verify(runs[False].vertices, F, passphrase=phrase)
    else:
        assert np.array_equal(key.carrier_pm_index, key.carrier_index) and key.pm_faces_fingerprint == ""
        pmwm.write_key(tmp_path / "k.json", key)
        v = verify(runs[False].vertices, F, pmwm.read_key(tmp_path / "k.json"))
    assert v.marked and v.payload == "Acme"


def test_the_paper_scheme_builds_its_progressive_mesh_anyway():
    """The paper's bits go in during the collapses: ``progressive=False`` cannot skip them."""
    V, F = meshes.blob()
    on = embed(V, F, EmbedOptions(payload="Acme", seed=4, scheme="paper"))
    off = embed(V, F, EmbedOptions(payload="Acme", seed=4, scheme="paper", progressive=False))
    assert off.pm is not None and np.array_equal(on.vertices, off.vertices)
    assert off.pm.n_records == on.pm.n_records


def test_a_keyed_payload_is_confirmed_only_when_every_bit_is_the_keys(marked):
    """The verdict from per-bit scores: all bits right, the payload is confirmed and shown; 3 of 72 wrong,
    the mesh is still marked but the payload is unconfirmed: no text, no bits in the JSON, and its words
    say how many bits differ; the rule is one function a scheme may replace (one that corrects errors)."""
    from pmwm import wording
    from pmwm.base import confirm_payload, verdict_from_scores

    key = marked[2].key
    right = np.where((key.bits ^ key.stream("scramble", key.n_bits)) == 1, 1.0, -1.0)
    v = verdict_from_scores(right, key, "index", 1e-6)
    assert v.marked and v.payload_confirmed and v.payload == "ACME 2026"
    assert v.to_dict()["payload"] == "ACME 2026" and wording.payload_line(v) == "payload: 'ACME 2026'"
    wrong = right.copy()
    wrong[[0, 9, 30]] *= -1  # (in the text's first bytes)
    v = verdict_from_scores(wrong, key, "index", 1e-6)
    assert v.marked and v.bit_errors == 3 and not v.payload_confirmed and v.payload is None
    d = v.to_dict()
    assert (d["payload_confirmed"], d["payload"], d["bits"]) == (False, None, None)
    assert wording.payload_line(v) == f"payload unconfirmed (3 of {key.n_bits} bits differ)"
    assert all("ACME" not in line for line in wording.lines(v))
    assert all("ACME" not in value for _, value in wording.rows(v) + wording.technical_rows(v))
    corrected = verdict_from_scores(wrong, key, "index", 1e-6, confirm=lambda marked, bits, key: marked)
    assert corrected.payload_confirmed and corrected.to_dict()["bits"] == corrected.bits
    assert not confirm_payload(False, key.bits, key) and confirm_payload(True, key.bits, key)
    unmarked = verdict_from_scores(-right, key, "index", 1e-6)
    assert not unmarked.marked and unmarked.payload is None and wording.payload_line(unmarked) == "no payload read"


def test_verify_dispatches_a_pass_phrase_through_the_registry(monkeypatch):
    """``pmwm.verify(..., passphrase=...)`` hands the suspect to the registry's scheme keyed by a pass phrase,
    as it hands a key to its scheme: nothing in ``pmwm.api`` names the blind scheme."""
    import dataclasses

    from pmwm.schemes import SCHEMES

    calls = []

    def read(vertices, faces, secret, p_threshold, progress=None):
        calls.append((secret, p_threshold, progress))
        return "a verdict"

    monkeypatch.setitem(SCHEMES, "blind", dataclasses.replace(SCHEMES["blind"], verify=read))
    V, F = meshes.blob()
    assert pmwm.verify(V, F, passphrase="a phrase", p_threshold=1e-9) == "a verdict"
    assert calls == [("a phrase", 1e-9, None)]


@pytest.mark.parametrize("scheme", ["robust", "paper", "cho1"])
def test_every_keyed_schemes_verdict_says_how_it_read_in_words_and_numbers(scheme):
    """Each scheme's verdict carries its own typed detail (no untyped dict): plain-words rows without the
    reader's jargon, and its numbers for a technical section."""
    V, F = meshes.cad_part()
    res = embed(V, F, EmbedOptions(bits="01" * 12, seed=2, scheme=scheme, progressive=False))
    v = verify(res.vertices, F, res.key)
    assert v.marked and v.payload_confirmed and not hasattr(v, "extra")
    assert type(v.detail) is not pmwm.VerdictDetail and isinstance(v.detail, pmwm.VerdictDetail)
    words, numbers = v.detail.in_words(), v.detail.numbers()
    assert words and numbers
    for _, value in words:
        assert "_" not in value and ": none (" not in value and "fingerprint" not in value


def _fractions(run) -> tuple[object, list[tuple[float, str]]]:
    """(what ``run(progress)`` returns, the (fraction, message) of every progress call it made)."""
    seen: list[tuple[float, str]] = []
    out = run(lambda f, m: seen.append((f, m)))
    return out, seen


@pytest.mark.parametrize("scheme", ["robust", "paper", "cho1", "blind"])
def test_verify_reports_its_stages_with_growing_fractions_ending_at_one(scheme):
    """``pmwm.verify(progress=...)``: every scheme's reader calls it with fractions in [0, 1] that never go
    back, the last one 1.0, on the marked mesh and on a moved and re-ordered copy (the robust reader then
    registers it and says so); the verdict is the one read without a callback."""
    V, F = meshes.cad_part() if scheme == "cho1" else meshes.blob()  # (Cho's bins: a mesh that fills them)
    phrase = "a pass phrase" if scheme == "blind" else None
    payload = {"bits": "01" * 12} if scheme == "cho1" else {"payload": "Acme"}
    res = embed(V, F, EmbedOptions(**payload, seed=4, scheme=scheme, passphrase=phrase, progressive=False))
    moved = attacks.reorder(*attacks.similarity(res.vertices, F, seed=5)[:2], seed=6)[:2]
    for Vs, Fs in ((res.vertices, F), moved):
        v, seen = _fractions(lambda p: verify(Vs, Fs, res.key, passphrase=phrase, progress=p))
        fractions = [f for f, _ in seen]
        assert len(seen) >= 2 and fractions[-1] == 1.0
        assert all(0.0 <= f <= 1.0 for f in fractions) and fractions == sorted(fractions)
        assert all(isinstance(m, str) and m for _, m in seen)
        plain = verify(Vs, Fs, res.key, passphrase=phrase)
        assert (v.marked, v.bits, v.p_value) == (plain.marked, plain.bits, plain.p_value)
    if scheme == "robust":  # the copy was moved: the registration's stages are reported
        assert any(m.startswith("aligning") for _, m in seen) and len({f for f, _ in seen}) >= 5


@pytest.mark.parametrize("scheme", ["robust", "blind"])
def test_a_progress_callback_that_raises_stops_the_reader(scheme):
    """The add-on cancels a run by raising from the progress callback: the reader stops there and the
    exception reaches the caller (nothing is returned)."""
    V, F = meshes.blob()
    phrase = "a pass phrase" if scheme == "blind" else None
    res = embed(V, F, EmbedOptions(payload="Acme", seed=4, scheme=scheme, passphrase=phrase, progressive=False))

    class Stop(Exception):
        pass

    calls = []

    def stop_at_second(f, m):
        calls.append(f)
        if len(calls) == 2:
            raise Stop()

    with pytest.raises(Stop):
        verify(res.vertices, F, res.key, passphrase=phrase, progress=stop_at_second)
    assert len(calls) == 2
