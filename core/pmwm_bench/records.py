"""What the runners record (one row per trial and per embedding) and how cells aggregate: the robustness
runner's ``Trial`` and ``Distortion``, the sweep's ``SweepEmbedding``, ``SweepTrial``, ``SweepPoint``,
``EqualMrms`` and ``SweepResults``.

``Trial`` and ``Distortion`` are written as they are to ``trials.json``; their field names are the
raw-results format of the robustness results (``benchmarks/results/robustness/``), so they do not change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Optional, Sequence, TypeVar

import numpy as np

from pmwm import metrics as M

T = TypeVar("T")


@dataclass
class Trial:
    """One attacked copy read back: ``matches`` of ``n_bits`` right; ``failed`` is the reader's error
    message when it could not read the copy at all (counted as chance: BER 0.5, correlation 0)."""

    protocol: str  # "paper" | "benchmark"
    model: str
    method: str
    group: str
    label: str
    key: int
    n_bits: int
    matches: int
    ber: float
    correlation: float
    failed: str = ""


@dataclass
class Distortion:
    """The embedding distortion of one marked mesh against its original."""

    protocol: str
    model: str
    method: str
    key: int
    n_bits: int
    vsnr: float
    vsnr_uncentred: float
    psnr: float
    rmse_percent: float  # vertex RMSE, % of the bbox diagonal
    energy_per_bit: float
    r_max: float  # max vertex norm of the marked mesh (paper noise reference)
    d_bar: float  # mean vertex norm of the marked mesh (benchmark noise reference)
    mrms_percent: float = float("nan")
    hausdorff_percent: float = float("nan")
    embed_seconds: float = 0.0


@dataclass
class BenchResults:
    """Everything one ``run_bench`` measured, and the markdown it rendered."""

    trials: list[Trial] = field(default_factory=list)
    distortions: list[Distortion] = field(default_factory=list)
    models: dict[str, dict] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    markdown: str = ""


@dataclass
class Cell:
    """A table cell: mean and std over the keys; ``chance`` when the pooled correct bits are not
    significant against Binomial(bits, 1/2) at p < 0.01 (one-sided)."""

    corr_mean: float
    corr_std: float
    ber_mean: float
    ber_std: float
    chance: bool
    failed: int
    n: int


def cell(trials: Iterable[Trial]) -> Optional[Cell]:
    """The cell of a group of trials (the keys of one setting), None when there is none."""
    ts = list(trials)
    if not ts:
        return None
    corr = np.array([t.correlation for t in ts])
    ber = np.array([t.ber for t in ts])
    matches = sum(t.matches for t in ts)
    total = sum(t.n_bits for t in ts)
    chance = M.binomial_tail(matches, total) >= 0.01
    return Cell(
        float(corr.mean()),
        float(corr.std()),
        float(ber.mean()),
        float(ber.std()),
        chance,
        sum(1 for t in ts if t.failed),
        len(ts),
    )


def mean_std(values: Sequence[float]) -> tuple[float, float]:
    """(mean, std) of the finite values; (inf, 0) when all are infinite, (nan, 0) when there are none."""
    a = np.array([v for v in values if math.isfinite(v)], dtype=float)
    if len(a) == 0:
        return (math.inf, 0.0) if values else (math.nan, 0.0)
    return float(a.mean()), float(a.std())


def select(items: Iterable[T], **kw) -> list[T]:
    """The records whose attributes equal every ``kw`` value."""
    return [x for x in items if all(getattr(x, k) == v for k, v in kw.items())]


# ----------------------------------------------------------------------------------------------
# the equal-distortion sweep (``sweep.run_sweep``), below the sweep, the markdown and the plots


@dataclass
class SweepEmbedding:
    """One marked mesh: its distortion against the original."""

    model: str
    method: str
    scheme: str
    strength: float
    key: int
    n_bits: int
    mrms_percent: float
    hausdorff_percent: float
    rmse_percent: float
    embed_seconds: float


@dataclass
class SweepTrial:
    """One attacked copy read back; ``failed`` holds the reader's error when it could not read it
    (counted as chance, BER 0.5)."""

    model: str
    method: str
    strength: float
    key: int
    attack: str
    n_bits: int
    matches: int
    ber: float
    failed: str = ""


@dataclass
class SweepPoint:
    """One point of a curve: a method at one strength under one attack, over the keys."""

    model: str
    method: str
    strength: float
    attack: str
    mrms_mean: float
    mrms_std: float
    ber_mean: float
    ber_std: float
    n: int
    failed: int
    chance: bool  # the pooled correct bits are not significant against Binomial(bits, 1/2) at p < 0.01


@dataclass
class EqualMrms:
    """The methods compared at equal MRMS for one attack on one model.

    overlap:    (low, high) MRMS % covered by every method's curve, None when they do not overlap.
    mean_ber:   method -> its BER interpolated (linear in log MRMS) on the overlap, averaged over a
                log-spaced grid of it; empty without an overlap.
    ranking:    methods by ``mean_ber``, lowest first. winner: ranking[0] (None without an overlap).
    tied:       the methods within ``tolerance`` (one bit over all keys) of the winner, winner first.
    lowest_share: share of the overlap's grid where the winner's BER is the lowest (within tolerance).
    at_chance:  the methods that read at chance (``SweepPoint.chance``) at every one of their strengths.
    """

    attack: str
    model: str
    overlap: Optional[tuple[float, float]]
    ranges: dict[str, tuple[float, float]]
    mean_ber: dict[str, float] = field(default_factory=dict)
    ranking: list[str] = field(default_factory=list)
    winner: Optional[str] = None
    tied: list[str] = field(default_factory=list)
    lowest_share: float = 0.0
    tolerance: float = 0.0
    at_chance: list[str] = field(default_factory=list)


@dataclass
class SweepResults:
    """Everything one ``run_sweep`` measured, its comparisons, and the markdown it rendered."""

    settings: dict = field(default_factory=dict)
    models: dict[str, dict] = field(default_factory=dict)
    embeddings: list[SweepEmbedding] = field(default_factory=list)
    trials: list[SweepTrial] = field(default_factory=list)
    points: list[SweepPoint] = field(default_factory=list)
    comparisons: list[EqualMrms] = field(default_factory=list)
    markdown: str = ""


__all__ = [
    "BenchResults",
    "Cell",
    "Distortion",
    "EqualMrms",
    "SweepEmbedding",
    "SweepPoint",
    "SweepResults",
    "SweepTrial",
    "Trial",
    "cell",
    "mean_std",
    "select",
]
