"""Decoding a progressive mesh: the base mesh refined by a prefix of its vertex-split records.

A level's records are independent, so they are applied together, touching only the faces around
their vertices. Each vertex keeps its corners (flat ids into F) in a row of a table (``CornerTable``),
in face order. For a vertex of at most 14 faces, one gather through a permutation table indexed by
the record's mask splits its row into the new vertex's and the old one's. The arc ends p and q that
the new faces take are read from the two faces the mask names (``ENDS_SHIFT``), or, for masks without
them (.pmwm version 1), from sums that telescope around the arc. What does not depend on the mesh (the
new faces' rows, their corners at u and v) is computed for all records at once, and the output arrays
are allocated at their final sizes. Why these choices: docs/decisions/062-progressive-decoder.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..adjacency import stable_order, unique_values
from .records import ENDS_SHIFT, FLAG_SECOND, FLAG_SINGLE, NO_END, TO_NEXT_CORNER, TO_PREV_CORNER


def decode_prefix(
    base_vertices: np.ndarray,
    base_faces: np.ndarray,
    pos: np.ndarray,
    v: np.ndarray,
    mask: np.ndarray,
    flags: np.ndarray,
    level_records: np.ndarray,
    k: int,
    *,
    end_ranks: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Apply the first ``k`` records to the base mesh, level by level (the fields of a ``ProgressiveMesh``);
    returns ``(V (nb + k, 3) float64, F (m, 3) int64)``.

    tests/test_progressive_decode.py checks the result, byte for byte, against a reference that
    applies the records one at a time from their definition.
    """
    nb = len(base_vertices)
    nf = len(base_faces)
    rec = RecordTable.of(v, mask, flags, k, nb, nf, end_ranks=end_ranks)
    V = np.empty((nb + k, 3), dtype=np.float64)
    V[:nb] = base_vertices
    V[nb:] = pos[:k]
    F = np.empty((rec.n_faces, 3), dtype=np.int64)
    F[:nf] = base_faces
    rec.fill_faces(F[nf:])
    corners = CornerTable.build(F[:nf], nb + k, np.int32 if 3 * rec.n_faces < 2**31 else np.int64)
    bounds = unique_values(np.r_[0, level_records[level_records < k], k]).tolist()
    for start, stop in zip(bounds[:-1], bounds[1:]):
        _split_batch(rec, F, nb + start, start, stop, corners)
    return V, F


@dataclass
class RecordTable:
    """The first k records with what follows from them alone, per record: where its faces go.
    Compact types: fresh memory costs page faults that weigh as much as the arithmetic here."""

    v: np.ndarray  # (k,) int64: the vertex it splits
    mask: np.ndarray  # (k,) uint64
    n_new_faces: np.ndarray  # (k,) int64: the number of faces it adds (1 or 2)
    u: np.ndarray  # (k,) int64: the vertex it adds
    has_pq: np.ndarray  # (2, k) bool: p is in a new face (then the first is [u, v, p], else [u, q, v]); q is
    corner_slots: np.ndarray  # (6, k) flat corner ids in F: the new faces' corners at u, u, v, v (the second
    # pair in the second face, or repeating the first face's u and landing on its p slot with one
    # face), then p's and q's slots (the other's when absent)
    n_faces: int  # faces after the k records
    end_slots: Optional[np.ndarray]  # (2, k) int64: flat slots in the fast table of v's corners in the
    # faces that end the arc, p's and q's (``ENDS_SHIFT``); None without end ranks
    n_without_ends: np.ndarray  # (k + 1,) int64: records before each whose ranks are not both in the fast
    # row (NO_END, or a rank past _ROW_SLOTS - 3): a batch with any of them finds p and q by the sums

    @staticmethod
    def of(
        v: np.ndarray, mask: np.ndarray, flags: np.ndarray, k: int, nb: int, nf: int, *, end_ranks: bool
    ) -> "RecordTable":
        """The table of the first ``k`` records of a progressive mesh with ``nb`` base vertices and
        ``nf`` base faces."""
        flags = flags[:k]
        single = (flags & FLAG_SINGLE).astype(bool)
        two = ~single
        has_first = ~(single & ((flags & FLAG_SECOND) != 0))  # the split adds [u, v, p]
        n_faces = nf + k + int(np.count_nonzero(two))
        index_type = np.int32 if 3 * n_faces < 2**31 else np.int64
        slots = np.empty((6, k), dtype=index_type)
        first = slots[0]  # corner 0 of each record's first face
        np.cumsum(two, dtype=index_type, out=first)
        first -= two
        first += np.arange(nf, nf + k, dtype=index_type)
        first *= 3
        np.add(first, np.where(two, 3, 0).astype(index_type), out=slots[1])  # ... of its second (first with one)
        np.subtract(first + 2, has_first, out=slots[2], casting="unsafe")
        np.add(slots[1], 2, out=slots[3])
        np.add(first + 1, has_first, out=slots[4], casting="unsafe")
        slots[5] = np.where(two, slots[3] - 1, slots[4])
        v = np.asarray(v[:k], dtype=np.int64)
        u = np.arange(nb, nb + k)
        end_slots, n_without_ends = None, np.zeros(k + 1, dtype=np.int64)
        if end_ranks:
            top = (mask[:k] >> np.uint64(ENDS_SHIFT)).view(np.int64)
            end_slots = np.stack([top & NO_END, top >> 6])
            np.cumsum((end_slots >= _ROW_SLOTS - 2).any(axis=0), out=n_without_ends[1:])  # (NO_END among them)
            end_slots += v * _ROW_SLOTS
        return RecordTable(
            v=v,
            mask=mask[:k],
            u=u,
            n_new_faces=two.astype(np.int64) + 1,
            has_pq=np.stack([has_first, ~has_first | two]),
            corner_slots=slots,
            n_faces=n_faces,
            end_slots=end_slots,
            n_without_ends=n_without_ends,
        )

    def fill_faces(self, new: np.ndarray) -> None:
        """Write the faces the records add, ``new`` (m, 3) in record order, as [u, v, v]: each is
        [u, v, p] or [u, q, v], and the decoding writes p or q over the one v out of place (three
        column writes: faster than scattering u and v to their corners)."""
        new[:, 0] = self.u.repeat(self.n_new_faces)
        new[:, 1] = new[:, 2] = self.v.repeat(self.n_new_faces)


