"""The frames the blind reader reads in: the suspect's own, then the best of a refined one and a cropped
copy's; and the mesh it reads, the suspect or, when it is a subdivided copy, the mesh it was subdivided
from, or when it is a smoothed copy, the suspect with its smoothing undone (``read_statistics``).

1. The own frame (``radial.frame_of_areas``): centre and range recomputed on the suspect. The word length read
   is the one whose bins show the most mark energy there.
2. The refined frame (``radial.refine_frame``): within 1.5 bin widths of the own, where the mark's energy
   is largest. Attacks that move the frame by a fraction of a bin (noise, smoothing, simplification)
   leave the bins' bias in place; this finds the frame that shows it again.
3. When the suspect has a planar cut (``crop.cut_planes``: a boundary loop in a plane): the frame of a
   cropped copy (``crop.crop_frames``), for every word length up to CROP_MAX_BINS bins (payloads up to
   64 bits: 8 bytes of text). Every frame found serves every length (its lo and bin width, with that
   many bins), and the length and frame whose bins show the most excess energy are read, when they
   show more than the refined frame. A search for 96 bins can find a 64-bin mark's own bins (its widths
   span -40 % .. +60 %): read as 96 bins they show the mark diluted by the 32 bins beyond it (or the
   same, when nothing lies beyond: the shorter length is read on a tie), read as 64 the mark alone
   (scratch: 63 of 80 10 % crops and 23 of 64 posed 30 % crops read, against 62 and 22 with each length
   read in its own frame). Every length is searched: a frame searched for another length than the
   mark's can show much of its energy too (up to four fifths of the right length's, measured on the
   bunny and dragon), so the first strong one may be the wrong length. The search runs whenever there
   is a cut, unless the own or refined frame already shows the mark in full: an excess energy of
   ``FULL_VIEW`` per vertex or more (an asset cut flat before it was marked, read intact, re-exported
   or lightly noised: 2.9e-3 to 9.5e-3 per vertex on the bunny, dragon, Venus head and Igea cut 10 %
   and marked; 3.3e-3 to 9.8e-3 intact without the cut), where a cropped copy's frames show at most
   1.2e-3 (3 keys of each model, 10 % and posed 30 % crops, marked or not: the search still runs on
   every one of them). Below that, no level of the refined frame's energy tells a crop from an
   intact copy on every shape (excess energy on unmarked shapes reaches 26 on the dragon and 60 on a
   cropped Igea, against 16-30 for marked Venus heads after 8-bit quantization, Loop subdivision or 30
   smoothing iterations). The choice involves no pass phrase: the frames read and the union bound are
   those of a suspect without a cut.
4. With the crop frame, the same frame moved by one and two bins either way (``CROP_SHIFTS``): the crop
   search takes the integer part of lo from an area quantile, and a frame a whole bin off shows about
   the same energy but reads the word shifted. Reading the neighbours one bin off too (4 frames, so 9
   Chase bits instead of 10 at the same best p-value, ``word.chase_bits``) read the whole payload in 129
   of 160 scratch 10 % plane crops against 126, and in 11 of 64 crops of 30 % in a random pose against
   9; two bins off as well (6 frames, 8 Chase bits) read the same then. With the present search the
   second neighbours read one more of 160 scratch crops (149 against 148: the Venus head crop of the
   benchmark row "plane crop 10 %" that the others miss, lo two bins off) and lose none of those 160
   nor of another 112 (64 of 10 % and 48 posed of 30 %: 59 and 24 read either way): BENCHMARKS.md,
   ``blind-crop``.
   Picking the shift by the energy instead, key-free, read 87 of the 160: it picks the wrong one on
   every bunny crop.

5. When no mesh shows the mark in full view and no crop frame was taken, but the bins of the reading show
   their neighbours' interference (the blur of 8-bit quantization or 0.5 % noise: ``radial.interferes``):
   the own and refined frames of the suspect after DENOISE_STEPS steps of Laplacian smoothing, read
   beside the others ("denoised", "denoised-refined"; ``with_denoised``).
6. Otherwise, when the suspect lies on a coarse grid (``on_grid``: quantized to 12 bits or fewer per axis) and
   no crop frame was taken: the same denoised frames, read as reserve frames (``Frames.reserve``) with what
   the p-value's budget leaves beside the others (``word.reserve_candidates``), so that those keep their
   Chase bits. Quantization blurs the radii even where the bins do not show it: the Venus head's 8-bit copy
   of the benchmark's key 1002 reads 5 wrong bits in its own frame, 8 in the refined one, 2 (ranks 0 and 7
   of 64 by reliability) in the denoised one, found among its 49 candidates. With them as full frames (4
   frames, 9 Chase bits) the bundled bunny simplified and quantized to 8 bits lost 3 of 120 marks read
   with 10 and gained 1 (BENCHMARKS.md, ``session-29``).

Every choice here is made on the mark's energy or the bins' shape, which involve no pass phrase, so it
costs the p-value nothing; the union bound counts the frames read (1 to 4, or 6) and the reserve frames'
candidates.
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
from ...errors import MeshError
from ...features import row_norms, vertex_areas
from ...metrics import bbox_diagonal
from ...smoothing import mean_operator, smoothed, unsmoothing_steps
from ...subdivision import coarse_mesh
from .crop import crop_frames, cut_planes
from .radial import (QUANTILES, REFINE_SAMPLE, Frame, by_distance, excess_energy, frame_of_areas, in_standard_errors,
                     interferes, refine_frame, statistics_in, thinned, weighted_quantiles)

CROP_MAX_BINS = 96  # the crop search reads words of up to this many bins (payloads up to 64 bits)
FULL_VIEW = 2.5e-3  # the mark in full view: the own or refined frame shows this much excess energy per vertex
# (then no crop search, and no coarse mesh under a subdivided suspect is read)
CROP_SHIFTS = (-2, -1, 1, 2)  # the crop frame is also read with lo and hi moved by these many bins
MAX_UNDO = 3  # steps of subdivision undone under a suspect, one at a time
COARSE_GAIN = 2.0  # a coarse mesh is read when it shows this many times the excess energy per vertex
# (and so is the suspect with its smoothing undone)
UNSMOOTH_LAM = 0.1  # the smoothing undone: steps of this share towards the neighbours' mean, backwards
UNSMOOTH_STRIDE = 3  # the scan takes steps of UNSMOOTH_STRIDE * UNSMOOTH_LAM, as many UNSMOOTH_LAM steps
UNSMOOTH_SCAN = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 16, 18, 20, 22, 25, 27)  # its steps it measures at
UNSMOOTH_SAMPLE = 10000  # vertices the scan's energies are measured on
UNSMOOTH_FLOOR = 4e-4  # the scan's best excess energy per vertex must reach this to be looked at closely
# (a cost gate, key-free: unmarked organic meshes show 1.8e-4 to 5.1e-4, some CAD and low-poly ones more; 6e-4
# skipped weak marks smoothed 10 times: BENCHMARKS.md, blind-denoised)
UNSMOOTH_NEAR = (0.4, 1.1)  # then the counts between these shares of the scan's best count,
UNSMOOTH_FINE = 0.07  # this share of it apart (at least 1), then every count around the best of them
UNSMOOTH_GROWTH = 1.1  # no count at which the steps back have grown the mesh's bounding box by this factor
DENOISE_LAM = 0.1  # a reading whose bins show interference is also read after DENOISE_STEPS steps of smoothing
DENOISE_STEPS = 3  # of this share
DENOISE_REFINE_SAMPLE = 60000  # and its refined frame is searched on this many vertices at most (REFINE_SAMPLE
# for the others): its bins are blurred, so the sample's own noise moves the frame more
GUESS_STEPS = (3, 6, 10, 16)  # a copy on a coarse grid is also guessed after this many smoothing steps
GRID_VALUES = 4096  # a coarse grid: at most this many values on every axis (12 bits), and a quarter of the vertices


@dataclass
class Frames:
    """What ``read_statistics_frames`` measured: for each frame read (``names``: "own", then "refined", or
    "crop" and the crop frame moved by CROP_SHIFTS bins: "crop-2", "crop-1", "crop+1", "crop+2"; then
    "denoised" and "denoised-refined", read on the suspect smoothed: ``with_denoised``), per bin count,
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
    statistics: list[list[tuple[np.ndarray, np.ndarray]]]
    energy: float = 0.0
    mesh: str = "suspect"
    guess: Optional[Callable[[], Optional[tuple[int, int, np.ndarray, np.ndarray]]]] = None
    reserve: int = 0  # the last ``reserve`` frames are read with what the p-value's budget leaves (item 6)


