"""Tracing a leaked copy to its recipient(s): read each site's soft value after registration (the
robust scheme's reader, one site per "bit"), correlate with every registered codeword, and name the
recipients whose corrected p-value is below the threshold (``codes``)."""

from __future__ import annotations

import dataclasses

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..schemes.robust.read import RobustDetail, readings
from .codes import Accusation, accuse, correlation_scores
from .registry import FingerprintKey, Registry

__all__ = ["TraceResult", "trace", "site_readings", "Accusation"]


@dataclass
class TraceResult:
    """The answer of ``trace``: the recipients named (best first; empty: "no recipient"), the
    threshold, how the copy was aligned and read, and every recipient's score and corrected p-value
    (N,) float64 in ``recipients`` order."""

    accused: list
    p_threshold: float
    n_recipients: int
    mode: str
    sites_read: int
    sites_total: int
    recipients: list = field(repr=False, default_factory=list)
    scores: np.ndarray = field(repr=False, default=None)
    p_values: np.ndarray = field(repr=False, default=None)
    detail: Optional[RobustDetail] = None  # how the robust reader read the copy

    @property
    def traced(self) -> bool:
        return bool(self.accused)

    def to_dict(self) -> dict:
        return {
            "traced": self.traced,
            "accused": [a.__dict__ for a in self.accused],
            "p_threshold": self.p_threshold,
            "n_recipients": self.n_recipients,
            "mode": self.mode,
            "sites_read": self.sites_read,
            "sites_total": self.sites_total,
        }


def site_readings(vertices, faces, fk: FingerprintKey) -> tuple[np.ndarray, str, RobustDetail]:
    """Each site's log-likelihood ratio x (S,) float64 (``robust.read.site_llr``, 0 where unread) of a suspect
    (any pose, order, resolution), how it was aligned, and the reader's details (the reading of the
    first pose the reader proposes; ``trace`` reads every pose worth reading)."""
    reading = next(readings(vertices, faces, fk.key))
    return reading.scores, reading.mode, reading.detail


def trace(vertices, faces, fk: FingerprintKey, registry: Registry, p_threshold: float = 1e-6) -> TraceResult:
    """Trace a suspect, vertices (n, 3), faces (m, 3), to the registry's recipients (RegistryError
    when the registry is not the key's). Of the suspect's poses (a mirror image, a symmetric shape:
    ``pmwm.schemes.robust.read.readings``), the one where some recipient scores highest is kept, and
    every p-value pays for the poses the reader may try, as well as for the recipients."""
    registry.check(fk)
    ids, C = registry.codewords()

    def strength(x: np.ndarray) -> float:  # the best recipient's score in a pose
        return float(correlation_scores(x, C).max(initial=0.0))

    best = None
    for n, reading in enumerate(readings(vertices, faces, fk.key, strength), 1):
        accused, T, p = accuse(reading.scores, ids, C, p_threshold, poses=reading.poses)
        if best is None or T.max(initial=0.0) > best[2].max(initial=0.0):
            best = (reading, accused, T, p)
        if accused:
            break
    reading, accused, T, p = best
    detail = dataclasses.replace(reading.detail, poses_read=n, poses_paid=reading.poses)
    return TraceResult(
        accused, p_threshold, len(ids), reading.mode, detail.sites_read, detail.sites_total, ids, T, p, detail
    )
