"""Tracing a leaked copy to its recipient(s): read each site's soft value after registration (the
robust scheme's reader, one site per "bit"), correlate with every registered codeword, and name the
recipients whose corrected p-value is below the threshold (``codes``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..schemes.robust.read import RobustDetail, read_scores
from .codes import Accusation, accuse
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
        return {"traced": self.traced, "accused": [a.__dict__ for a in self.accused],
                "p_threshold": self.p_threshold, "n_recipients": self.n_recipients, "mode": self.mode,
                "sites_read": self.sites_read, "sites_total": self.sites_total}


def site_readings(vertices, faces, fk: FingerprintKey) -> tuple[np.ndarray, str, RobustDetail]:
    """Each site's weighted soft value x (S,) float64 (soft / variance, 0 where unread) of a suspect
    (any pose, order, resolution), how it was aligned, and the reader's details."""
    return read_scores(vertices, faces, fk.key)


def trace(vertices, faces, fk: FingerprintKey, registry: Registry, p_threshold: float = 1e-6) -> TraceResult:
    """Trace a suspect, vertices (n, 3), faces (m, 3), to the registry's recipients (RegistryError
    when the registry is not the key's)."""
    registry.check(fk)
    ids, C = registry.codewords()
    x, mode, detail = site_readings(vertices, faces, fk)
    accused, T, p = accuse(x, ids, C, p_threshold)
    return TraceResult(accused, p_threshold, len(ids), mode, detail.sites_read, detail.sites_total, ids, T, p,
                       detail)