def read_statistics(V: np.ndarray, F: np.ndarray, bin_counts) -> Frames:
    """``read_statistics_frames`` of the suspect V (n, 3), F (m, 3), or of the coarse mesh it was subdivided
    from (``pmwm.subdivision.coarse_mesh``, up to MAX_UNDO steps, one at a time) when that shows COARSE_GAIN
    times the excess energy per vertex (any, when that is not positive); the coarse meshes are only looked for
    when the suspect does not show the mark in full view (``FULL_VIEW``), and no further once one does. Under a
    1-to-4 step solved as Loop's, the original vertices as the copy has them are read too, the better of the two
    counting (``Frames.mesh`` "1-to-4"): an interpolating scheme (butterfly) keeps them where they were.

    Why: one step of Loop, sqrt(3) or Catmull-Clark subdivision smooths the original vertices and adds new
    ones, averages of their neighbours: the Venus head read no whole payload after Loop and 3 of 10
    after sqrt(3) (BENCHMARKS.md, ``blind-subdivision``). The coarse mesh solved from the new vertices is
    the marked mesh itself when the copy is exact. Per vertex, because the subdivided suspect's vertices
    are linear combinations of the coarse mesh's: its total energy counts the same information about
    four times, so a subdivided copy's coarse mesh shows about four times its energy per vertex (three
    for sqrt(3)), a subdivided mesh marked as it is about as much (its original vertices, a quarter of
    the marked ones) or less (the solved positions mix them); hence the factor 2 between. Scratch, bunny
    and Venus head, 2 keys: exact midpoint, Loop and sqrt(3) copies 2.9-19 times; Loop then 0.3 % noise
    3.7-6.8; Loop then 8-bit quantization 2.1-2.5 (bunny) and 3.1-3.4 (Venus head); a Loop-subdivided
    mesh marked as it is, then 8-bit quantized or 0.3 % noised, 0.96-1.08 for its original vertices as
    they are and 0.19-0.98 solved (read intact it is in full view). The choice involves no pass phrase,
    so the p-value's union bound is the chosen mesh's. Then, when still no mesh shows the mark in full
    view, the suspect with its smoothing undone (``unsmoothing``), read when it shows COARSE_GAIN times
    the excess energy per vertex of the best so far; and the suspect smoothed a little, beside the reading
    kept, when that reading's bins show the blur of noise (``with_denoised``), or as reserve frames on a copy
    on a coarse grid (module docstring, item 6), whose denoised frames a worker measures from the start."""
    area = vertex_areas(V, F)
    grid = on_grid(V)
    # a copy on a coarse grid is read in the denoised frames whatever else it shows (in full, or as reserve
    # frames: module docstring, item 6): measured in a worker from the start, with the smoothing operator
    # the reading shares (the unsmoothing scan, the guess)
    counts0 = edge_face_counts(F, len(V)) if grid else None
    operator = mean_operator(F, len(V), counts0) if grid else None
    with beside(grid, silent(denoised_frames), V, F, bin_counts, operator) as early:
        return _read_statistics(V, F, bin_counts, area, early, counts0, operator)


