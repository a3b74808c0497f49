"""The blind reader's tuning: frozen dataclasses holding every setting of its frames, meshes and searches.

``ReaderConfig`` is what ``blind.verify``, ``blind.bin_statistics`` and ``blind.decide`` take (default
``READER``); ``ReaderConfig.stages`` names the stages of the reading plan (``plan.STAGES``) it may read, so
that a caller (a test, a benchmark) can read without one by ``dataclasses.replace``. Nothing here involves
the pass phrase: the settings choose frames and meshes key-free, and the p-value's union bound counts what
was read (``plan``). The measurements behind the values: docs/decisions/080-blind-reader-frames.md,
081-blind-crop-frame-search.md; the algorithm: docs/schemes/blind.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .plan import STAGES


def _around(half: int, step: float) -> tuple[float, ...]:
    """1 + step * k for k in -half .. half, as numpy computes it (the crop search's widths around one)."""
    return tuple((1.0 + step * np.arange(-half, half + 1)).tolist())


def _linspace(a: float, b: float, n: int) -> tuple[float, ...]:
    return tuple(np.linspace(a, b, n).tolist())


@dataclass(frozen=True)
class CutConfig:
    """Which boundary loops are planar cuts (``crop.cut_planes``)."""

    min_edges: int = 12  # a boundary loop of fewer edges is not a cut
    max_loops: int = 32  # the largest loops are looked at, no more (a mesh may have thousands of holes)
    max_planes: int = 4  # the cut planes searched, those of the largest loops first
    thickness: float = 2.0  # a loop is planar when it lies within this many mean edge lengths (RMS) of a plane


@dataclass(frozen=True)
class CropConfig:
    """The crop frame search (``crop.crop_frames``): the family of candidate centres, the screening, the
    coarse and the fine stages. Lengths in bin widths of the suspect's own frame unless said otherwise."""

    lambda_max: float = 0.55  # the largest share of the area a crop may have taken (by the family's model)
    t_range: tuple[float, float] = (-0.1, 0.6)  # the cap's centroid from the cut, along its normal, in bbox diagonals
    reach: float = 40.0  # candidate centres within this many bin widths of the suspect's centroid
    lattice: float = 0.3  # spacing of the candidate centres (the mark shows within about 0.5)
    coarse_sample: int = 6000  # vertices scoring the candidate centres
    layers: tuple[float, ...] = tuple(0.9 * k for k in range(-4, 5))  # the family's plane and copies this far off it
    screen_lattice: float = 0.9  # the screening looks first at candidates this far apart (3 lattice)
    screen_top: float = 0.02  # then, near the best share of those (screen_min at least),
    expand: float = 0.65  # at the candidates a lattice apart within this many bin widths
    screen_widths: tuple[float, float] = (0.6, 1.6)  # every candidate: the bin widths, relative to the suspect's
    screen_cells: int = 4  # own, where its radii may add up in phase (``radial.in_phase``; cells per smallest
    screen_pad: int = 2  # width, counts zero-padded to twice their length)
    screen_keep: float = 0.05  # the share of one layer's candidates (screen_min at least) scored again
    screen_min: int = 64
    coarse_around: tuple[float, ...] = _around(6, 0.01)  # the widths within 6 % of each one's in-phase width
    coarse_phases: tuple[float, ...] = _linspace(-0.75, 0.75, 5)  # and these lo offsets
    top: int = 10  # candidates searched finely
    off_plane: tuple[float, ...] = _linspace(-1.5, 1.5, 11)  # offsets of a candidate off its family's plane
    fine_cells: int = 16  # the fine fit's in-phase width (``radial.in_phase``) over screen_widths,
    fine_pad: int = 8
    fine_step: float = 0.00125  # and the widths it tries: 0.125 % steps, 3 % either side of it
    fine_half: int = 24
    fine_phases: tuple[float, ...] = _linspace(-0.5, 0.5, 33)  # within half a bin: a whole bin off reads shifted
    fine_keep: int = 8  # widths of most energy at the phases fine_phases[::4], tried at every phase
    refined: int = 4  # of the top, the best (by the fine fit's energy) refined, on refine_first vertices
    refine_first: int = 8000
    final: int = 2  # of those, the best fitted again at their refined centre
    beyond: float = 2.0  # vertices beyond the suspect's hi + 2 reach bin widths + this many ranges are left out
    cut: CutConfig = field(default_factory=CutConfig)


@dataclass(frozen=True)
class UnsmoothConfig:
    """The smoothing undone (``frames.unsmoothing``): a coarse scan, then a fine search around its best."""

    lam: float = 0.1  # steps of this share towards the neighbours' mean, backwards
    stride: int = 3  # the scan takes steps of stride * lam, as many lam steps
    scan: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 16, 18, 20, 22, 25, 27)  # its steps measured
    sample: int = 10000  # vertices the scan's energies are measured on
    floor: float = 4e-4  # the scan's best excess energy per vertex must reach this to be looked at closely
    # (a cost gate, key-free: above what most unmarked meshes show, below weak marks smoothed 10 times)
    near: tuple[float, float] = (0.4, 1.1)  # then the counts between these shares of the scan's best count,
    fine: float = 0.07  # this share of it apart (at least 1), then every count around the best of them
    growth: float = 1.1  # no count at which the steps back have grown the mesh's bounding box by this factor


