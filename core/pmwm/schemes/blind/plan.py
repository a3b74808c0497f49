"""The blind reading as a plan: its stages in order, what each reads, and its share of the p-value's budget.

A verdict's p-value is a union bound: the reader keeps the best of many candidate words (every frame read,
both payload kinds, the Chase candidates of each reading, ``word.likely_flips``), and under the null each
candidate's 32 check bits are fair coins (``word.check_bits``), so P(m or more match) <= (candidates) *
P(Binomial(32, 1/2) >= m). The budget: a reading with every check bit right must stay below ``P_BEST``, that
is at most P_BEST * 2^32 = 4294 candidates in all. Every choice the stages make (which frames, which mesh,
which word length) is made on the bins' energy or shape, without the pass phrase, so the bound counts the
frames read and nothing else.

The stages (``STAGES``, in the order the reader takes them; ``frames.read_statistics`` runs them, a
``config.ReaderConfig`` says which it may read) declare how they pay:

- ``SHARED``: each frame the stage reads takes an equal part of the budget with the other shared frames read:
  2^C candidates per kind, C the most, up to ``CHASE_BITS``, that keeps them all within it (``chase_bits``);
- ``REST``: each frame takes an equal part of what the shared frames leave (``reserve_candidates``), so that
  adding these frames costs the others no Chase bits;
- ``MESH``: no frames of its own; it chooses the mesh the frame stages read (a coarse mesh under a subdivided
  suspect, the suspect with its smoothing undone), and the frames read there pay as above.

``candidates`` turns the stages of the frames read into each frame's candidates, ``union_bound`` counts them
all, and ``p_value`` is the one place a verdict's p-value is computed. The algorithm: docs/schemes/blind.md
(its section "The reading plan" is ``table()``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .radial import REFINE_BOUND
from .word import CHECK_BITS, KINDS

CHASE_BITS = 10  # the reader tries (at most) 2^10 candidate words per reading: the most likely flips
P_BEST = 1e-6  # the p-value of a reading with every check bit right stays below this

SHARED, REST, MESH = "shared", "rest", "mesh"

WAVES_SHARE = 1e-4  # the keyed-waves reading's share of a verdict's false-positive budget (the histogram's: the rest)


@dataclass(frozen=True)
class Stage:
    """One stage of the reading: its ``name`` (what ``config.ReaderConfig.stages`` lists), the ``frames`` it
    reads (their names, with the default crop shifts; none for a mesh stage), how it ``pays`` (SHARED, REST
    or MESH: module docstring), and ``when`` it applies, in words (the docs' table: a template filled with a
    ``config.ReaderConfig`` as ``c`` and ``radial.REFINE_BOUND`` as ``bound``)."""

    name: str
    frames: tuple[str, ...]
    pays: str
    when: str


STAGES: tuple[Stage, ...] = (
    Stage("own", ("own",), SHARED, "always: the suspect's area-weighted centre and quantile range"),
    Stage(
        "refined",
        ("refined",),
        SHARED,
        "the compass search (at most {bound:g} bin widths) finds a frame of more mark energy than the own one",
    ),
    Stage(
        "crop",
        ("crop", "crop-2", "crop-1", "crop+1", "crop+2"),
        SHARED,
        "the suspect has a planar cut, does not show the mark in full view, and the crop search finds a "
        "frame of more energy than the refined one (which it replaces); words of up to {c.crop_max_bins} bins",
    ),
    Stage(
        "coarse",
        (),
        MESH,
        "not in full view, and the mesh a subdivided suspect was made from (up to {c.max_undo} steps undone) "
        "shows {c.coarse_gain:g} times its excess energy per vertex",
    ),
    Stage(
        "unsmoothed",
        (),
        MESH,
        "still not in full view, and the suspect with steps of smoothing undone shows {c.coarse_gain:g} times "
        "the excess energy per vertex of the best so far",
    ),
    Stage(
        "denoised",
        ("denoised", "denoised-refined"),
        SHARED,
        "still not in full view, no crop frame, and the bins show their neighbours' interference (the blur "
        "of noise or quantization): the own and refined frames of the suspect after {c.denoise.steps} "
        "smoothing steps",
    ),
    Stage(
        "reserve",
        ("denoised", "denoised-refined"),
        REST,
        "the suspect lies on a coarse grid (at most {c.denoise.grid_values} values per axis), no crop frame "
        "and no denoised stage: the same frames, paid from what the others leave",
    ),
)

_PAYS = {s.name: s.pays for s in STAGES}


def stage(name: str) -> Stage:
    """The stage of ``STAGES`` called ``name``."""
    return next(s for s in STAGES if s.name == name)


def chase_bits(n_shared: int) -> int:
    """C, for 2^C Chase candidates per kind in each of ``n_shared`` shared frames: the most, up to CHASE_BITS,
    for which n_shared * 2 kinds * 2^C candidates keep a reading with all CHECK_BITS right below P_BEST
    (1 or 2 frames: 10; 3 or 4: 9; 5 or 6: 8)."""
    budget = P_BEST * 2.0**CHECK_BITS / (len(KINDS) * max(1, n_shared))  # candidates allowed per reading
    return int(min(CHASE_BITS, np.floor(np.log2(budget))))


def reserve_candidates(n_shared: int, n_rest: int) -> int:
    """The candidates per kind of each of ``n_rest`` REST frames read beside ``n_shared`` shared frames of
    2^``chase_bits(n_shared)`` each: what P_BEST leaves, shared equally (0 when nothing is left). With 2
    shared frames: 49 each (2 REST frames); with 1: 561."""
    main = len(KINDS) * max(1, n_shared) * 2 ** chase_bits(n_shared)
    return max(0, int(np.floor((P_BEST * 2.0**CHECK_BITS - main) / (len(KINDS) * max(1, n_rest)))))


def candidates(frame_stages: Sequence[str]) -> list[int]:
    """The Chase candidates per kind read in each frame, (R,), from the stage of each frame read (R names of
    ``STAGES``, in the order read): 2^``chase_bits`` in the SHARED frames, ``reserve_candidates`` in the
    REST ones."""
    pays = [_PAYS[s] for s in frame_stages]
    if MESH in pays:
        raise ValueError("a mesh stage reads no frames of its own")
    shared = pays.count(SHARED)
    full, rest = 2 ** chase_bits(shared), reserve_candidates(shared, len(pays) - shared)
    return [full if p == SHARED else rest for p in pays]


def union_bound(frame_stages: Sequence[str]) -> int:
    """Every candidate word the reading weighs: both kinds of every frame's ``candidates``."""
    return len(KINDS) * sum(candidates(frame_stages))


