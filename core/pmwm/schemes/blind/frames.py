"""The frames the blind reader reads in, and the mesh it reads them on (``read_statistics``).

The frames: the suspect's own (``radial.frame_of_areas``); a refined one near it (``radial.refine_frame``);
when the suspect has a planar cut and does not show the mark in full view, a cropped copy's (``crop``) and that
frame moved by one and two bins; when the bins show the blur of noise or quantization, the own and refined
frames of the suspect smoothed a little (``with_denoised``; on a coarse grid as reserve frames). The mesh: the
suspect, or the mesh a subdivided copy was made from, or the suspect with its smoothing undone. Every choice is
made on the mark's energy or the bins' shape, which involve no pass phrase; the union bound counts the frames
read (``plan``: the stages in order and what each pays). The settings: ``config.ReaderConfig``, whose
``stages`` say which of the plan's stages may be read. The algorithm: docs/schemes/blind.md; the measurements
behind the settings: docs/decisions/080-blind-reader-frames.md.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ...adjacency import edge_face_counts, unique_values
from ...background import Background, beside, silent
from ...base import Progress, no_progress
from ...errors import MeshError
from ...features import row_norms, vertex_areas
from ...metrics import bbox_diagonal
from ...smoothing import mean_operator, smoothed, unsmoothing_steps
from ...subdivision import coarse_mesh
from .config import READER, DenoiseConfig, ReaderConfig, UnsmoothConfig
from .crop import crop_frames, cut_planes
from .radial import (
    QUANTILES,
    REFINE_SAMPLE,
    Frame,
    by_distance,
    excess_energy,
    frame_of_areas,
    in_standard_errors,
    interferes,
    refine_frame,
    statistics_in,
    thinned,
    weighted_quantiles,
)


@dataclass
class Frames:
    """What ``read_statistics_frames`` measured: for each frame read (``names``: "own", then "refined", or
    "crop" and the crop frame moved by ``ReaderConfig.crop_shifts`` bins: "crop-2", "crop-1", "crop+1",
    "crop+2"; then "denoised" and "denoised-refined", read on the suspect smoothed: ``with_denoised``), the
    stage of the reading plan that read it (``stages``, names of ``plan.STAGES``: what it pays), per bin count,
    each bin's mean of r - 1/2 (M,) and its share of the vertices (M,); ``index``, the bin count to read (an
    index into the counts asked for); ``energy``, the excess energy per vertex (``excess_energy`` over the
    vertices' total weight) of the frame and count read; ``mesh``, the mesh read: "suspect", or the coarse mesh
    a subdivided suspect was made from, by the steps undone in the order they were applied ("loop", "sqrt3",
    "catmull-clark", "midpoint", "1-to-4" for a 1-to-4 step's original vertices as they are; several joined
    by " + "), or the suspect with k steps of smoothing undone ("smoothing:k", ``unsmoothing``); the
    "denoised" frames' own mesh: ``mesh_of``; ``guess`` (from ``read_statistics``), called only when the reader
    finds no mark (it measures once, then caches): for a suspect on a coarse grid (``on_grid``),
    ``guess_statistics`` over the counts, else None."""

    index: int
    names: tuple[str, ...]
    stages: tuple[str, ...]
    statistics: list[list[tuple[np.ndarray, np.ndarray]]]
    energy: float = 0.0
    mesh: str = "suspect"
    guess: Optional[Callable[[], Optional[tuple[int, int, np.ndarray, np.ndarray]]]] = None


def read_statistics(
    V: np.ndarray, F: np.ndarray, bin_counts, config: ReaderConfig = READER, progress: Progress = None
) -> Frames:
    """``read_statistics_frames`` of the suspect V (n, 3), F (m, 3), or of the coarse mesh it was subdivided
    from (``pmwm.subdivision.coarse_mesh``, up to ``config.max_undo`` steps, one at a time: the "coarse" stage)
    when that shows ``config.coarse_gain`` times the excess energy per vertex (any, when that is not positive);
    the coarse meshes are only looked for when the suspect does not show the mark in full view
    (``config.full_view``), and no further once one does. Under a
    1-to-4 step solved as Loop's, the original vertices as the copy has them are read too, the better of the two
    counting (``Frames.mesh`` "1-to-4"): an interpolating scheme (butterfly) keeps them where they were.

    Why: one step of Loop, sqrt(3) or Catmull-Clark subdivision smooths the original vertices and adds new
    ones, averages of their neighbours, which blurs the mark; the coarse mesh solved from the new vertices is
    the marked mesh itself when the copy is exact. Per vertex, because the subdivided suspect's vertices are
    linear combinations of the coarse mesh's: a subdivided copy's coarse mesh shows about four times its
    energy per vertex (three for sqrt(3)), a mesh subdivided and then marked about as much or less; hence the
    factor 2 between (measured: docs/decisions/080-blind-reader-frames.md). The choice involves no pass
    phrase, so the p-value's union bound is the chosen mesh's. Then, when still no mesh shows the mark in full
    view, the suspect with its smoothing undone (``unsmoothing``: the "unsmoothed" stage), read when it shows
    ``config.coarse_gain`` times the excess energy per vertex of the best so far; and the suspect smoothed a
    little, beside the reading kept, when that reading's bins show the blur of noise (``with_denoised``: the
    "denoised" stage), or as reserve frames on a copy on a coarse grid (``_with_reserve``: the "reserve"
    stage), whose denoised frames a worker measures from the start. A stage ``config.stages`` leaves out is
    not looked for. ``progress(fraction, message)`` before each stage taken."""
    report = progress or no_progress
    report(0.0, "measuring the suspect")
    area = vertex_areas(V, F)
    grid = on_grid(V, config.denoise.grid_values)
    # a copy on a coarse grid is read in the denoised frames whatever else it shows (in full, or as reserve
    # frames: ``_with_reserve``): measured in a worker from the start, with the smoothing operator
    # the reading shares (the unsmoothing scan, the guess)
    counts0 = edge_face_counts(F, len(V)) if grid else None
    operator = mean_operator(F, len(V), counts0) if grid else None
    early_denoised = grid and config.workers and (config.reads("denoised") or config.reads("reserve"))
    with beside(early_denoised, silent(denoised_frames), V, F, bin_counts, operator, config) as early:
        return _read_statistics(V, F, bin_counts, area, grid, early, counts0, operator, config, report)


def _read_statistics(
    V: np.ndarray,
    F: np.ndarray,
    bin_counts,
    area: np.ndarray,
    grid: bool,
    early: Optional[Background],
    counts0: Optional[tuple[np.ndarray, np.ndarray]],
    operator,
    config: ReaderConfig,
    report: Callable[[float, str], None] = no_progress,
) -> Frames:
    """``read_statistics`` once the suspect's ``area`` is known; ``grid``, whether it lies on a coarse grid;
    ``early``, the worker measuring the denoised frames of a copy on a coarse grid (None when none does),
    ``counts0`` and ``operator`` its ``edge_face_counts`` and ``mean_operator`` (None off a grid);
    ``report(fraction, message)`` the progress."""
    full_view = config.full_view
    report(0.1, "reading the suspect's frames")
    got = read_statistics_frames(V, F, bin_counts, area, config=config, progress=lambda f, m: report(0.1 + 0.3 * f, m))
    V0, F0 = V, F
    # the suspect's edges, for the coarse mesh's first look and the smoothing operator: both are looked for
    # when the mark is not in full view
    if counts0 is None and got.energy < full_view:
        counts0 = edge_face_counts(F0, len(V0))
    rules: list[str] = []
    while config.reads("coarse") and got.energy < full_view and len(rules) < config.max_undo:
        step = 0.4 + 0.1 * len(rules)
        report(step, "looking for a mesh it was subdivided from")
        coarse = coarse_mesh(V, F, None if rules else counts0, progress=lambda f, m, s=step: report(s + 0.08 * f, m))
        if coarse is None:
            break
        tries = [(coarse.vertices, rules + [coarse.rule])]
        if coarse.rule == "loop":
            tries.append((V[coarse.original], rules + ["1-to-4"]))
        alt, steps = max(
            ((read_statistics_frames(Vc, coarse.faces, bin_counts, config=config), steps) for Vc, steps in tries),
            key=lambda r: r[0].energy,
        )
        if alt.energy > config.coarse_gain * max(got.energy, 0.0):
            got = dataclasses.replace(alt, mesh=" + ".join(reversed(steps)))
        rules.append(coarse.rule)
        V, F = coarse.vertices, coarse.faces
    if got.energy < full_view:
        operator = mean_operator(F0, len(V0), counts0) if operator is None else operator
        # a reading that shows the blur has its denoised frames measured in a worker beside the unsmoothing
        # scan (which seldom replaces the reading), unless the early one measures them: on two cores the two
        # overlap
        blurred = _blurred(got, config)
        late_denoised = blurred and early is None and config.workers
        with beside(late_denoised, silent(denoised_frames), V0, F0, bin_counts, operator, config) as late:
            measuring = early or late
            report(0.7, "undoing a smoothing")
            steps = None
            if config.reads("unsmoothed"):
                steps = unsmoothing(
                    V0, F0, bin_counts, config.coarse_gain * max(got.energy, 0.0), area, operator, config
                )
            if steps is not None:
                got = dataclasses.replace(steps[1], mesh=f"smoothing:{steps[0]}")
                blurred = _blurred(got, config)
            report(0.85, "reading the suspect smoothed")
            if blurred:
                got = with_denoised(got, V0, F0, bin_counts, operator, measuring, config)
            elif grid:
                got = _with_reserve(got, V0, F0, bin_counts, operator, measuring, config)
    elif grid:
        report(0.85, "reading the suspect smoothed")
        got = _with_reserve(got, V0, F0, bin_counts, operator, early, config)
    return dataclasses.replace(
        got,
        guess=functools.cache(
            lambda: guess_statistics(V0, F0, bin_counts, operator, area, config.denoise) if grid else None
        ),
    )


def _with_reserve(
    got: Frames,
    V: np.ndarray,
    F: np.ndarray,
    bin_counts,
    operator,
    measuring: Optional[Background],
    config: ReaderConfig,
) -> Frames:
    """``got`` with the denoised frames of ``with_denoised`` as reserve frames (the "reserve" stage), for a
    suspect on a coarse grid; ``got`` itself when it was read in a crop frame, or when ``config`` leaves the
    stage out. Why: quantization blurs the radii even where the bins do not show it, and reserve frames are
    read with what the p-value's budget leaves (``plan.reserve_candidates``), so that the other frames keep
    their Chase bits."""
    if any(n.startswith("crop") for n in got.names) or not config.reads("reserve"):
        return got
    return with_denoised(got, V, F, bin_counts, operator, measuring, config, stage="reserve")


def _blurred(got: Frames, config: ReaderConfig) -> bool:
    """Whether the reading ``got`` is also read in denoised frames: ``config`` reads the "denoised" stage, its
    own frame's bins show their neighbours' interference (``radial.interferes``) and no crop frame was taken."""
    return (
        config.reads("denoised")
        and "crop" not in got.names
        and interferes(in_standard_errors(*got.statistics[0][got.index]))
    )


def with_denoised(
    got: Frames,
    V: np.ndarray,
    F: np.ndarray,
    bin_counts,
    operator,
    measuring: Optional[Background] = None,
    config: ReaderConfig = READER,
    stage: str = "denoised",
) -> Frames:
    """``got`` with the own and refined frames of the suspect V (n, 3), F (m, 3) after ``config.denoise.steps``
    steps of uniform Laplacian smoothing (``pmwm.smoothing.smoothed``, ``config.denoise.lam`` each;
    ``operator``, its ``mean_operator``) read too, named "denoised" and "denoised-refined" (their mesh:
    ``mesh_of``), read by the plan's ``stage`` ("denoised", or "reserve": what they pay); the word length read
    stays ``got``'s. ``measuring``: a ``Background`` already measuring them (``denoised_frames``), else they are
    measured here.

    Why: 8-bit quantization and 0.5 % noise move every vertex by a good part of a bin, independently of
    its neighbours, and blur the radii across the bins' edges; the mark is smooth over the surface, so a
    few steps of smoothing take out more of the blur than of the mark. The energy does not tell which copies
    read better so, so both readings are read and the union bound counts their frames (up to 4: 9 Chase bits
    instead of 10). The caller (``read_statistics``) adds them only to a reading whose bins show the blur
    (``radial.interferes``): the fewer Chase bits lose weak marks read intact. Not after a crop frame: its 6
    frames already spend the p-value's budget down to 8 Chase bits. The denoised refined frame is searched on
    up to ``config.denoise.refine_sample`` vertices, where the other frames' search takes
    ``radial.REFINE_SAMPLE``: with the mark blurred, the sample's own noise moves the frame the search finds
    (measured: docs/decisions/080-blind-reader-frames.md)."""
    more = measuring.result() if measuring is not None else denoised_frames(V, F, bin_counts, operator, config)
    if more is None:
        return got
    names = tuple("denoised" if n == "own" else f"denoised-{n}" for n in more.names)
    return dataclasses.replace(
        got,
        names=got.names + names,
        stages=got.stages + (stage,) * len(names),
        statistics=got.statistics + more.statistics,
    )


def denoised_frames(
    V: np.ndarray, F: np.ndarray, bin_counts, operator, config: ReaderConfig = READER
) -> Optional[Frames]:
    """The own and refined frames (``read_statistics_frames``, no crop search) of the suspect V (n, 3), F (m, 3)
    after ``config.denoise.steps`` steps of smoothing (``operator``: its ``mean_operator``), for
    ``with_denoised``; None when smoothing flattened the surface to no area or no range."""
    X = smoothed(V, operator, config.denoise.lam, config.denoise.steps)
    try:
        return read_statistics_frames(
            X, F, bin_counts, crop=False, refine_sample=config.denoise.refine_sample, config=config
        )
    except MeshError:
        return None


def on_grid(V: np.ndarray, grid_values: int = READER.denoise.grid_values) -> bool:
    """Whether the vertices V (n, 3) lie on a coarse grid: every axis takes at most ``grid_values`` distinct
    values, and at most a quarter as many as there are vertices (a copy quantized to 12 bits or fewer per
    axis and not moved since). Key-free; a prefix of each axis rejects most meshes at a small cost."""
    limit = min(grid_values, len(V) // 4)
    cols = np.asarray(V, dtype=np.float64).T
    return all(len(unique_values(c[: 4 * limit + 1])) <= limit for c in cols) and all(
        len(unique_values(c)) <= limit for c in cols
    )


def guess_statistics(
    V: np.ndarray,
    F: np.ndarray,
    bin_counts,
    operator=None,
    area: Optional[np.ndarray] = None,
    cfg: DenoiseConfig = READER.denoise,
) -> Optional[tuple[int, int, np.ndarray, np.ndarray]]:
    """(steps, index, stat (M,), share (M,)): the own frame's statistics (``statistics_in``) of the suspect
    V (n, 3), F (m, 3) as it is or after each of ``cfg.guess_steps`` steps of smoothing (``cfg.lam`` each; ``operator``
    and ``area``: its ``mean_operator`` and ``vertex_areas``, when the caller has them), at each bin count of
    ``bin_counts``: the copy and count (``index`` into ``bin_counts``, M bins) whose bins show the most excess
    energy; None when no surface has area and range. For the word a reader returns when it finds no mark
    (``blind.decide``).

    Why: quantization to 7 bits moves every vertex by up to half a grid step, several bins' worth of radius,
    independently of its neighbours; the mark is smooth over the surface, so smoothing takes out more of the
    blur than of the mark, and how much depends on the mesh (its density against the grid step). The energy,
    which involves no pass phrase, picks the count of steps, and the word length with it, as the reader picks
    its length. It errs on fewer bits than the copy as it is at 7 and 8 bits (measured:
    docs/decisions/080-blind-reader-frames.md). The reader's verdict does not use it: only the word it
    returns when it reads no mark."""
    counts = list(bin_counts)
    operator = mean_operator(F, len(V)) if operator is None else operator
    X = np.asarray(V, dtype=np.float64)
    # ``smoothed``'s steps, one at a time
    views = zip(range(1, max(cfg.guess_steps, default=0) + 1), unsmoothing_steps(X, operator, -cfg.lam))
    best: Optional[tuple[float, int, int, np.ndarray, np.ndarray]] = None
    for steps, X in itertools.chain([(0, X)], ((k, Y) for k, Y in views if k in cfg.guess_steps)):
        areas = area if steps == 0 and area is not None else vertex_areas(X, F)
        try:
            fr, a = frame_of_areas(X, areas, 1)
        except MeshError:
            continue
        for index, (stat, share) in enumerate(statistics_in(X, a, fr, counts)):
            e = excess_energy(stat, share, float(a.sum()))
            if best is None or e > best[0]:
                best = (e, steps, index, stat, share)
    return None if best is None else best[1:]


def mesh_of(name: str, mesh: str, cfg: DenoiseConfig = READER.denoise) -> str:
    """The mesh a frame ``name`` of a ``Frames`` whose ``mesh`` is ``mesh`` was read on: the suspect
    smoothed by ``cfg.steps`` steps ("smoothing:-3") for a "denoised" frame, else ``mesh``."""
    return f"smoothing:-{cfg.steps}" if name.startswith("denoised") else mesh


def unsmoothing(
    V: np.ndarray,
    F: np.ndarray,
    bin_counts,
    above: float,
    area: Optional[np.ndarray] = None,
    operator=None,
    config: ReaderConfig = READER,
):
    """(steps, ``Frames``) of the suspect V (n, 3), F (m, 3) with that many steps of uniform Laplacian
    smoothing undone (``pmwm.smoothing``, ``cfg.lam`` each, ``cfg = config.unsmooth``: names below without the
    prefix), the count whose own frame shows the most
    excess energy per vertex, when its frames show more than ``above``; else None. ``area`` (n,): the
    suspect's ``vertex_areas``, and ``operator`` its ``mean_operator``, when the caller has them.

    Why: smoothing leaves the mark in the copy but blurs the radii (each vertex moves inward by its own
    curvature) and the bins lose it across their edges. Smoothing damps the mesh's frequencies without
    mixing them, so steps taken back restore the radii and the mark. The count is unknown: a scan measures the
    energy at ``scan`` of its steps on ``sample`` vertices (the surface's areas kept from the suspect:
    cheaper, but it peaks beyond the right count, up to twice), taking ``stride`` steps at once (a step of
    ``stride`` times the share is their product to first order in the share), and when its best reaches
    ``floor`` per vertex (above what most unmarked meshes show), the own frame is measured in full over
    ``near`` of that count, every ``fine`` of it, then at every count around the best of those
    (stepping on from the count measured before it). Nothing involves the pass phrase: the union bound is that
    of the frames read.

    Neither looks at a count where the steps back have grown the bounding box by ``growth``: smoothing
    shrinks a mesh by a few percent at most, so more growth is the steps back amplifying what no smoothing
    damped (a crop's zigzag border, the finest detail), whose own frame shows a large energy that is not the
    mark's (measured: docs/decisions/080-blind-reader-frames.md)."""
    cfg = config.unsmooth
    area = vertex_areas(V, F) if area is None else area
    if not area.sum() > 0:
        return None
    operator = mean_operator(F, len(V)) if operator is None else operator
    weight = area / area.sum()
    sub = thinned(by_distance(V, area, weight @ V), cfg.sample)
    ones = np.ones(len(sub))
    # no count that grows the bounding box by ``growth`` (scan: of the sample; fine search: of the mesh)
    scan_limit, limit = cfg.growth * bbox_diagonal(V[sub]), cfg.growth * bbox_diagonal(V)
    scan = {}
    scan_steps = unsmoothing_steps(V, operator, cfg.stride * cfg.lam)
    for j, X in zip(range(1, cfg.scan[-1] + 1), scan_steps):
        m = j * cfg.stride  # (in steps of ``lam``)
        if j in cfg.scan:
            if bbox_diagonal(X[sub]) >= scan_limit:  # (steps back amplifying what smoothing never damped)
                break
            centre = weight @ X
            lo, hi = weighted_quantiles(row_norms(X[sub] - centre)[None], area[sub], [QUANTILES])[0]
            if hi > lo:
                scan[m] = max(
                    excess_energy(st, share, len(sub))
                    for st, share in statistics_in(X[sub], ones, Frame(centre, lo, hi, 1), bin_counts)
                )
    if not scan or max(scan.values()) < cfg.floor * len(sub):
        return None
    best = max(scan, key=scan.get)
    step = max(1, int(round(cfg.fine * best)))
    lo_m, hi_m = max(1, int(round(cfg.near[0] * best))), int(round(cfg.near[1] * best))
    (m, e, X, aX), (m0, X0) = _best_count(V, F, operator, bin_counts, range(lo_m, hi_m + 1, step), limit, cfg)
    if step > 1:  # every count around the best, stepped on from the count measured before it
        second, _ = _best_count(
            X0, F, operator, bin_counts, [k for k in range(m - step + 1, m + step) if k != m and k > m0], limit, cfg, m0
        )
        if second[1] > e:
            m, e, X, aX = second
    if not np.isfinite(e):
        return None
    try:
        got = read_statistics_frames(X, F, bin_counts, aX, config=config)
    except MeshError:  # (a surface the steps back flattened to no area or no range: not this one)
        return None
    return (m, got) if got.energy > above else None


def _best_count(
    V: np.ndarray, F: np.ndarray, operator, bin_counts, counts, limit: float, cfg: UnsmoothConfig, start: int = 0
) -> tuple[tuple[int, float, np.ndarray, Optional[np.ndarray]], tuple[int, np.ndarray]]:
    """Of the step counts ``counts`` (ascending, above ``start``), the one whose unsmoothed vertices'
    own frame shows the most excess energy per vertex over ``bin_counts``: (count, energy, vertices
    (n, 3), their ``vertex_areas`` (n,)), energy -inf, V and None when ``counts`` is empty; and the
    count measured before it, with its vertices ((start, V) when none), for a finer search around it to
    step on from. V (n, 3): the vertices after ``start`` steps back. No count whose vertices' bounding-box
    diagonal reaches ``limit`` is measured (nor any after it)."""
    wanted = set(counts)
    best, before, last = (start, -np.inf, V, None), (start, V), (start, V)
    steps = unsmoothing_steps(V, operator, cfg.lam)
    for m, X in zip(range(start + 1, max(wanted, default=start) + 1), steps):
        if m in wanted:
            if bbox_diagonal(X) >= limit:
                break
            area = vertex_areas(X, F)
            try:
                fr, a = frame_of_areas(X, area, 1)
            except MeshError:
                continue
            e = max(excess_energy(st, share, a.sum()) for st, share in statistics_in(X, a, fr, bin_counts)) / a.sum()
            if e > best[1]:
                best, before = (m, e, X, area), last
            last = (m, X)
    return best, before


def read_statistics_frames(
    V: np.ndarray,
    F: np.ndarray,
    bin_counts,
    area: Optional[np.ndarray] = None,
    crop: bool = True,
    refine_sample: int = REFINE_SAMPLE,
    config: ReaderConfig = READER,
    progress: Progress = None,
) -> Frames:
    """The bins' statistics of the suspect V (n, 3), F (m, 3) for every count in ``bin_counts``, in the
    frames of the module docstring that ``config`` reads (the stages "own", "refined", "crop"; with ``crop``
    False, the own and refined frames only; the refined one searched on ``refine_sample`` vertices at most,
    ``radial.refine_frame``). ``area`` (n,): its ``vertex_areas``, when the caller has them;
    ``progress(fraction, message)`` during the crop search (``crop_frames``)."""
    counts = list(bin_counts)
    area = vertex_areas(V, F) if area is None else area
    fr, a = frame_of_areas(V, area, 1)
    total = float(a.sum())
    own = statistics_in(V, a, fr, counts)
    z_own = [excess_energy(stat, share, total) for stat, share in own]
    index = int(np.argmax(z_own))
    second, name, z = None, "", z_own[index]
    if config.reads("refined"):
        ref = refine_frame(V, a, fr, counts[index], refine_sample)
        if not (np.array_equal(ref.centre, fr.centre) and ref.lo == fr.lo and ref.hi == fr.hi):
            second, name = ref, "refined"
            z = excess_energy(*statistics_in(V, a, ref, [counts[index]])[0], total)
    # the mark in full view already (an asset cut flat before it was marked, intact or nearly): no search
    search = crop and config.reads("crop") and z < config.full_view * total
    planes = cut_planes(V, F, fr.centre, config.crop.cut) if search else []
    searched = [j for j, n in enumerate(counts) if n <= config.crop_max_bins] if planes else []
    if searched:
        (progress or no_progress)(0.0, "looking for a cropped copy's frame")
        found = crop_frames(V, a, area, fr, planes, [counts[j] for j in searched], config.crop, progress)
        zc, j, f = best_length(V, a, found, counts, searched)
        if zc > z:
            second, name, index, z = f, "crop", j, zc
    if second is None:
        return Frames(index, ("own",), ("own",), [own], z / total)
    if name != "crop":
        return Frames(index, ("own", name), ("own", name), [own, statistics_in(V, a, second, counts)], z / total)
    shifts = config.crop_shifts
    shifted = [
        Frame(second.centre, second.lo + k * second.width, second.hi + k * second.width, second.n_bins) for k in shifts
    ]
    return Frames(
        index,
        ("own", "crop", *(f"crop{k:+d}" for k in shifts)),
        ("own",) + ("crop",) * (1 + len(shifts)),
        [own, *(statistics_in(V, a, f, counts) for f in (second, *shifted))],
        z / total,
    )


def best_length(
    V: np.ndarray, a: np.ndarray, found: list[Frame], counts: list[int], searched: list[int]
) -> tuple[float, int, Frame]:
    """Of the frames the crop search ``found`` (one per searched count), each read at every searched length
    (its lo and bin width, with that many bins: ``counts[j]`` for j in ``searched``), the one of most excess
    energy (``excess_energy`` on the vertices V (n, 3) of weights a (n,)): (energy, j, frame). Why: the search
    for a longer word can find a shorter mark's own bins, which hold the mark read at the shorter length."""
    total = float(a.sum())
    read = [
        (excess_energy(*statistics_in(V, a, f, [counts[j]])[0], total), j, f)
        for g in found
        for j in searched
        for f in [Frame(g.centre, g.lo, g.lo + counts[j] * g.width, counts[j])]
    ]
    return max(read, key=lambda r: r[0])