@dataclass(frozen=True)
class DenoiseConfig:
    """The denoised frames (``frames.with_denoised``) and the guess of a copy on a coarse grid."""

    lam: float = 0.1  # a reading whose bins show interference is also read after ``steps`` steps of smoothing
    steps: int = 3  # of this share
    refine_sample: int = 60000  # its refined frame is searched on this many vertices at most
    # (``radial.REFINE_SAMPLE`` for the others): its bins are blurred, so the sample's own noise moves the frame more
    guess_steps: tuple[int, ...] = (3, 6, 10, 16)  # a copy on a coarse grid is also guessed after these many steps
    grid_values: int = 4096  # a coarse grid: at most this many values per axis (12 bits), a quarter of the vertices


@dataclass(frozen=True)
class ReaderConfig:
    """Everything the blind reader is tuned by. ``stages``: the names of the plan's stages it may read
    (``plan.STAGES``, in the plan's order; a stage left out is never looked for). ``equalize``: the bins'
    neighbours' interference removed before the decisions (``radial.equalized``). ``workers``: measurements
    that overlap run in worker threads (``background.beside``); the result is the same either way."""

    stages: tuple[str, ...] = tuple(s.name for s in STAGES)
    full_view: float = 2.5e-3  # the mark in full view: the own or refined frame shows this much excess energy
    # per vertex (then no crop search, and no coarse mesh under a subdivided suspect is read)
    crop_max_bins: int = 96  # the crop search reads words of up to this many bins (payloads up to 64 bits)
    crop_shifts: tuple[int, ...] = (-2, -1, 1, 2)  # the crop frame is also read with lo, hi moved by these many bins
    max_undo: int = 3  # steps of subdivision undone under a suspect, one at a time
    coarse_gain: float = 2.0  # a coarse mesh is read when it shows this many times the excess energy per vertex
    # (and so is the suspect with its smoothing undone)
    equalize: bool = True
    workers: bool = True
    crop: CropConfig = field(default_factory=CropConfig)
    unsmooth: UnsmoothConfig = field(default_factory=UnsmoothConfig)
    denoise: DenoiseConfig = field(default_factory=DenoiseConfig)

    def __post_init__(self):
        unknown = set(self.stages) - {s.name for s in STAGES}
        if unknown:
            raise ValueError(f"no stage {sorted(unknown)} in the reading plan: {[s.name for s in STAGES]}")

    def reads(self, stage: str) -> bool:
        """Whether the plan's stage ``stage`` may be read (a name of ``plan.STAGES``)."""
        return stage in self.stages

    def without(self, *stages: str) -> "ReaderConfig":
        """This configuration with the named stages left out."""
        return replace(self, stages=tuple(s for s in self.stages if s not in stages))


READER = ReaderConfig()
"""The reader's defaults: the values its benchmarks were measured with."""
