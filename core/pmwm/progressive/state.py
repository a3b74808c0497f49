"""The encoder's state between passes: the vertices' quadrics and flags, the live mesh with its
collapse candidates per corner, and the small numpy helpers the passes share.

Nothing is rebuilt per pass. The live faces carry their candidates per corner (corner j of face f:
collapse F[f, j] into F[f, j+1], and the reverse on boundary half-edges) with their costs. The cost of
a -> b is Q_a(V_b) + E_b (E the vertices' own errors), one dot product of Q_a with the fixed monomials
of V_b. Removed faces point to a sink vertex (the last local vertex) until a quarter of the rows are
retired, and the vertices are renumbered whenever half of them are gone (``compact``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .records import NEXT_CORNER, TO_NEXT_CORNER


@dataclass
class EncoderVertices:
    """Per local vertex (n of them, then the sink): geometry, quadrics (updated in place) and flags."""

    positions: np.ndarray  # (n + 1, 3) float64 (the last row: the sink)
    coords: np.ndarray  # (3, n + 1) the same, by coordinate
    monomials: np.ndarray  # (n + 1, 10) the positions' monomials: a quadric's value at V[i] is Q . monomials[i]
    tiebreak: np.ndarray  # (n + 1,) int64: a fixed permutation, the order of equal cost buckets
    quadrics: np.ndarray  # (n + 1, 10) (a row per vertex: one gather is one cache line); v absorbs u's
    own_error: np.ndarray  # (n + 1,) each vertex's own error Q_v(V_v)
    removable: np.ndarray  # (n + 1,) bool: may be removed
    locked: np.ndarray  # (n + 1,) bool: may not absorb (non-manifold, isolated, the sink)
    on_boundary: np.ndarray  # (n + 1,) bool: on the boundary (stays so: collapses keep the boundary)
    area_eps: float  # a face whose doubled area squared is below area_eps**2 after a collapse is a sliver


@dataclass
class LiveMesh:
    """The live mesh while encoding, with per-corner candidates kept across passes.

    Corner j of face f is the half-edge F[f, j] -> F[f, j+1]; its forward candidate collapses
    F[f, j] into F[f, j+1], its reverse candidate (boundary half-edges only) F[f, j+1] into
    F[f, j]. Costs are recomputed only on the half-edges from and to each pass's survivors.
    Removed faces become (n, n, n) (the sink, never removable) until the arrays are compacted.
    """

    faces: np.ndarray  # (m, 3) int64 local vertex ids (n: a retired face)
    face_ids: np.ndarray  # (m,) input face ids
    boundary: np.ndarray  # (m, 3) bool: the half-edge is on the boundary
    forward_cost: np.ndarray  # (m, 3) inf where the vertex flags forbid it or the candidate was found
    # invalid (until its neighbourhood changes)
    reverse_cost: np.ndarray  # (m, 3) inf off the boundary, where forbidden or found invalid
    failed: list = field(default_factory=list)  # arrays of flat corners whose candidate was found invalid
    n_retired: int = 0  # faces pointing to the sink

    def keep_rows(self, rows: np.ndarray) -> None:
        """Keep the faces ``rows`` ((m,) bool), in order."""
        idx = np.flatnonzero(rows)
        for name in ("faces", "face_ids", "boundary", "forward_cost", "reverse_cost"):
            setattr(self, name, np.take(getattr(self, name), idx, axis=0))
        if self.failed:
            c = np.concatenate(self.failed)
            new = np.cumsum(rows) - 1
            c = c[np.take(rows, c // 3)]
            self.failed = [np.take(new, c // 3) * 3 + c % 3]

    def current_faces(self, sink: int) -> np.ndarray:
        """The live faces (rows without the sink)."""
        return self.faces[self.faces[:, 0] < sink]


_COST_BLOCK = 1 << 15  # corners per block of quadric work (its temporaries stay in cache)


def update_costs(verts: EncoderVertices, live: LiveMesh, corners: np.ndarray) -> None:
    """Recompute the forward (and, on the boundary, reverse) candidates of flat ``corners``.

    Costs are quadric errors, inf where the vertex flags forbid the collapse.
    """
    for s in range(0, len(corners), _COST_BLOCK):
        _update_cost_block(verts, live, corners[s : s + _COST_BLOCK])


def _update_cost_block(verts: EncoderVertices, live: LiveMesh, corners: np.ndarray) -> None:
    # cost of a -> b: (Q_a + Q_b)(V_b) = Q_a(V_b) + E_b, with E_b = Q_b(V_b) kept per vertex
    take = np.take
    flat = live.faces.ravel()
    a = take(flat, corners)
    b = take(flat, corners + take(TO_NEXT_CORNER, corners % 3))
    on_boundary = take(live.boundary.ravel(), corners)
    allowed = take(verts.removable, a) & ~take(verts.locked, b) & (on_boundary == take(verts.on_boundary, a))
    into_b = np.einsum("ij,ij->i", take(verts.quadrics, a, axis=0), take(verts.monomials, b, axis=0)) + take(
        verts.own_error, b
    )
    into_b[~allowed] = np.inf
    live.forward_cost.ravel()[corners] = into_b
    # (off the boundary the reverse cost stays inf, as it was made: a corner's side of the boundary
    # never changes)
    reverse = live.reverse_cost.ravel()
    on = np.flatnonzero(on_boundary)
    if len(on):
        a, b = a[on], b[on]
        into_a = np.einsum("ij,ij->i", take(verts.quadrics, b, axis=0), take(verts.monomials, a, axis=0)) + take(
            verts.own_error, a
        )
        into_a[~(verts.removable[b] & ~verts.locked[a])] = np.inf
        reverse[corners[on]] = into_a


def cheapest_costs(verts: EncoderVertices, live: LiveMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n + 1,) per vertex, the cost of its cheapest live candidate; and the live cost arrays (m, 3)
    forward and reverse."""
    forward, reverse = live.forward_cost, live.reverse_cost
    cheapest = np.full(len(verts.removable), np.inf)
    F = live.faces
    for j in range(3):
        np.minimum.at(cheapest, F[:, j], forward[:, j])
    b = np.flatnonzero(np.isfinite(reverse.ravel()))
    if len(b):
        np.minimum.at(cheapest, F.ravel()[(b // 3) * 3 + NEXT_CORNER[b % 3]], reverse.ravel()[b])
    return cheapest, forward, reverse


def protect(verts: EncoderVertices, live: LiveMesh, protected: np.ndarray) -> None:
    """Forbid removing the ``protected`` vertices ((n,) bool) after the costs were first computed:
    the candidates from and (reverse, on the boundary) into them computed again, the others as they
    were, so that the costs are those of a build protecting them from the start."""
    n = len(verts.removable) - 1
    if protected.shape != (n,):
        raise ValueError(f"protected: expected ({n},) bool, got shape {protected.shape}")
    verts.removable[:n] &= ~protected
    hit = np.take(np.r_[protected, False], live.faces)
    update_costs(verts, live, np.flatnonzero((hit | hit[:, NEXT_CORNER]).ravel()))


def compact(
    verts: EncoderVertices, live: LiveMesh, ids: np.ndarray, keep: np.ndarray
) -> tuple[EncoderVertices, np.ndarray]:
    """Renumber the live vertices 0..k-1 (sink k) so that per-vertex work follows the shrinking mesh;
    ``ids`` (n,) the input id of each local vertex, ``keep`` (n,) bool the vertices still alive. Returns
    the renumbered vertices and their input ids."""
    n_local = len(ids)
    kept = np.flatnonzero(keep)
    k = len(kept)
    new_id = np.full(n_local + 1, k, np.int64)
    new_id[kept] = np.arange(k)
    live.keep_rows(live.faces[:, 0] < n_local)
    live.n_retired = 0
    live.faces = new_id[live.faces]
    sel = np.r_[kept, n_local]  # the old sink's entries (locked, zero quadric) serve the new sink
    return EncoderVertices(
        positions=verts.positions[sel],
        coords=np.take(verts.coords, sel, axis=1),
        monomials=verts.monomials[sel],
        tiebreak=verts.tiebreak[sel],
        quadrics=verts.quadrics[sel],
        own_error=verts.own_error[sel],
        removable=verts.removable[sel],
        locked=verts.locked[sel],
        on_boundary=verts.on_boundary[sel],
        area_eps=verts.area_eps,
    ), ids[kept]


def compress(mask: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """``a[mask]`` for each array (1-D, same length as the bool ``mask``), through one flatnonzero and
    gathers: several times faster than boolean indexing when the mask is irregular."""
    i = np.flatnonzero(mask)
    return tuple(np.take(a, i) for a in arrays)


def any_in_row(m: np.ndarray) -> np.ndarray:
    """(k,) row-wise any of a (k, 3) bool array (faster than .any(axis=1))."""
    return m[:, 0] | m[:, 1] | m[:, 2]


def tagged_corners(F: np.ndarray, tag: np.ndarray, rows: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
    """Flat corner ids (into F (m, 3)) whose vertex has tag >= 0, and their tags (int64); only faces
    ``rows`` if given."""
    t = np.take(tag, F.ravel() if rows is None else np.take(F, rows, axis=0).ravel())
    c = np.flatnonzero(t >= 0)
    tc = np.take(t, c).astype(np.int64, copy=False)
    if rows is None:
        return c, tc
    return rows[c // 3] * 3 + c % 3, tc


def inverse_index(n: int, x: np.ndarray) -> np.ndarray:
    """(n + 1,) int32: i at vertex x[i] (x distinct), -1 elsewhere (entry n: none)."""
    tag = np.full(n + 1, -1, np.int32)
    tag[x] = np.arange(len(x), dtype=np.int32)
    return tag


def ring_minimum(F: np.ndarray, val: np.ndarray) -> np.ndarray:
    """(n,) the minimum of ``val`` (n,) over each vertex's closed 1-ring (through its faces F (m, 3))."""
    g = np.take(val, F)
    face_min = np.minimum(np.minimum(g[:, 0], g[:, 1]), g[:, 2])
    out = val.copy()
    for j in range(3):
        np.minimum.at(out, F[:, j], face_min)
    return out
