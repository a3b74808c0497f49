"""The blind scheme ("blind"): a pass phrase and the suspect mesh are all the reader needs.

- ``word``: the pass phrase (scrypt), the payload and its keyed check, the keyed layout.
- ``radial``: the carrier, the distribution of the vertices' distances to the surface centroid in
  equal bins (Cho et al.'s method I, over an area-quantile range instead of the extreme vertices, with
  an edge-preserving push in each bin), and the frame refinement.
- ``crop``: the frame of a plane-cropped copy; ``frames``: the frames the reader reads in.
- ``keydata``: the record in the in-memory key (no key file is written; nothing from the mesh).

Embedding writes word = payload + check, XOR a keyed scrambling, one bit per ``BINS_PER_BIT`` keyed
bins. Reading computes the bins' statistics for every possible word length in up to two frames: the
suspect's own (centre and range recomputed) and a refined one, the frame within 1.5 bin widths of it
where the mark's energy (sum of n_j (bin mean - 1/2)^2, no pass phrase involved) is largest
(``radial.refine_frame``). It reads one length, the one whose bins show the most energy in the own
frame (no pass phrase involved either), and keeps the reading whose check bits match best; its
p-value is exact per reading and a union bound over all (2 frames x 2 kinds x 1024 Chase candidates =
4096 candidates: all 32 check bits right still gives p <= 9.5e-7 < 1e-6; see ``word``; a cropped
copy's 6 frames x 2 kinds x 256 candidates: 7.2e-7; a blurred copy's own and refined frames read as
they are and after a few smoothing steps, 4 x 2 x 512: 9.5e-7). The candidates are the words with the
most likely sets of bits flipped (``word.likely_flips``), each bit's reliability its score in units of its
bins' standard error (``word_read``).

Why one length, chosen by energy: choices made without the pass phrase cost the p-value nothing, so
reading one length instead of four pays for 2 more Chase bits (10 instead of 8) at the same p-value.
The energy named the right length in 119 of 120 attacked copies (bunny, Venus head, dragon; 5 keys;
midpoint, Loop and sqrt3 subdivision, 8-bit quantization, 10 smoothing iterations, 50 and 70 %
simplification, 0.5 % noise), the miss on a copy no search read; the 10-bit search would read 6 of
those 120 copies more than the 8-bit one (the errors all among the 10 least reliable bits, not
among the 8).

Why the refined frame (BENCHMARKS.md section ``blind``, 4 models x 3 keys, whole payload read, the
same copies read in the own frame alone -> in both frames): smoothing 5 it. 5/12 -> 11/12, 10 it.
0/12 -> 4/12, simplification 50 % 5/12 -> 9/12, 70 % 1/12 -> 6/12, noise 0.5 % 2/12 -> 5/12; no copy
read in the own frame is lost (its reading is still among the candidates). After these attacks the
frame drifts by 0.1-0.4 bin widths while the bins' bias stays: read in the original's frame, 50 %
simplification of the dragon gives BER 0 against 0.14 in its own frame.

Strength: without an explicit ``strength`` the margin is calibrated per mesh to the distortion budget
(``TARGET_MRMS``; ``_calibrated``): 0.07 everywhere gave MRMS 0.012 % on the Venus head and Igea
against 0.019 % on the bunny and dragon (vertices moved along their radius); calibrated, the margin (of a
bin of median count, ``radial.bin_margins``) is about 0.09 on the bunny and dragon, 0.11-0.13 on the heads
(moved partly along the surface, ``radial.moved_to_radius``; 0.07 and 0.09-0.10 along the radius).

Cropping: a 10 % plane crop moves the area centroid by 5-21 bin widths and lo/hi by up to 9, far
outside the refinement's reach (no cropped copy read before). When the suspect has a planar cut, the
reader also searches the frame the cut took away (``crop``: the original centroid lies near a
two-parameter family given by the cut plane; ``frames``), key-free as well, and reads there the length
whose frame shows the most energy. The mark is global (no places); it is rotation-, scale-,
translation- and order-invariant by construction.

Subdivision: a subdivided copy (midpoint, Loop, sqrt(3), Catmull-Clark) carries the marked mesh in its
connectivity; when the suspect does not show the mark in full view, the reader also measures the mesh
it was subdivided from (``pmwm.subdivision``, up to three steps back; ``frames.read_statistics``),
key-free, and reads that one when it shows twice the mark energy per vertex.

Noise: when the bins read show their neighbours' interference (8-bit quantization, 0.5 % noise blur the
radii across the bins' edges), the reader also reads the suspect after three steps of Laplacian
smoothing, which take out more of the blur than of the mark (``frames.with_denoised``), its frames
counted in the union bound. A copy on a coarse grid whose bins do not show the blur is read in the same
denoised frames as reserve frames, with the candidates the p-value's budget leaves (49 per reading beside
two frames: ``word.reserve_candidates``), so that its other frames keep their 10 Chase bits: the Venus
head's 8-bit copy of the benchmark's key 1002 is read so (``frames``, item 6).

No mark read: the verdict also returns the reader's best guess of the word, chosen without the check bits
(``_guess``): the hard decisions of its reading's own frame, or for a copy quantized to a coarse grid, of the
copy smoothed by the count of steps, at the length, that shows the most mark energy
(``frames.guess_statistics``): at 7 bits it errs on 0.02-0.21 of the bits against 0.06-0.39 (an owner can
compare it with the payloads they marked).

Smoothing: a copy smoothed by uniform Laplacian steps still holds the mark, damped with the rest of its
detail, but its radii are blurred; when the suspect does not show the mark in full view, the reader
also takes the smoothing back step by step (``pmwm.smoothing``, ``frames.unsmoothing``), key-free, and
reads the count of steps that shows twice the mark energy per vertex.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ... import metrics
from ...background import Background, beside, silent
from ...base import EmbedOptions, EmbedResult, Progress, Scheme, Verdict, finish_embed, start_embed
from ...errors import MeshError, PayloadError
from ...key import WatermarkKey, keyed_bits
from ...progressive import ProgressiveMesh, base_vertex_count, build_progressive_mesh, with_positions
from ...validate import check_mesh
from . import frames, radial, selfcheck, word
from .keydata import BlindKeyData

__all__ = ["SCHEME", "DEFAULT_ALPHA", "BINS_PER_BIT", "key_from_passphrase", "read", "read_with_passphrase",
           "bin_statistics", "decide", "Statistics", "word_read", "mesh_read", "guessed_payload", "BlindKeyData"]

DEFAULT_ALPHA = 0.07
TARGET_MRMS = 0.019  # without an explicit strength: the margin giving this MRMS (% of the bbox diagonal)
CALIBRATION_SAMPLES = 5000
CALIBRATION_ROUNDS = 2  # rescales of the margin towards TARGET_MRMS
ALPHA_RANGE = (0.03, 0.2)  # the calibrated margin stays in this range
BINS_PER_BIT = 1
NAME = "blind"


def _n_bins(n_word: int) -> int:
    return n_word * BINS_PER_BIT


def embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
    """Mark a mesh, vertices (n, 3) float64, faces (m, 3) int64 (kept), with the pass phrase of
    ``options``; the payload is ``options.payload`` (text), ``options.bits`` or ``options.n_bits``
    random bits (from ``options.seed``)."""
    opts = options or EmbedOptions(scheme=NAME)
    passphrase = getattr(opts, "passphrase", None)
    if passphrase is None:
        raise PayloadError("the blind scheme needs a pass phrase (EmbedOptions.passphrase, --passphrase-file "
                           "or PMWM_PASSPHRASE)")
    word.check_passphrase(passphrase)  # (its secret is derived once the build has started: scrypt takes a while)
    # the generic first steps with an explicit-bits stand-in (the blind payload has its own lengths)
    job = start_embed(vertices, faces, EmbedOptions(bits="0", strength=opts.strength, base_ratio=opts.base_ratio,
                                                    seed=opts.seed, scheme=NAME, progressive=opts.progressive),
                      progress, NAME, DEFAULT_ALPHA)
    if not job.strength < 0.5:
        raise PayloadError(f"the blind scheme's strength (the bin-mean margin) must be below 0.5, got {job.strength}")
    payload_seed = job.secret  # fresh randomness, or from the seed: one payload per mesh
    payload, kind = word.payload_of(opts.payload, opts.bits, opts.n_bits,
                                    lambda n: keyed_bits(payload_seed, "blind-random-payload", n))
    V, F = job.vertices, job.faces
    base = base_vertex_count(opts.base_ratio, len(V))
    # the progressive mesh of the unmarked mesh, built beside the marking (its thread makes its own
    # adjacency: the marking and the key need none); the marked positions go in after. None built when
    # the options ask for none.
    build = job.options.progressive
    with beside(build, build_progressive_mesh, V, F, base_vertices=base) as building:
        secret = word.derive_secret(passphrase)
        w = word.word_of(secret, kind, payload)
        n_bins = _n_bins(len(w))
        bit_of_bin, scramble = word.layout(secret, len(w), n_bins)
        signs = np.where((w ^ scramble)[bit_of_bin] == 1, 1, -1)
        job.report(0.0, "marking the radial distribution")
        host = radial.Host.of(V, F, n_bins)  # (the unmarked mesh's frame and normals, for every marking)
        marked = radial.embed_signs(V, F, signs, job.strength, host=host)
        if opts.strength is None:  # the default: calibrate the margin to the distortion budget
            job.strength, marked = _calibrated(V, F, signs, job.strength, marked, host)
        job.report(0.05, "checking that the mark reads back")  # (else a raised margin, or a PayloadError)
        job.strength, marked = selfcheck.ensure(selfcheck.Mark(
            V, F, lambda a: radial.embed_signs(V, F, signs, a, host=host), lambda V2, F2: read(V2, F2, secret),
            "".join(map(str, payload.tolist())), word.text_of(payload) if kind == "text" else None, secret),
            marked, job.strength, adjustable=opts.strength is None)

        def marked_pm() -> ProgressiveMesh:  # awaited last: the key is made meanwhile
            pm, _ = building.result(lambda f, m: job.report(0.1 + 0.85 * f, m))
            return with_positions(pm, marked)

        job.bits = payload  # (the result's bits: the payload embedded; the key holds the secret and its kind)
        return finish_embed(job, marked, marked_pm if build else None, np.zeros(0, np.int64),
                            _key(secret, payload, kind, job.strength))


def _calibrated(V, F, signs, alpha, marked, host: radial.Host) -> tuple[float, np.ndarray]:
    """(margin, marked vertices) with the margin rescaled up to CALIBRATION_ROUNDS times so that the
    embedding's MRMS (the benchmark's surface distance on ``CALIBRATION_SAMPLES`` points;
    ``metrics.displaced_surface_distance`` measures it without a spatial index: the same figure as
    ``metrics.surface_distance`` on the bunny, Venus head and Igea, 1.4e-5 relative above it on the dragon,
    in a third of the time) is TARGET_MRMS % of the bounding-box diagonal, clipped to ALPHA_RANGE. The
    same margin gives different distortions on different shapes (0.07: MRMS 0.012 % on the Venus head,
    0.019 % on the bunny); spending the same budget on each buys robustness where the margin was cheap.
    The MRMS grows about linearly with the margin, not exactly: one rescale left the Venus head at
    0.0177-0.0181 %, a second brings it to 0.0188 %. The margin used is recorded in the key; the reader
    does not need it."""
    for _ in range(CALIBRATION_ROUNDS):
        mrms = metrics.displaced_surface_distance(V, marked, F, CALIBRATION_SAMPLES, seed=0)[0]
        if not mrms > 0:
            break
        new = float(np.clip(alpha * TARGET_MRMS / mrms, *ALPHA_RANGE))
        if abs(new - alpha) < 1e-3:
            break
        alpha, marked = new, radial.embed_signs(V, F, signs, new, host=host)
    return alpha, marked


@dataclass
class Statistics:
    """What the reader measures on a suspect, independent of the pass phrase: per word length N the
    bins' statistics (R, N * BINS_PER_BIT) float64 (bin mean of r - 1/2; NaN: an empty bin) in R = 1
    to 4 or 6 frames (``frame_names``: the suspect's own, then a refined one, or a cropped copy's and its
    neighbours, then the "denoised" ones; see ``frames.read_statistics``), and the length ``n_word`` the
    reader reads;
    ``shares``, the same shape, each bin's share of the vertices (None: taken as equal), which weighs how
    reliable its reading is (``word_read``); ``mesh``, the mesh measured ("suspect", or the mesh a
    subdivided suspect was made from: ``frames.Frames.mesh``; the "denoised" frames': ``frames.mesh_of``);
    ``reserve``, the number of trailing frames read with what the p-value's budget leaves
    (``frames.Frames.reserve``, ``candidates``); ``guess``, called only for a verdict that finds no mark (``frames.Frames.guess``: for a suspect on a coarse
    grid, the statistics of the suspect as it is or smoothed, and the length (an index into ``words``) whose bins
    show the most energy, else None; ``_guess``)."""

    words: dict[int, np.ndarray]
    n_word: int
    frame_names: tuple[str, ...]
    shares: Optional[dict[int, np.ndarray]] = None
    mesh: str = "suspect"
    guess: Optional[Callable[[], Optional[tuple[int, int, np.ndarray, np.ndarray]]]] = None
    reserve: int = 0

    def own_frame(self) -> "Statistics":
        """The same measurements in the suspect's own frame alone (the reader without the refinement)."""
        shares = None if self.shares is None else {n: s[:1] for n, s in self.shares.items()}
        return Statistics({n: s[:1] for n, s in self.words.items()}, self.n_word, self.frame_names[:1], shares,
                          self.mesh, self.guess)

    def candidates(self) -> list[int]:
        """The Chase candidates read per kind in each frame: 2^``word.chase_bits`` in the frames read in full,
        ``word.reserve_candidates`` in the last ``reserve`` ones (``frames.Frames.reserve``)."""
        n_frames = len(self.frame_names)
        full = n_frames - self.reserve
        return [2 ** word.chase_bits(full)] * full + [word.reserve_candidates(full, self.reserve)] * self.reserve


def bin_statistics(vertices, faces) -> Statistics:
    """The ``Statistics`` of a suspect, vertices (n, 3), faces (m, 3) (``frames.read_statistics``: its
    own, or those of the coarse mesh under it when it is a subdivided copy)."""
    V, F = check_mesh(vertices, faces)
    if len(F) == 0:
        raise MeshError("the suspect has no faces; the blind scheme reads a surface")
    words = [L + word.CHECK_BITS for L in word.PAYLOAD_BITS]
    got = frames.read_statistics(V, F, [_n_bins(n) for n in words])
    return Statistics({n: np.stack([many[i][0] for many in got.statistics]) for i, n in enumerate(words)},
                      words[got.index], got.names,
                      {n: np.stack([many[i][1] for many in got.statistics]) for i, n in enumerate(words)},
                      got.mesh, got.guess, got.reserve)


def word_read(stat: np.ndarray, secret: str, n_word: int, share: Optional[np.ndarray] = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """The word of length ``n_word`` as read from the bins' statistics (M,) in radial order (after
    ``radial.equalized``: hard decisions, erasures drawn from a keyed coin) (N,) uint8, and the score of
    each bit (N,) float64 (sign = the scrambled bit, 0 = an erasure). With the bins' shares of the
    vertices ``share`` (M,), each bin's statistic counts in units of its standard error (times
    sqrt(share): a bin mean of n vertices errs by about 1 / sqrt(12 n)), so that the scores' magnitudes
    rank the bits by how likely they are right (the Chase search's order, ``word.likely_flips``). The
    neighbours' interference is removed in those units: the margins make every bin's mark the same
    number of standard errors (``radial.bin_margins``), as the equalizer's model has it (one g for all
    bins), where in bin means they differ from bin to bin (BENCHMARKS.md, ``blind-equalizer-rounds``)."""
    bit_of_bin, scramble = word.layout(secret, n_word, len(stat))
    if share is not None:
        stat = radial.in_standard_errors(stat, share)
    z = np.nan_to_num(radial.equalized(stat), nan=0.0)
    score = np.bincount(bit_of_bin, weights=z, minlength=n_word)
    got = (score > 0).astype(np.uint8)
    erased = score == 0
    got[erased] = keyed_bits(secret, f"blind-erasure:{n_word}", n_word)[erased]
    return got ^ scramble, score


def decide(stats: Statistics, secret: str, p_threshold: float = 1e-6) -> Verdict:
    """The verdict from the ``Statistics`` of ``bin_statistics`` and a secret (module docstring): the
    chosen length in every frame, both kinds, every Chase candidate; the p-value is the union bound over
    all of these candidates (R frames * 2 kinds * 2^C, C = ``word.chase_bits(R)``, and the reserve frames'
    candidates: ``Statistics.candidates``), so it stays exact when the reader keeps the best of them."""
    readings = []
    n_word = stats.n_word
    L = n_word - word.CHECK_BITS
    per_frame = np.atleast_2d(stats.words[n_word])
    shares = [None] * len(per_frame) if stats.shares is None else np.atleast_2d(stats.shares[n_word])
    n_frames = len(per_frame)
    per_reading = stats.candidates()
    chase = word.chase_bits(n_frames - stats.reserve)
    for fi, stat in enumerate(per_frame):
        if per_reading[fi] == 0:
            continue
        got, score = word_read(stat, secret, n_word, shares[fi])
        candidates = got[None] ^ word.likely_flips(np.abs(score), per_reading[fi])  # row 0: the word as read
        # the flips of check bits leave the payload as it is: each distinct payload's check computed once
        _, first, which = np.unique(np.packbits(candidates[:, :L], axis=1), axis=0, return_index=True,
                                    return_inverse=True)
        for kind in word.KINDS:
            checks = word.check_bits(secret, kind, candidates[first, :L])
            matches = np.sum(candidates[:, L:] == checks[which.ravel()], axis=1)
            best = int(np.argmax(matches))  # the first candidate of the most matches
            m, cand = int(matches[best]), candidates[best]
            readings.append((metrics.binomial_tail(m, word.CHECK_BITS), -m, fi, L, kind, cand, score, got))
    p1, neg_m, fi, L, kind, cand, score, raw = min(readings, key=lambda r: (r[0], r[1], r[2]))
    p = float(min(1.0, len(word.KINDS) * sum(per_reading) * p1))
    m = -neg_m
    payload = cand[:L]
    text = word.text_of(payload) if kind == "text" else None
    expected = word.check_bits(secret, kind, payload)
    marked = bool(p < p_threshold)
    guessed = {} if marked else _guess(stats, secret, per_frame[0], shares[0])
    return Verdict(
        marked=marked, p_value=p, bits="".join(map(str, payload.tolist())), payload=text,
        # matches / bit_errors / carriers_*: over the check bits (what the p-value counts)
        matches=m, bit_errors=word.CHECK_BITS - m,
        correlation=float(metrics.correlation(expected, cand[L:])),
        carriers_found=int(np.sum(score[L:] != 0)), carriers_total=word.CHECK_BITS, mode="blind",
        p_threshold=p_threshold,
        extra={"payload_bits": L, "check_bits": word.CHECK_BITS, "payload_kind": kind,
               # the mesh of the reading kept: "suspect", the subdivision steps undone, the smoothing
               # steps undone or taken ("smoothing:k", k < 0: a "denoised" frame; frames.mesh_of)
               "mesh": frames.mesh_of(stats.frame_names[fi], stats.mesh),
               "frame": stats.frame_names[fi], "frame_index": fi, "frames": n_frames, "chase_bits": chase,
               "reserve_frames": stats.reserve, "candidates": per_reading[fi],
               "word": "".join(map(str, cand.tolist())),  # after the Chase search
               "word_read": "".join(map(str, raw.tolist())),  # the hard decisions, before it
               **guessed},  # no mark found: the word guessed without the check bits (``_guess``)
        scores=score,  # (N,) sign = the scrambled bit read, as every scheme's scores
        places=np.zeros((0, 3)), place_bits=np.zeros(0, np.int64),
    )


def _guess(stats: Statistics, secret: str, own: np.ndarray, own_share: Optional[np.ndarray]) -> dict[str, str]:
    """For a verdict that finds no mark, the reader's best guess of the word, chosen without the check bits:
    {"guess": the hard decisions (``word_read``) of the reading's own frame (``own`` (M,), ``own_share``) at the
    length read, or for a suspect on a coarse grid those of ``Statistics.guess`` (the suspect as it is or
    smoothed, and the length, whichever shows the most mark energy: ``frames.guess_statistics``); "guess_mesh":
    the mesh they were read on}. The verdict's ``bits`` and "word" are the candidate whose check bits matched
    best, which, when nothing is read, the check bits chose; a guess is what an owner can compare with the
    payloads they marked. At 7-bit quantization it errs on 0.02-0.21 of the bits where the own frame errs on
    0.06-0.39 (mean per model; four models, 20 keys each; BENCHMARKS.md, ``session-30``)."""
    found = None if stats.guess is None else stats.guess()
    if found is None:
        n_word, stat, share, mesh = stats.n_word, own, own_share, stats.mesh
    else:
        steps, index, stat, share = found
        n_word, mesh = list(stats.words)[index], f"smoothing:-{steps}" if steps else "suspect"
    got, _ = word_read(stat, secret, n_word, share)
    return {"guess": "".join(map(str, got.tolist())), "guess_mesh": mesh}


def read(vertices, faces, secret: str, p_threshold: float = 1e-6) -> Verdict:
    """The blind reading: the payload read, its verdict and p-value. vertices (n, 3), faces (m, 3)
    of the suspect; ``secret`` from ``word.derive_secret``."""
    return decide(bin_statistics(vertices, faces), secret, p_threshold)


def read_with_passphrase(vertices, faces, passphrase: str, p_threshold: float = 1e-6) -> Verdict:
    """``read`` with the secret of ``passphrase``, derived in a worker thread beside the bins' statistics,
    which need none: hashlib's scrypt (``word.SCRYPT``, about 0.05 s) releases the GIL, so the derivation
    costs a cut suspect's reading no time on two cores."""
    word.check_passphrase(passphrase)
    with Background(silent(word.derive_secret), passphrase) as deriving:
        stats = bin_statistics(vertices, faces)
        return decide(stats, deriving.result(), p_threshold)


def verify(vertices, faces, key: WatermarkKey, p_threshold: float = 1e-6) -> Verdict:
    """Read with the secret of ``key`` (from ``pmwm.embed`` or ``key_from_passphrase``); the payload in
    the key is not used: the reading is blind."""
    return read(vertices, faces, key.secret, p_threshold)


def mesh_read(mesh: str) -> str:
    """The mesh a verdict was read on (``Verdict.extra["mesh"]``, ``frames.Frames.mesh``) in words, for
    the command line and the add-on: "" for the suspect itself."""
    if mesh == "suspect":
        return ""
    if mesh.startswith("smoothing:"):
        steps = int(mesh.split(":", 1)[1])
        if steps < 0:
            return f"read after {-steps} steps of Laplacian smoothing ({frames.DENOISE_LAM:g} each) against noise"
        return f"read with {steps} steps of Laplacian smoothing ({frames.UNSMOOTH_LAM:g} each) undone"
    return f"read on the mesh it was subdivided from: {mesh} undone"


def guessed_payload(verdict: Verdict) -> str:
    """The payload bits of a verdict's guess (``_guess``: a verdict that read no mark), for the command line
    and the add-on; "" when it has none (a verdict that read the mark, or another scheme's)."""
    return verdict.extra.get("guess", "")[: verdict.extra.get("payload_bits", 0)]


def key_from_passphrase(passphrase: str) -> WatermarkKey:
    """An in-memory key for ``pmwm.verify`` that holds only the secret derived from ``passphrase``."""
    return _key(word.derive_secret(passphrase), np.zeros(word.PAYLOAD_BITS[0], np.uint8), "bits", DEFAULT_ALPHA)


def _key(secret: str, payload: np.ndarray, kind: str, margin: float) -> WatermarkKey:
    """The blind scheme's key: the secret, the payload (N,) uint8 and its kind, the margin; nothing of the
    mesh (no size, no fingerprint, no coordinate: the reader needs none, and a key file written from it
    tells nothing of the asset)."""
    return WatermarkKey(
        secret=secret, bits=payload, payload_kind=kind, strength=margin, carrier_index=np.zeros(0, np.int64),
        carrier_pm_index=np.zeros(0, np.int64), carrier_position=np.zeros((0, 3)), n_vertices=1, n_faces=1,
        mean_edge=1.0, bbox_diagonal=1.0, scheme=NAME, data=BlindKeyData(len(payload), word.CHECK_BITS, margin),
    )


def load_key_data(key: WatermarkKey) -> BlindKeyData:
    """The blind data of a key."""
    return BlindKeyData.from_extra(key.extra if isinstance(key.extra, dict) else {})


SCHEME = Scheme(NAME, DEFAULT_ALPHA, embed, verify, load_key_data,
                "read with a pass phrase alone (no key file); the distribution of vertex norms")