def _read_statistics(V: np.ndarray, F: np.ndarray, bin_counts, area: np.ndarray, early: Optional[Background],
                     counts0: Optional[tuple[np.ndarray, np.ndarray]], operator) -> Frames:
    """``read_statistics`` once the suspect's ``area`` is known; ``early``, the worker measuring the denoised
    frames of a copy on a coarse grid, ``counts0`` and ``operator`` its ``edge_face_counts`` and
    ``mean_operator`` (all None for another suspect)."""
    grid = early is not None
    got = read_statistics_frames(V, F, bin_counts, area)
    V0, F0 = V, F
    # the suspect's edges, for the coarse mesh's first look and the smoothing operator: both are looked for
    # when the mark is not in full view
    if counts0 is None and got.energy < FULL_VIEW:
        counts0 = edge_face_counts(F0, len(V0))
    rules: list[str] = []
    while got.energy < FULL_VIEW and len(rules) < MAX_UNDO:
        coarse = coarse_mesh(V, F, None if rules else counts0)
        if coarse is None:
            break
        tries = [(coarse.vertices, rules + [coarse.rule])]
        if coarse.rule == "loop":
            tries.append((V[coarse.original], rules + ["1-to-4"]))
        alt, steps = max(((read_statistics_frames(Vc, coarse.faces, bin_counts), steps) for Vc, steps in tries),
                         key=lambda r: r[0].energy)
        if alt.energy > COARSE_GAIN * max(got.energy, 0.0):
            got = dataclasses.replace(alt, mesh=" + ".join(reversed(steps)))
        rules.append(coarse.rule)
        V, F = coarse.vertices, coarse.faces
    if got.energy < FULL_VIEW:
        operator = mean_operator(F0, len(V0), counts0) if operator is None else operator
        # a reading that shows the blur has its denoised frames measured in a worker beside the unsmoothing
        # scan (which seldom replaces the reading), unless the early one measures them: on two cores the two
        # overlap
        blurred = _blurred(got)
        with beside(blurred and early is None, silent(denoised_frames), V0, F0, bin_counts, operator) as late:
            measuring = early or late
            steps = unsmoothing(V0, F0, bin_counts, COARSE_GAIN * max(got.energy, 0.0), area, operator)
            if steps is not None:
                got = dataclasses.replace(steps[1], mesh=f"smoothing:{steps[0]}")
                blurred = _blurred(got)
            if blurred:
                got = with_denoised(got, V0, F0, bin_counts, operator, measuring)
            elif grid:
                got = _with_reserve(got, V0, F0, bin_counts, operator, measuring)
    elif grid:
        got = _with_reserve(got, V0, F0, bin_counts, operator, early)
    return dataclasses.replace(got, guess=functools.cache(
        lambda: guess_statistics(V0, F0, bin_counts, operator, area) if grid else None))


