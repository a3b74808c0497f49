"""The blind scheme ("blind"): a pass phrase and the suspect mesh are all the reader needs.

Two carriers, one reader: ``blind`` marks with keyed waves, ``blind-histogram`` (the baseline) with the
histogram of the vertices' distances to the centroid; ``verify`` reads both, keyed waves first, each with its
share of the p-value's budget (``plan.WAVES_SHARE``).

- ``solid``: the solid's frame (centroid, axes, RMS radius); ``waves``: the keyed waves, their integrals over
  the solid and the marking; ``waveread``: the keyed-waves reading (hypotheses, lattice fit, decoding).
- ``word``: the pass phrase (scrypt), the payload and its keyed check, the keyed layout, the candidates.
- ``radial``: the carrier, the distribution of the vertices' distances to the surface centroid in equal bins
  (Cho et al.'s method I over an area-quantile range, with an edge-preserving push), and the frame refinement.
- ``crop``: the frame of a plane-cropped copy; ``frames``: the frames and meshes the reader reads in.
- ``plan``: the reading's stages in order, each one's share of the p-value's budget, the union bound;
  ``config``: ``ReaderConfig``, the reader's settings and the stages it may read.
- ``detail``: ``BlindDetail``, how a verdict was read. No key exists: ``pmwm.embed`` returns none.
- ``selfcheck``: the embed reads its own output and light copies of it before returning it.

Embedding writes word = payload + check, XOR a keyed scrambling, one bit per ``BINS_PER_BIT`` keyed bins, and
checks that it reads back. Reading chooses frames, meshes and the word length without the pass phrase, then
keeps the candidate whose check bits match best; its p-value is a union bound over every candidate read
(``plan.p_value``). A
marked reading's payload is confirmed by its check bits; a reading that finds no mark returns no payload. The
algorithm: docs/schemes/blind.md; the measurements behind its choices: docs/decisions/080-blind-reader-frames.md.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np

from ... import metrics
from ...background import beside
from ...base import (
    PASS_PHRASE,
    EmbedOptions,
    EmbedResult,
    Progress,
    Scheme,
    Verdict,
    finish_embed,
    no_progress,
    start_embed,
)
from ...errors import KeyFileError, MeshError, PayloadError
from ...key import WatermarkKey, keyed_bits
from ...progressive import ProgressiveMesh, base_vertex_count, build_progressive_mesh, with_positions
from ...validate import check_mesh
from . import frames, plan, radial, selfcheck, waveread, waves, word
from .config import READER, ReaderConfig
from .detail import BlindDetail, mesh_read
from .solid import solid_frame

__all__ = [
    "SCHEME",
    "HISTOGRAM_SCHEME",
    "WAVES_BUDGET",
    "DEFAULT_ALPHA",
    "BINS_PER_BIT",
    "read",
    "verify",
    "bin_statistics",
    "decide",
    "Statistics",
    "word_read",
    "guess_word",
    "mesh_read",
    "BlindDetail",
    "ReaderConfig",
    "READER",
]

DEFAULT_ALPHA = 0.07
TARGET_MRMS = 0.019  # without an explicit strength: the margin giving this MRMS (% of the bbox diagonal)
CALIBRATION_SAMPLES = 5000
CALIBRATION_ROUNDS = 2  # rescales of the margin towards TARGET_MRMS
ALPHA_RANGE = (0.03, 0.2)  # the calibrated margin stays in this range
BINS_PER_BIT = 1
NAME = "blind"
HISTOGRAM_NAME = "blind-histogram"
WAVES_BUDGET = 0.03  # keyed waves: the MRMS (% of the bbox diagonal) the marking may cost; the default strength
MRMS_SAMPLES = 5000


def _n_bins(n_word: int) -> int:
    return n_word * BINS_PER_BIT


def embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
    """Mark a mesh, vertices (n, 3) float64, faces (m, 3) int64 (kept), with the pass phrase of
    ``options`` in keyed waves (``waves``); the payload is ``options.payload`` (text of at most 12 bytes),
    ``options.bits`` or ``options.n_bits`` random bits (a multiple of 8 up to 96, from ``options.seed``); the strength
    is the most MRMS the marking may cost (% of the bounding-box diagonal, default ``WAVES_BUDGET``): the
    largest public step within it whose marked mesh reads back from its light copies. Where keyed waves
    cannot (a longer payload, an open sheet, no step that reads back), the mesh is marked with the baseline
    carrier (``embed_histogram``, its own read-back check) and ``EmbedResult.notes`` says so."""
    opts = options or EmbedOptions(scheme=NAME)
    passphrase, job = _start(vertices, faces, opts, progress, NAME, WAVES_BUDGET)
    V, F = job.vertices, job.faces
    secret = word.derive_secret(passphrase)
    job.report(0.0, "marking keyed waves")
    try:
        try:
            payload, kind = word.payload_of(
                opts.payload,
                opts.bits,
                opts.n_bits,
                lambda n: keyed_bits(job.secret, "blind-random-payload", n),
                waveread.LENGTHS,
                "keyed waves",
            )
        except PayloadError as exc:
            raise _Refused(str(exc)) from None
        marked, job.strength = _marked_waves(V, F, secret, payload, kind, job.strength)
    except _Refused as exc:
        # the baseline carrier marks what the keyed waves cannot (with its own read-back check), and says so
        try:
            res = embed_histogram(vertices, faces, replace(opts, scheme=HISTOGRAM_NAME, strength=None), progress)
        except PayloadError as base_exc:
            raise PayloadError(f"{exc}, and the baseline carrier: {base_exc}") from None
        note = (
            f"{exc}; marked with the baseline histogram carrier instead (scheme {HISTOGRAM_NAME}: less robust, "
            "see docs/schemes/blind.md)"
        )
        return replace(res, notes=res.notes + (note,))
    build = job.options.progressive
    base = base_vertex_count(opts.base_ratio, len(V))
    with beside(build, build_progressive_mesh, V, F, base_vertices=base) as building:

        def marked_pm() -> ProgressiveMesh:
            pm, _ = building.result(lambda f, m: job.report(0.1 + 0.85 * f, m))
            return with_positions(pm, marked)

        job.bits = payload
        return finish_embed(job, marked, marked_pm if build else None, np.zeros(0, np.int64), None)


def _start(vertices, faces, opts: EmbedOptions, progress: Progress, name: str, default_strength: float):
    """(pass phrase, EmbedJob): the options' pass phrase checked, then the generic first steps
    (``start_embed``) with an explicit-bits stand-in (a blind payload has its own lengths)."""
    passphrase = getattr(opts, "passphrase", None)
    if passphrase is None:
        raise PayloadError(
            "the blind scheme needs a pass phrase (EmbedOptions.passphrase, --passphrase-file or PMWM_PASSPHRASE)"
        )
    word.check_passphrase(passphrase)
    stand_in = EmbedOptions(
        bits="0",
        strength=opts.strength,
        base_ratio=opts.base_ratio,
        seed=opts.seed,
        scheme=name,
        progressive=opts.progressive,
    )
    return passphrase, start_embed(vertices, faces, stand_in, progress, name, default_strength)


class _Refused(PayloadError):
    """The keyed waves cannot carry this payload on this mesh (its message says why)."""


def _marked_waves(V, F, secret: str, payload: np.ndarray, kind: str, budget: float) -> tuple[np.ndarray, float]:
    """(marked vertices (n, 3), their MRMS %): the largest public step (``waves.STEPS``) whose marking costs at
    most ``budget`` % MRMS and reads back from every light copy (``selfcheck.failed_copy``), trying larger
    steps within the budget when one does not read. Raises PayloadError (one line) when none does."""
    w = waveread.word_of(secret, kind, payload)
    spread = waves.spread_of(secret, len(w))
    bits = w ^ spread.scramble
    keyed = waves.waves_of(secret)
    try:
        solid_frame(V, F)
    except ValueError as exc:
        raise _Refused(f"keyed waves mark a solid: {exc}") from None
    marked: dict[float, np.ndarray] = {}
    mrms: dict[float, float] = {}

    def at(step: float) -> float:
        if step not in marked:  # (float32-exact: what a file holds, what the self-check reads)
            marked[step] = waves.mark(V, F, keyed, spread, bits, step).astype(np.float32).astype(np.float64)
            mrms[step] = float(metrics.displaced_surface_distance(V, marked[step], F, MRMS_SAMPLES, seed=0)[0])
        return mrms[step]

    probe = waves.STEPS[len(waves.STEPS) // 2]
    guess = probe * budget / max(at(probe), 1e-300)  # (the MRMS grows about linearly with the step)
    order = sorted((s for s in waves.STEPS if s <= 1.1 * guess), reverse=True)
    order += sorted((s for s in waves.STEPS if s > 1.1 * guess))  # (when the first do not read back)
    check = selfcheck.Mark(
        V,
        F,
        lambda a: marked[a],
        lambda V2, F2: waveread.read(V2, F2, secret),
        "".join(map(str, payload.tolist())),
        word.text_of(payload) if kind == "text" else None,
        secret,
    )
    failed = "the mesh as written"
    for step in order:
        if at(step) > budget:
            continue
        failed = selfcheck.failed_copy(check, marked[step])
        if failed is None:
            return marked[step], mrms[step]
    raise _Refused(f"keyed waves do not read back from {failed} within {budget:g} % MRMS")


def embed_histogram(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
    """Mark a mesh, vertices (n, 3) float64, faces (m, 3) int64 (kept), with the pass phrase of
    ``options`` in the histogram of distances (the baseline carrier, scheme ``blind-histogram``); the
    payload is ``options.payload`` (text), ``options.bits`` or ``options.n_bits`` random bits (from
    ``options.seed``)."""
    opts = options or EmbedOptions(scheme=HISTOGRAM_NAME)
    # (its secret is derived once the build has started: scrypt takes a while)
    passphrase, job = _start(vertices, faces, opts, progress, HISTOGRAM_NAME, DEFAULT_ALPHA)
    if not job.strength < 0.5:
        raise PayloadError(f"the blind scheme's strength (the bin-mean margin) must be below 0.5, got {job.strength}")
    payload_seed = job.secret  # fresh randomness, or from the seed: one payload per mesh
    payload, kind = word.payload_of(
        opts.payload, opts.bits, opts.n_bits, lambda n: keyed_bits(payload_seed, "blind-random-payload", n)
    )
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
        job.strength, marked = selfcheck.ensure(
            selfcheck.Mark(
                V,
                F,
                lambda a: radial.embed_signs(V, F, signs, a, host=host),
                lambda V2, F2: read(V2, F2, secret),
                "".join(map(str, payload.tolist())),
                word.text_of(payload) if kind == "text" else None,
                secret,
            ),
            marked,
            job.strength,
            adjustable=opts.strength is None,
        )

        def marked_pm() -> ProgressiveMesh:  # awaited last: the key is made meanwhile
            pm, _ = building.result(lambda f, m: job.report(0.1 + 0.85 * f, m))
            return with_positions(pm, marked)

        job.bits = payload  # (the result's bits: the payload embedded)
        return finish_embed(job, marked, marked_pm if build else None, np.zeros(0, np.int64), None)


def _calibrated(V, F, signs, alpha, marked, host: radial.Host) -> tuple[float, np.ndarray]:
    """(margin, marked vertices) with the margin rescaled up to CALIBRATION_ROUNDS times so that the
    embedding's MRMS (the benchmark's surface distance on ``CALIBRATION_SAMPLES`` points, measured
    without a spatial index by ``metrics.displaced_surface_distance``) is TARGET_MRMS % of the
    bounding-box diagonal, clipped to ALPHA_RANGE: the same margin gives different distortions on
    different shapes, and spending the same budget on each buys robustness where the margin is cheap.
    The MRMS grows about linearly with the margin, not exactly, hence a second rescale. The reader does
    not need the margin (``EmbedResult.strength`` reports it)."""
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
    neighbours, then the "denoised" ones; see ``frames.read_statistics``), the stage of the reading plan that
    read each (``frame_stages``, R names of ``plan.STAGES``: what each frame pays of the p-value's budget),
    and the length ``n_word`` the reader reads;
    ``shares``, the same shape, each bin's share of the vertices (None: taken as equal), which weighs how
    reliable its reading is (``word_read``); ``mesh``, the mesh measured ("suspect", or the mesh a
    subdivided suspect was made from: ``frames.Frames.mesh``; the "denoised" frames': ``frames.mesh_of``);
    ``guess``, called by ``guess_word`` only
    (``frames.Frames.guess``: for a suspect on a coarse grid, the statistics of the suspect as it is or
    smoothed, and the length (an index into ``words``) whose bins show the most energy, else None)."""

    words: dict[int, np.ndarray]
    n_word: int
    frame_names: tuple[str, ...]
    frame_stages: tuple[str, ...]
    shares: Optional[dict[int, np.ndarray]] = None
    mesh: str = "suspect"
    guess: Optional[Callable[[], Optional[tuple[int, int, np.ndarray, np.ndarray]]]] = None

    def __post_init__(self):
        if len(self.frame_stages) != len(self.frame_names):
            raise ValueError("Statistics: one stage per frame read")

    @property
    def reserve(self) -> int:
        """The frames read with what the p-value's budget leaves (``plan.REST``)."""
        return sum(plan.stage(s).pays == plan.REST for s in self.frame_stages)

    def own_frame(self) -> "Statistics":
        """The same measurements in the suspect's own frame alone (the reader without the refinement)."""
        shares = None if self.shares is None else {n: s[:1] for n, s in self.shares.items()}
        return Statistics(
            {n: s[:1] for n, s in self.words.items()},
            self.n_word,
            self.frame_names[:1],
            self.frame_stages[:1],
            shares,
            self.mesh,
            self.guess,
        )

    def candidates(self) -> list[int]:
        """The Chase candidates read per kind in each frame (``plan.candidates`` of ``frame_stages``)."""
        return plan.candidates(self.frame_stages)