def p_value(p_one: float, frame_stages: Sequence[str]) -> float:
    """A verdict's p-value: the union bound over the candidates of the frames read (their stages,
    ``frame_stages``) times the best candidate's own tail probability ``p_one``, at most 1."""
    return float(min(1.0, union_bound(frame_stages) * p_one))


def waves_p_value(p_one: float, hypotheses: int) -> float:
    """The p-value of a keyed-waves reading (``waveread``): its union bound, ``hypotheses`` (every sign
    choice, mesh, step, length and kind it weighed, ``waveread.hypotheses``) times the best candidate's own tail
    probability ``p_one``, over its share ``WAVES_SHARE`` of the budget; at most 1."""
    return float(min(1.0, hypotheses * p_one / WAVES_SHARE))


def histogram_p_value(p: float) -> float:
    """A histogram reading's p-value (``p_value``) over its share, 1 - ``WAVES_SHARE``, of the budget:
    a pass phrase's verdict reads both carriers, and marked at p < alpha by either it is a false positive
    with probability at most alpha."""
    return float(min(1.0, p / (1.0 - WAVES_SHARE)))


def table(config) -> list[str]:
    """The plan as the lines of a Markdown table (docs/schemes/blind.md, "The reading plan"), its conditions
    with the settings of ``config`` (a ``config.ReaderConfig``)."""
    rows = ["| stage | frames | share of the budget | read when |", "|---|---|---|---|"]
    share = {
        SHARED: f"an equal part with the other shared frames (2^C candidates per kind, C <= {CHASE_BITS})",
        REST: "an equal part of what the shared frames leave",
        MESH: "none: the mesh the frame stages read",
    }
    for s in STAGES:
        when = s.when.format(c=config, bound=REFINE_BOUND)
        rows.append(f"| {s.name} | {', '.join(s.frames) or '-'} | {share[s.pays]} | {when} |")
    return rows