def _with_reserve(got: Frames, V: np.ndarray, F: np.ndarray, bin_counts, operator,
                  measuring: Optional[Background] = None) -> Frames:
    """``got`` with the denoised frames of ``with_denoised`` as reserve frames (``Frames.reserve``; module
    docstring, item 6), for a suspect on a coarse grid; ``got`` itself when it was read in a crop frame."""
    if any(n.startswith("crop") for n in got.names):
        return got
    more = with_denoised(got, V, F, bin_counts, operator, measuring)
    return dataclasses.replace(more, reserve=len(more.names) - len(got.names))


def _blurred(got: Frames) -> bool:
    """Whether the reading ``got`` is also read in denoised frames: its own frame's bins show their
    neighbours' interference (``radial.interferes``) and no crop frame was taken."""
    return "crop" not in got.names and interferes(in_standard_errors(*got.statistics[0][got.index]))


def with_denoised(got: Frames, V: np.ndarray, F: np.ndarray, bin_counts, operator,
                  measuring: Optional[Background] = None) -> Frames:
    """``got`` with the own and refined frames of the suspect V (n, 3), F (m, 3) after DENOISE_STEPS steps of
    uniform Laplacian smoothing (``pmwm.smoothing.smoothed``, DENOISE_LAM each; ``operator``, its
    ``mean_operator``) read too, named "denoised" and "denoised-refined" (their mesh: ``mesh_of``); the
    word length read stays ``got``'s. ``measuring``: a ``Background`` already measuring them
    (``denoised_frames``), else they are measured here.

    Why: 8-bit quantization and 0.5 % noise move every vertex by a good part of a bin, independently of
    its neighbours, and blur the radii across the bins' edges; the mark is smooth over the surface, so a
    few steps of smoothing take out more of the blur than of the mark. Which copies read better so is
    not told by the energy (on the Venus head's copies it rose by 0.8-1.6 times, read or not), so both
    readings are read and the union bound counts their frames (up to 4: 9 Chase bits instead of 10). The
    caller (``read_statistics``) adds them only to a reading whose bins show the blur (``radial.interferes``,
    the equalizer's own judgement): the fewer Chase bits lose weak marks read intact (a 2,906-vertex blob
    marked at margin 0.05). Scratch (BENCHMARKS.md, ``blind-denoised``): 288 copies (bunny 6 keys, dragon
    5, Venus head 10, Igea 3; 8- and 7-bit quantization, 0.3 and 0.5 % noise, 5 and 30 smoothing
    iterations, 50 and 70 % simplification, Loop, Loop then 8-bit, a 10 % plane crop, none): 231 read
    against 219, none lost, the same with the extra frames on every copy not in full view or on the 49
    whose bins show the blur; 2 or 4 steps instead of 3 read 226 and 223. Not after a crop frame: its 6
    frames already spend the p-value's budget down to 8 Chase bits.

    The denoised refined frame is searched on up to DENOISE_REFINE_SAMPLE vertices, where the other frames'
    search takes REFINE_SAMPLE: with the mark blurred, the sample's own noise moves the frame the search
    finds. Measured on the bundled bunny (34,835 vertices: every vertex against every second one) marked
    at margins 0.05, 0.06 and 0.07 with 80 pass phrases, the 395 copies of 8-bit quantization and 0.5 %
    noise read in these frames: 215 whole payloads against 195 (24 gained, 4 lost); Igea's 8-bit copy of the
    benchmark's key 1008 is read (searched on every third vertex; not on every fourth). It costs a suspect that
    takes this path about 0.03 s on Igea (134,345 vertices), an unmarked Igea among them; every vertex would
    cost 0.13-0.2 s (BENCHMARKS.md, ``session-29``)."""
    more = measuring.result() if measuring is not None else denoised_frames(V, F, bin_counts, operator)
    if more is None:
        return got
    names = tuple("denoised" if n == "own" else f"denoised-{n}" for n in more.names)
    return dataclasses.replace(got, names=got.names + names, statistics=got.statistics + more.statistics)