_ROW_SLOTS = 16  # row width of the corner table on the fast path (degrees up to _ROW_SLOTS - 2)
_LOW_BITS = np.array([(1 << i) - 1 for i in range(_ROW_SLOTS - 1)], dtype=np.uint64)  # (15,) the low i bits
_SPLIT_TABLES: list = []  # made on first use: the fast path's permutation table and popcounts (2 MB)


def _split_tables() -> tuple[np.ndarray, np.ndarray]:
    """For every mask m of _ROW_SLOTS - 2 bits: (2^14, _ROW_SLOTS) int64 source slots, first the set
    bits of m ascending, then the clear bits descending from the last slot (so that the reversed row
    lists them ascending); and (2^14,) int64 the popcount of m. Built once per process (about 1 ms)
    from the same table for bytes: m's row is its low byte's row with the high byte's row (+ 8)
    inserted after the low byte's set bits."""
    if not _SPLIT_TABLES:
        j = np.arange(8)
        bits = np.unpackbits(np.arange(256, dtype=np.uint8)[:, None], axis=1, bitorder="little").astype(bool)
        row8 = np.argsort(np.where(bits, j, 16 - j), axis=1, kind="stable").astype(np.uint8)
        pop8 = bits.sum(axis=1)
        n_high = 1 << (_ROW_SLOTS - 10)
        perm = np.empty((n_high, 256, _ROW_SLOTS), dtype=np.uint8)  # [high byte, low byte]
        for n_low_set in range(9):
            low = np.flatnonzero(pop8 == n_low_set)
            perm[:, low, :n_low_set] = row8[low, :n_low_set]
            perm[:, low, n_low_set : n_low_set + 8] = (row8[:n_high] + 8)[:, None, :]
            perm[:, low, n_low_set + 8 :] = row8[low, n_low_set:]
        pop = (pop8[:n_high, None] + pop8[None, :]).reshape(-1)
        _SPLIT_TABLES[:] = [perm.reshape(-1, _ROW_SLOTS).astype(np.int64), pop.astype(np.int64)]  # int64: adds in place
    return _SPLIT_TABLES[0], _SPLIT_TABLES[1]