def bin_statistics(vertices, faces, config: ReaderConfig = READER, progress: Progress = None) -> Statistics:
    """The ``Statistics`` of a suspect, vertices (n, 3), faces (m, 3) (``frames.read_statistics``: its
    own, or those of the coarse mesh under it when it is a subdivided copy), read by the stages and settings
    of ``config``; ``progress(fraction, message)`` at the frames' stages."""
    V, F = check_mesh(vertices, faces)
    if len(F) == 0:
        raise MeshError("the suspect has no faces; the blind scheme reads a surface")
    words = [L + word.CHECK_BITS for L in word.PAYLOAD_BITS]
    got = frames.read_statistics(V, F, [_n_bins(n) for n in words], config, progress=progress)
    return Statistics(
        {n: np.stack([many[i][0] for many in got.statistics]) for i, n in enumerate(words)},
        words[got.index],
        got.names,
        got.stages,
        {n: np.stack([many[i][1] for many in got.statistics]) for i, n in enumerate(words)},
        got.mesh,
        got.guess,
    )


def word_read(
    stat: np.ndarray, secret: str, n_word: int, share: Optional[np.ndarray] = None, equalize: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """The word of length ``n_word`` as read from the bins' statistics (M,) in radial order (after
    ``radial.equalized``: hard decisions, erasures drawn from a keyed coin) (N,) uint8, and the score of
    each bit (N,) float64 (sign = the scrambled bit, 0 = an erasure). With the bins' shares of the
    vertices ``share`` (M,), each bin's statistic counts in units of its standard error (times
    sqrt(share): a bin mean of n vertices errs by about 1 / sqrt(12 n)), so that the scores' magnitudes
    rank the bits by how likely they are right (the Chase search's order, ``word.likely_flips``). The
    neighbours' interference is removed in those units: the margins make every bin's mark the same
    number of standard errors (``radial.bin_margins``), as the equalizer's model has it (one g for all
    bins), where in bin means they differ from bin to bin. ``equalize`` False: the bins as read
    (``ReaderConfig.equalize``)."""
    bit_of_bin, scramble = word.layout(secret, n_word, len(stat))
    if share is not None:
        stat = radial.in_standard_errors(stat, share)
    z = np.nan_to_num(radial.equalized(stat) if equalize else stat, nan=0.0)
    score = np.bincount(bit_of_bin, weights=z, minlength=n_word)
    got = (score > 0).astype(np.uint8)
    erased = score == 0
    got[erased] = keyed_bits(secret, f"blind-erasure:{n_word}", n_word)[erased]
    return got ^ scramble, score


def decide(stats: Statistics, secret: str, p_threshold: float = 1e-6, config: ReaderConfig = READER) -> Verdict:
    """The verdict from the ``Statistics`` of ``bin_statistics`` and a secret (module docstring): the
    chosen length in every frame, both kinds, every Chase candidate; the p-value is the union bound over
    all of these candidates (``plan.p_value`` over the stages of the frames read), so it stays exact when the
    reader keeps the best of them. ``config.equalize``: whether ``word_read`` equalizes the bins."""
    readings = []
    n_word = stats.n_word
    L = n_word - word.CHECK_BITS
    per_frame = np.atleast_2d(stats.words[n_word])
    shares = [None] * len(per_frame) if stats.shares is None else np.atleast_2d(stats.shares[n_word])
    n_frames = len(per_frame)
    per_reading = stats.candidates()
    chase = plan.chase_bits(n_frames - stats.reserve)
    for fi, stat in enumerate(per_frame):
        if per_reading[fi] == 0:
            continue
        got, score = word_read(stat, secret, n_word, shares[fi], config.equalize)
        candidates = got[None] ^ word.likely_flips(np.abs(score), per_reading[fi])  # row 0: the word as read
        # the flips of check bits leave the payload as it is: each distinct payload's check computed once
        _, first, which = np.unique(
            np.packbits(candidates[:, :L], axis=1), axis=0, return_index=True, return_inverse=True
        )
        for kind in word.KINDS:
            checks = word.check_bits(secret, kind, candidates[first, :L])
            matches = np.sum(candidates[:, L:] == checks[which.ravel()], axis=1)
            best = int(np.argmax(matches))  # the first candidate of the most matches
            m, cand = int(matches[best]), candidates[best]
            readings.append((metrics.binomial_tail(m, word.CHECK_BITS), -m, fi, L, kind, cand, score, got))
    p1, neg_m, fi, L, kind, cand, score, raw = min(readings, key=lambda r: (r[0], r[1], r[2]))
    p = plan.p_value(p1, stats.frame_stages)
    m = -neg_m
    payload = cand[:L]
    expected = word.check_bits(secret, kind, payload)
    marked = bool(p < p_threshold)  # (its check bits confirm the payload: a marked reading's is confirmed)
    detail = BlindDetail(
        payload_bits=L,
        check_bits=word.CHECK_BITS,
        mesh=frames.mesh_of(stats.frame_names[fi], stats.mesh),
        frame=stats.frame_names[fi],
        frame_index=fi,
        frames=n_frames,
        chase_bits=chase,
        reserve_frames=stats.reserve,
        candidates=per_reading[fi],
        payload_kind=kind if marked else None,
        word="".join(map(str, cand.tolist())) if marked else None,  # after the Chase search
        word_read="".join(map(str, raw.tolist())) if marked else None,
    )  # the hard decisions, before it
    return Verdict(
        marked=marked,
        p_value=p,
        bits="".join(map(str, payload.tolist())) if marked else "",
        payload=word.text_of(payload) if kind == "text" and marked else None,
        # matches / bit_errors / carriers_*: over the check bits (what the p-value counts)
        matches=m,
        bit_errors=word.CHECK_BITS - m,
        correlation=float(metrics.correlation(expected, cand[L:])),
        carriers_found=int(np.sum(score[L:] != 0)),
        carriers_total=word.CHECK_BITS,
        mode="blind",
        p_threshold=p_threshold,
        payload_confirmed=marked,
        detail=detail,
        scores=score,  # (N,) sign = the scrambled bit read, as every scheme's scores
        places=np.zeros((0, 3)),
        place_bits=np.zeros(0, np.int64),
    )


def guess_word(stats: Statistics, secret: str) -> tuple[np.ndarray, str]:
    """The reader's best guess of the word (payload + check bits) (N,) uint8, chosen without the check
    bits, and the mesh it was read on: the hard decisions (``word_read``) of the suspect's own frame at
    the length read, or for a suspect on a coarse grid those of ``Statistics.guess`` (the suspect as it
    is or smoothed, and the length, whichever shows the most mark energy: ``frames.guess_statistics``).
    Nothing confirms it: it is never part of a verdict; an owner may compare it with the payloads
    they marked when no mark is read."""
    found = None if stats.guess is None else stats.guess()
    if found is None:
        own = np.atleast_2d(stats.words[stats.n_word])[0]
        share = None if stats.shares is None else np.atleast_2d(stats.shares[stats.n_word])[0]
        n_word, stat, mesh = stats.n_word, own, stats.mesh
    else:
        steps, index, stat, share = found
        n_word, mesh = list(stats.words)[index], f"smoothing:-{steps}" if steps else "suspect"
    got, _ = word_read(stat, secret, n_word, share)
    return got, mesh


def read(vertices, faces, secret: str, p_threshold: float = 1e-6, config: ReaderConfig = READER) -> Verdict:
    """The blind reading: the payload read, its verdict and p-value. vertices (n, 3), faces (m, 3)
    of the suspect; ``secret`` from ``word.derive_secret``; ``config``, the reader's stages and settings."""
    return decide(bin_statistics(vertices, faces, config), secret, p_threshold, config)


def verify(
    vertices,
    faces,
    passphrase: str,
    p_threshold: float = 1e-6,
    config: ReaderConfig = READER,
    progress: Progress = None,
) -> Verdict:
    """The verdict of a suspect with the pass phrase: the keyed-waves reading (``waveread.read``) first, and
    when it finds no mark the histogram's (``read``, the baseline carrier's marks), each paying its share of
    the budget (``plan.waves_p_value``, ``plan.histogram_p_value``); the histogram's verdict when neither
    reads (no payload either way). ``progress(fraction, message)`` at the stages read, ending at 1.0."""
    report = progress or no_progress
    word.check_passphrase(passphrase)
    secret = word.derive_secret(passphrase)
    report(0.0, "reading keyed waves")
    waved = waveread.read(vertices, faces, secret, p_threshold)
    if waved.marked:
        report(1.0, "read")
        return waved
    stats = bin_statistics(vertices, faces, config, lambda f, m: report(0.1 + 0.8 * f, m))
    report(0.9, "reading the word")
    verdict = decide(stats, secret, p_threshold * (1.0 - plan.WAVES_SHARE), config)
    verdict = replace(verdict, p_value=plan.histogram_p_value(verdict.p_value), p_threshold=p_threshold)
    report(1.0, "read")
    return verdict


def load_key_data(key: WatermarkKey) -> None:
    """The blind scheme has no key file: a key that names it is refused."""
    raise KeyFileError("the blind scheme has no key file: read the mark with its pass phrase")


SCHEME = Scheme(
    NAME,
    WAVES_BUDGET,
    embed,
    verify,
    load_key_data,
    "read with a pass phrase alone (no key file); keyed waves in the solid's shape",
    PASS_PHRASE,
)

HISTOGRAM_SCHEME = Scheme(
    HISTOGRAM_NAME,
    DEFAULT_ALPHA,
    embed_histogram,
    verify,
    load_key_data,
    "the blind scheme's baseline carrier: the distribution of vertex norms, read with the pass phrase",
    PASS_PHRASE,
)
