"""The progressive mesh: a base mesh and the vertex-split records that refine it, level by level.

Any prefix of the records is a valid mesh, and all records give back exactly the input mesh (vertex
order: ``vertex_order``; face order: ``face_order``). The records of one level are independent (they
split vertices whose neighbourhoods do not overlap), so a level is decoded at once. A record costs 24
bytes in a .pmwm file (float32 position, v, 64-bit mask); ``records`` says what its fields mean.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .decode import decode_prefix
from .records import FLAG_SINGLE


@dataclass
class ProgressiveMesh:
    """A base mesh and vertex-split records; ``decode`` gives any level of detail."""

    base_vertices: np.ndarray  # (nb, 3) float64
    base_faces: np.ndarray  # (fb, 3) int64
    pos: np.ndarray  # (R, 3) float64: position of the vertex each record adds
    v: np.ndarray  # (R,) int64: the vertex it splits from
    mask: np.ndarray  # (R,) uint64: which of v's faces move to the new vertex (and the arc's end faces)
    flags: np.ndarray  # (R,) uint8: FLAG_SINGLE, FLAG_SECOND
    level_records: np.ndarray  # (L,) int64: records at the end of each level, ascending, last == R
    float32: bool = False  # positions are exactly float32 (stored as such in files)
    end_ranks: bool = False  # masks name each arc's end faces (``ENDS_SHIFT``); not in .pmwm version 1 files
    vertex_order: Optional[np.ndarray] = field(default=None, repr=False)  # PM index -> input index
    face_order: Optional[np.ndarray] = field(default=None, repr=False)  # PM face -> input face

    @property
    def n_base_vertices(self) -> int:
        return len(self.base_vertices)

    @property
    def n_records(self) -> int:
        return len(self.v)

    @property
    def n_vertices(self) -> int:
        return self.n_base_vertices + self.n_records

    @property
    def n_faces(self) -> int:
        return len(self.base_faces) + int(np.sum(2 - (self.flags & FLAG_SINGLE)))

    def records_for_vertices(self, n_vertices: int) -> int:
        """Number of records whose LoD has ``n_vertices`` vertices (clamped to the valid range)."""
        return int(np.clip(n_vertices - self.n_base_vertices, 0, self.n_records))

    def decode(self, records: Optional[int] = None, vertices: Optional[int] = None) -> tuple[np.ndarray, np.ndarray]:
        """The mesh after ``records`` vertex splits (or with ``vertices`` vertices); default: all.
        Returns ``(V (nb + k, 3) float64, F (m, 3) int64)`` in PM vertex order."""
        if records is not None and vertices is not None:
            raise ValueError("give records or vertices, not both")
        if vertices is not None:
            records = self.records_for_vertices(vertices)
        k = self.n_records if records is None else int(np.clip(records, 0, self.n_records))
        return decode_prefix(
            self.base_vertices,
            self.base_faces,
            self.pos,
            self.v,
            self.mask,
            self.flags,
            self.level_records,
            k,
            end_ranks=self.end_ranks,
        )


def base_vertex_count(base_ratio: float, n_vertices: int) -> int:
    """The base mesh's vertex count the embedders ask for: ``base_ratio`` of the mesh, at least 4."""
    return max(int(round(base_ratio * n_vertices)), 4)


def with_positions(pm: ProgressiveMesh, vertices: np.ndarray) -> ProgressiveMesh:
    """The same progressive mesh with the vertices at ``vertices`` (n, 3) float64 (input order):
    connectivity, records and levels unchanged, the base mesh and every record's position taken from
    ``vertices``. A mesh marked by moving vertices has the progressive mesh of the unmarked one with
    its own positions: it decodes exactly to ``vertices`` (in ``pm.vertex_order``)."""
    X = np.asarray(vertices, np.float64)
    if pm.vertex_order is None or len(X) != pm.n_vertices:
        raise ValueError(
            f"with_positions needs one position per vertex of the progressive mesh ({pm.n_vertices}), got {len(X)}"
        )
    order, nb = pm.vertex_order, pm.n_base_vertices
    return dataclasses.replace(
        pm,
        base_vertices=X[order[:nb]],
        pos=X[order[nb:]],
        float32=bool(np.all(X.astype(np.float32).astype(np.float64) == X)),
    )