@dataclass
class CornerTable:
    """Each vertex's corners (flat ids into F), ascending, in slots: the first _ROW_SLOTS in ``fast``, the
    rest (high degrees, rare) in ``overflow``; ``degree`` of them are live, slots past it are stale.

    ``overflow`` starts empty and widens on demand; ``fast`` never changes shape, so that the fast path
    always moves whole rows.
    """

    fast: np.ndarray  # (n, _ROW_SLOTS) corner ids
    overflow: np.ndarray  # (n, X) corner ids, X a multiple of 8
    degree: np.ndarray  # (n,) int64

    @staticmethod
    def build(F: np.ndarray, n: int, dtype) -> "CornerTable":
        """The table of faces ``F`` (m, 3) over ``n`` vertices, corner ids of type ``dtype``."""
        flat = F.reshape(-1)
        degree = np.bincount(flat, minlength=n)
        table = CornerTable(np.zeros((n, _ROW_SLOTS), dtype=dtype), np.zeros((n, 0), dtype=dtype), degree)
        order, vert = stable_order(flat)  # corners grouped by vertex, ascending in each group
        start = np.cumsum(degree) - degree
        table.set_slots(vert, np.arange(len(flat)) - np.take(start, vert), order)
        return table

    @property
    def width(self) -> int:
        return _ROW_SLOTS + self.overflow.shape[1]

    def make_room(self, need: int) -> None:
        """Make room for ``need`` corners per vertex."""
        X = self.overflow.shape[1]
        if need > _ROW_SLOTS + X:
            wider = np.zeros((len(self.fast), -(-max(need - _ROW_SLOTS, X + X // 2) // 8) * 8), dtype=self.fast.dtype)
            wider[:, :X] = self.overflow
            self.overflow = wider

    def rows(self, x: np.ndarray) -> np.ndarray:
        """(len(x), width) the slots of vertices x."""
        rows = np.take(self.fast, x, axis=0)
        return np.concatenate([rows, np.take(self.overflow, x, axis=0)], axis=1) if self.overflow.shape[1] else rows

    def set_rows(self, x, rows: np.ndarray) -> None:
        """Slots 0..rows.shape[1]-1 of vertices x (an index array or a slice) = rows."""
        self.fast[x] = rows[:, :_ROW_SLOTS]
        if rows.shape[1] > _ROW_SLOTS:
            self.overflow[x, : rows.shape[1] - _ROW_SLOTS] = rows[:, _ROW_SLOTS:]

    def set_slots(self, x: np.ndarray, slot: np.ndarray, val: np.ndarray) -> None:
        """Slot ``slot[i]`` of vertex ``x[i]`` = ``val[i]``, the table widened as needed."""
        top = int(slot.max(initial=0))
        if top >= _ROW_SLOTS:
            self.make_room(top + 1)
            big = slot >= _ROW_SLOTS
            s = np.flatnonzero(big)
            self.overflow.reshape(-1)[np.take(x, s) * self.overflow.shape[1] + np.take(slot, s) - _ROW_SLOTS] = np.take(
                val, s
            )
            s = np.flatnonzero(~big)
            x, slot, val = np.take(x, s), np.take(slot, s), np.take(val, s)
        self.fast.reshape(-1)[x * _ROW_SLOTS + slot] = val


def _split_batch(rec: RecordTable, F: np.ndarray, first_u: int, start: int, stop: int, corners: CornerTable) -> None:
    """Apply the independent records ``start..stop-1`` (one level or a prefix of it) to F in place.

    Record r moves the corners of its vertex v whose rank among v's faces (in face order) is set
    in ``mask[r]`` to the new vertex u = first_u + r - start; its new faces [u, v, p] and/or [u, q, v]
    (already in F but for p and q) take the ends p, q of the moved arc. The records' v, p and q
    are distinct, no moved face holds another record's v (the encoder's selection rule): the records
    form one batch.
    """
    n_rec = stop - start
    v = rec.v[start:stop]
    u = rec.u[start:stop]
    degree = corners.degree
    deg_v = degree.take(v)
    mask = rec.mask[start:stop]
    flat = F.reshape(-1)
    # move the corners: records of degree above _ROW_SLOTS - 2 (rare) on the general path, first (it may
    # widen the table), the others through the permutation table
    # the lists are read again (not after the last records): they get the new faces' corners at u, v
    new = rec.corner_slots[:4, start:stop] if stop < len(rec.v) else None
    if deg_v.max(initial=0) <= _ROW_SLOTS - 2:
        # the corners that end the arcs, read before the lists change (p after, q before them)
        ends = (
            None
            if rec.end_slots is None or rec.n_without_ends[stop] > rec.n_without_ends[start]
            else corners.fast.reshape(-1).take(rec.end_slots[:, start:stop])
        )
        moved, n_moved = _move_corners_fast(corners, v, slice(first_u, first_u + n_rec), mask, deg_v, new)
        flat[moved] = u.repeat(n_moved)
        # (a rank past v's degree, only in corrupt data, reads a stale slot: a corner of an earlier
        # face, whose vertices are written; p and q are then wrong but vertices of the mesh)
        pq = (
            _arc_ends(flat, moved, n_moved, first_u + n_rec)
            if ends is None
            else flat.take(ends + _END_OFFSET.take(ends % 3 + _END_ROW))
        )
    else:
        n_moved = np.empty(n_rec, dtype=np.int64)
        pq = np.empty((2, n_rec), dtype=np.int64)
        fast = deg_v <= _ROW_SLOTS - 2
        fast, wide = np.flatnonzero(fast), np.flatnonzero(~fast)
        for sel, move in [(wide, _move_corners_wide), (fast, _move_corners_fast)]:
            u_sel = u.take(sel)
            moved, n_sel = move(
                corners, v.take(sel), u_sel, mask.take(sel), deg_v.take(sel), None if new is None else new[:, sel]
            )
            flat[moved] = u_sel.repeat(n_sel)
            n_moved[sel] = n_sel
            pq[:, sel] = _arc_ends(flat, moved, n_sel, first_u + n_rec)
    has_pq = rec.has_pq[:, start:stop]  # p's and q's slots: the other's when one is absent
    pq_slots = rec.corner_slots[4:, start:stop].reshape(-1)
    flat[pq_slots] = np.where(has_pq, pq, pq[::-1]).reshape(-1)
    if new is None:
        return
    # the lists: one corner at the end of p's and of q's
    n_kept = deg_v - n_moved
    has_pq = has_pq.reshape(-1)
    pq = pq.reshape(-1)[has_pq]
    deg_pq = degree.take(pq)
    corners.set_slots(pq, deg_pq, pq_slots[has_pq])
    degree[pq] = deg_pq + 1
    n_new = rec.n_new_faces[start:stop]
    degree[first_u : first_u + n_rec] = n_moved + n_new
    degree[v] = n_kept + n_new


def _move_corners_fast(
    corners: CornerTable, v: np.ndarray, u, mask: np.ndarray, deg_v: np.ndarray, new: Optional[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """Split the lists of v (degrees ``deg_v`` <= 14, rows of 16) into u's (the corners whose rank bit
    is set) and v's (the rest), each followed by its new corners ``new`` (4, len(v)): u's two, v's two
    (the second ones past the degree with one new face; None: the lists are not kept). u: an index
    array or a slice. Returns the moved corners grouped by record, ascending, and (len(v),) their counts.

    One gather through the permutation table puts the moved corners first and the kept ones last in
    reverse; u's row is that row, v's row the same row reversed (slots past the lists: stale). The
    new corners go into the free middle of the row (at least two slots), u's before u's row is
    stored and v's, which may overwrite them, after.
    """
    perm, pop = _split_tables()
    low_mask = (mask & _LOW_BITS.take(deg_v)).view(np.int64)
    table = corners.fast
    at = perm.take(low_mask, axis=0)
    at += (v * _ROW_SLOTS)[:, None]
    row = table.reshape(-1).take(at)
    n_moved = pop.take(low_mask)
    moved = row.reshape(-1).take(_leading_slots(n_moved, _ROW_SLOTS)).astype(np.int64)
    if new is not None:
        flat = row.reshape(-1)
        at = np.arange(0, _ROW_SLOTS * len(v), _ROW_SLOTS) + n_moved
        flat[at] = new[0]
        at += 1
        flat[at] = new[1]
        table[u] = row
        at += _ROW_SLOTS - 2 - deg_v  # slot n_kept of v's row, counted from the row's end
        flat[at] = new[2]
        at -= 1
        flat[at] = new[3]
        whole = np.dtype((np.void, row.strides[0]))  # a row as one item: a scatter of rows, 2x faster
        corners.fast.view(whole).reshape(-1).put(v, np.ascontiguousarray(row[:, ::-1]).view(whole).reshape(-1))
    return moved, n_moved


def _leading_slots(n: np.ndarray, width: int) -> np.ndarray:
    """Flat ids of the first n[i] slots of each row i of a (len(n), width) array."""
    ends = n.cumsum()
    return (np.arange(0, width * len(n), width) - ends + n).repeat(n) + np.arange(int(ends[-1]) if len(n) else 0)


def _move_corners_wide(
    corners: CornerTable, v: np.ndarray, u: np.ndarray, mask: np.ndarray, deg_v: np.ndarray, new: Optional[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """``_move_corners_fast`` for any degree: rank masks by shifts and cumulative sums (ranks past 63,
    only in corrupt data, read bit 63)."""
    take = np.take
    n_rec = len(v)
    W = int(deg_v.max(initial=0))
    col = np.arange(W)
    is_moved = ((mask[:, None] >> np.minimum(col, 63).astype(np.uint64)) & np.uint64(1)).astype(bool)
    is_moved &= col < deg_v[:, None]
    below = np.cumsum(is_moved, axis=1) - is_moved  # moved corners before each one
    n_moved = np.count_nonzero(is_moved, axis=1).astype(np.int64)
    # room for the lists read and for the new ones with their new corners
    corners.make_room(max(W, int(np.maximum(n_moved, deg_v - n_moved).max(initial=0)) + 2))
    C = corners.width
    rows = corners.rows(v)[:, :W]
    # u's row and v's row side by side in a scratch block; corners past deg(v) land past the new degree
    rel = np.where(is_moved, below, (col + C) - below)
    buf = np.zeros((n_rec, 2, C), dtype=corners.fast.dtype)  # zeros: slots past the lists stay valid ids
    base = np.arange(0, 2 * C * n_rec, 2 * C)
    buf.reshape(-1)[rel + base[:, None]] = rows
    if new is not None:
        at_u, at_v = base + n_moved, base + C + deg_v - n_moved
        buf.reshape(-1)[np.concatenate([at_u, at_u + 1, at_v, at_v + 1])] = new.reshape(-1)
        corners.set_rows(u, buf[:, 0])
        corners.set_rows(v, buf[:, 1])
    return take(buf.reshape(-1), _leading_slots(n_moved, 2 * C)).astype(np.int64), n_moved


_END_OFFSET = np.concatenate([TO_NEXT_CORNER, TO_PREV_CORNER])  # p: the vertex after an end face's corner; q: before
_END_ROW = np.array([[0], [3]])


def _arc_ends(flat: np.ndarray, moved: np.ndarray, n_moved: np.ndarray, n: int) -> np.ndarray:
    """Per record, the ends p, q of its moved arc of faces (the moved corners ``moved``, grouped by
    record, ``n_moved`` per record) as (2, len(n_moved)) int64.

    Around the arc, each face's previous vertex is the next one of its neighbour, so the sums of
    (next - previous) and (next^2 - previous^2) over a record's faces telescope to p - q and
    p^2 - q^2 (exact in wrapping 64-bit integers for vertex ids below 2^31). Records whose arc is
    empty or closed, or whose sums give no vertex below ``n`` (only in corrupt data) fall back to
    matching the ends by a tag table (then every end is a vertex of the mesh).
    """
    take = np.take
    corner = moved % 3
    nxt = flat.take(moved + TO_NEXT_CORNER.take(corner))
    prv = flat.take(moved + TO_PREV_CORNER.take(corner))
    if len(moved) and n < 2**31:  # (a record without moved corners gets s1 == 0 or garbage)
        s = np.empty((2, len(moved)), dtype=np.int64)
        np.subtract(nxt, prv, out=s[0])
        np.multiply(s[0], nxt + prv, out=s[1])
        s = s.cumsum(axis=1).take(n_moved.cumsum() - 1, axis=1)  # sums per record (wrapping is fine)
        s[:, 1:] -= s[:, :-1].copy()
        s1, s2 = s
        if (s1 != 0).all():
            both = s2 // s1  # p + q
            pq = np.concatenate([both + s1, both - s1]).reshape(2, -1)
            pq >>= 1
            if (pq.view(np.uint64) < n).all():
                return pq
    n_rec = len(n_moved)
    rec = np.repeat(np.arange(n_rec), n_moved)
    tag = np.full(int(max(nxt.max(initial=0), prv.max(initial=0))) + 1, -1, dtype=np.int64)
    tag[prv] = rec
    p_end = np.flatnonzero(take(tag, nxt) != rec)
    tag[prv] = -1
    tag[nxt] = rec
    q_end = np.flatnonzero(take(tag, prv) != rec)
    pq = np.zeros((2, n_rec), dtype=np.int64)
    pq[0, take(rec, p_end)] = take(nxt, p_end)
    pq[1, take(rec, q_end)] = take(prv, q_end)
    return pq