def denoised_frames(V: np.ndarray, F: np.ndarray, bin_counts, operator) -> Optional[Frames]:
    """The own and refined frames (``read_statistics_frames``, no crop search) of the suspect V (n, 3), F (m, 3)
    after DENOISE_STEPS steps of smoothing (``operator``: its ``mean_operator``), for ``with_denoised``; None
    when smoothing flattened the surface to no area or no range."""
    X = smoothed(V, operator, DENOISE_LAM, DENOISE_STEPS)
    try:
        return read_statistics_frames(X, F, bin_counts, crop=False, refine_sample=DENOISE_REFINE_SAMPLE)
    except MeshError:
        return None


def on_grid(V: np.ndarray) -> bool:
    """Whether the vertices V (n, 3) lie on a coarse grid: every axis takes at most GRID_VALUES distinct
    values, and at most a quarter as many as there are vertices (a copy quantized to 12 bits or fewer per
    axis and not moved since). Key-free; a prefix of each axis rejects most meshes at a small cost."""
    limit = min(GRID_VALUES, len(V) // 4)
    cols = np.asarray(V, dtype=np.float64).T
    return all(len(unique_values(c[: 4 * limit + 1])) <= limit for c in cols) and \
        all(len(unique_values(c)) <= limit for c in cols)


def guess_statistics(V: np.ndarray, F: np.ndarray, bin_counts, operator=None, area: Optional[np.ndarray] = None
                     ) -> Optional[tuple[int, int, np.ndarray, np.ndarray]]:
    """(steps, index, stat (M,), share (M,)): the own frame's statistics (``statistics_in``) of the suspect
    V (n, 3), F (m, 3) as it is or after each of GUESS_STEPS steps of smoothing (DENOISE_LAM each; ``operator``
    and ``area``: its ``mean_operator`` and ``vertex_areas``, when the caller has them), at each bin count of
    ``bin_counts``: the copy and count (``index`` into ``bin_counts``, M bins) whose bins show the most excess
    energy; None when no surface has area and range. For the word a reader returns when it finds no mark
    (``blind.decide``).

    Why: quantization to 7 bits moves every vertex by up to half a grid step, several bins' worth of radius,
    independently of its neighbours; the mark is smooth over the surface, so smoothing takes out more of the
    blur than of the mark, and how much depends on the mesh (its density against the grid step). The energy,
    which involves no pass phrase, picks the count of steps, and the word length with it, as the reader picks
    its length (the blurred copy as it is can name another). On the benchmark's four models at 7 bits (20 keys
    each; 3 steps on the bunny, 3 or 6 on the dragon and the Venus head, 6 or 10 on Igea), the own frame's hard
    decisions of the 64-bit word err on 0.02-0.21 of the bits (mean per model) against 0.06-0.39 as the copy
    is; at 8 bits 0.005-0.064 against 0.005-0.073; at 9 bits it keeps the copy as it is, and at 6 bits
    nothing helps (BENCHMARKS.md, ``session-30``). The reader's verdict does not use it: only the word it
    returns when it reads no mark."""
    counts = list(bin_counts)
    operator = mean_operator(F, len(V)) if operator is None else operator
    X = np.asarray(V, dtype=np.float64)
    # ``smoothed``'s steps, one at a time
    views = zip(range(1, max(GUESS_STEPS, default=0) + 1), unsmoothing_steps(X, operator, -DENOISE_LAM))
    best: Optional[tuple[float, int, int, np.ndarray, np.ndarray]] = None
    for steps, X in itertools.chain([(0, X)], ((k, Y) for k, Y in views if k in GUESS_STEPS)):
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


def mesh_of(name: str, mesh: str) -> str:
    """The mesh a frame ``name`` of a ``Frames`` whose ``mesh`` is ``mesh`` was read on: the suspect
    smoothed by DENOISE_STEPS steps ("smoothing:-DENOISE_STEPS") for a "denoised" frame, else ``mesh``."""
    return f"smoothing:-{DENOISE_STEPS}" if name.startswith("denoised") else mesh


def unsmoothing(V: np.ndarray, F: np.ndarray, bin_counts, above: float, area: Optional[np.ndarray] = None,
                operator=None):
    """(steps, ``Frames``) of the suspect V (n, 3), F (m, 3) with that many steps of uniform Laplacian
    smoothing undone (``pmwm.smoothing``, UNSMOOTH_LAM each), the count whose own frame shows the most
    excess energy per vertex, when its frames show more than ``above``; else None. ``area`` (n,): the
    suspect's ``vertex_areas``, and ``operator`` its ``mean_operator``, when the caller has them.

    Why: smoothing leaves the mark in the copy but blurs the radii (each vertex moves inward by its own
    curvature) and the bins lose it across their edges. Smoothing damps the mesh's frequencies without
    mixing them, so steps taken back restore the radii and the mark, even after 50 iterations
    (BENCHMARKS.md, ``blind-unsmoothing``). The count is unknown: a scan measures the energy at
    UNSMOOTH_SCAN of its steps on UNSMOOTH_SAMPLE vertices (the surface's areas kept from the suspect: cheaper,
    but it peaks beyond the right count, up to twice), taking UNSMOOTH_STRIDE steps at once (a step of
    UNSMOOTH_STRIDE times the share is their product to first order in the share: a third of the sparse
    products for a scan that only places the count roughly), and when its best reaches UNSMOOTH_FLOOR
    per vertex (above what most unmarked meshes show), the own frame is measured in full over UNSMOOTH_NEAR of
    that count, every UNSMOOTH_FINE of it, then at every count around the best of those (stepping on
    from the count measured before it). Nothing involves the pass phrase: the union bound is that of the
    frames read. The scan takes 27 sparse products with the neighbour-mean operator, the full
    measurement up to 100 more (the scan runs on every suspect not read in full view, unmarked ones
    included: BENCHMARKS.md, ``verify-speed-blind``).

    Neither looks at a count where the steps back have grown the bounding box by UNSMOOTH_GROWTH: smoothing
    shrinks a mesh by a few percent at most (the benchmark's 50 iterations: 1 % of the bunny's diagonal, and
    as many steps back give it back), so more growth is the steps back amplifying what no smoothing damped
    (a crop's zigzag border, the finest detail: 1.2 times per step at the highest frequency), whose own
    frame shows a large energy that is not the mark's (a 10 % plane crop of the bunny was read after 83
    steps back, its bounding box 13,000 times as large, in place of its crop frame)."""
    area = vertex_areas(V, F) if area is None else area
    if not area.sum() > 0:
        return None
    operator = mean_operator(F, len(V)) if operator is None else operator
    weight = area / area.sum()
    sub = thinned(by_distance(V, area, weight @ V), UNSMOOTH_SAMPLE)
    ones = np.ones(len(sub))
    # no count that grows the bounding box by UNSMOOTH_GROWTH (scan: of the sample; fine search: of the mesh)
    scan_limit, limit = UNSMOOTH_GROWTH * bbox_diagonal(V[sub]), UNSMOOTH_GROWTH * bbox_diagonal(V)
    scan = {}
    scan_steps = unsmoothing_steps(V, operator, UNSMOOTH_STRIDE * UNSMOOTH_LAM)
    for j, X in zip(range(1, UNSMOOTH_SCAN[-1] + 1), scan_steps):
        m = j * UNSMOOTH_STRIDE  # (in steps of UNSMOOTH_LAM)
        if j in UNSMOOTH_SCAN:
            if bbox_diagonal(X[sub]) >= scan_limit:  # (steps back amplifying what smoothing never damped)
                break
            centre = weight @ X
            lo, hi = weighted_quantiles(row_norms(X[sub] - centre)[None], area[sub], [QUANTILES])[0]
            if hi > lo:
                scan[m] = max(excess_energy(st, share, len(sub))
                              for st, share in statistics_in(X[sub], ones, Frame(centre, lo, hi, 1), bin_counts))
    if not scan or max(scan.values()) < UNSMOOTH_FLOOR * len(sub):
        return None
    best = max(scan, key=scan.get)
    step = max(1, int(round(UNSMOOTH_FINE * best)))
    lo_m, hi_m = max(1, int(round(UNSMOOTH_NEAR[0] * best))), int(round(UNSMOOTH_NEAR[1] * best))
    (m, e, X, aX), (m0, X0) = _best_count(V, F, operator, bin_counts, range(lo_m, hi_m + 1, step), limit)
    if step > 1:  # every count around the best, stepped on from the count measured before it
        second, _ = _best_count(X0, F, operator, bin_counts,
                                [k for k in range(m - step + 1, m + step) if k != m and k > m0], limit, m0)
        if second[1] > e:
            m, e, X, aX = second
    if not np.isfinite(e):
        return None
    try:
        got = read_statistics_frames(X, F, bin_counts, aX)
    except MeshError:  # (a surface the steps back flattened to no area or no range: not this one)
        return None
    return (m, got) if got.energy > above else None


def _best_count(V: np.ndarray, F: np.ndarray, operator, bin_counts, counts, limit: float, start: int = 0
                ) -> tuple[tuple[int, float, np.ndarray, Optional[np.ndarray]], tuple[int, np.ndarray]]:
    """Of the step counts ``counts`` (ascending, above ``start``), the one whose unsmoothed vertices'
    own frame shows the most excess energy per vertex over ``bin_counts``: (count, energy, vertices
    (n, 3), their ``vertex_areas`` (n,)), energy -inf, V and None when ``counts`` is empty; and the
    count measured before it, with its vertices ((start, V) when none), for a finer search around it to
    step on from. V (n, 3): the vertices after ``start`` steps back. No count whose vertices' bounding-box
    diagonal reaches ``limit`` is measured (nor any after it)."""
    wanted = set(counts)
    best, before, last = (start, -np.inf, V, None), (start, V), (start, V)
    steps = unsmoothing_steps(V, operator, UNSMOOTH_LAM)
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


def read_statistics_frames(V: np.ndarray, F: np.ndarray, bin_counts,
                           area: Optional[np.ndarray] = None, crop: bool = True,
                           refine_sample: int = REFINE_SAMPLE) -> Frames:
    """The bins' statistics of the suspect V (n, 3), F (m, 3) for every count in ``bin_counts``, in the
    frames of the module docstring (with ``crop`` False, the own and refined frames only; the refined
    one searched on ``refine_sample`` vertices at most, ``radial.refine_frame``). ``area`` (n,): its
    ``vertex_areas``, when the caller has them."""
    counts = list(bin_counts)
    area = vertex_areas(V, F) if area is None else area
    fr, a = frame_of_areas(V, area, 1)
    total = float(a.sum())
    own = statistics_in(V, a, fr, counts)
    z_own = [excess_energy(stat, share, total) for stat, share in own]
    index = int(np.argmax(z_own))
    second, name, z = None, "", z_own[index]
    ref = refine_frame(V, a, fr, counts[index], refine_sample)
    if not (np.array_equal(ref.centre, fr.centre) and ref.lo == fr.lo and ref.hi == fr.hi):
        second, name = ref, "refined"
        z = excess_energy(*statistics_in(V, a, ref, [counts[index]])[0], total)
    # the mark in full view already (an asset cut flat before it was marked, intact or nearly): no search
    planes = cut_planes(V, F, fr.centre) if crop and z < FULL_VIEW * total else []
    searched = [j for j, n in enumerate(counts) if n <= CROP_MAX_BINS] if planes else []
    if searched:
        found = crop_frames(V, a, area, fr, planes, [counts[j] for j in searched])
        # every frame found serves every length: its lo and bin width, with that many bins
        read = [(excess_energy(*statistics_in(V, a, f, [counts[j]])[0], total), j, f)
                for g in found for j in searched
                for f in [Frame(g.centre, g.lo, g.lo + counts[j] * g.width, counts[j])]]
        zc, j, f = max(read, key=lambda r: r[0])
        if zc > z:
            second, name, index, z = f, "crop", j, zc
    if second is None:
        return Frames(index, ("own",), [own], z / total)
    if name != "crop":
        return Frames(index, ("own", name), [own, statistics_in(V, a, second, counts)], z / total)
    shifted = [Frame(second.centre, second.lo + k * second.width, second.hi + k * second.width, second.n_bins)
               for k in CROP_SHIFTS]
    return Frames(index, ("own", "crop", *(f"crop{k:+d}" for k in CROP_SHIFTS)),
                  [own, *(statistics_in(V, a, f, counts) for f in (second, *shifted))], z / total)
