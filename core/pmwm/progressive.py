"""Progressive mesh: batched half-edge collapses down to a base mesh, exact vertex splits back up.

Encoding. Each pass picks a set of independent half-edge collapses u -> v (u vanishes,
v keeps its position) in quadric-error order: a vertex u is collapsed when the
priority of its cheapest valid collapse (the cost's quantile bucket, then a fixed
pseudo-random order, Luby-style) is the best in its closed 1-ring and the collapse shares
no vertex of its vanishing faces with a better one (``_select`` gives the rule), so that
the whole pass can be applied (and undone) at once with numpy. One pass is one level of
detail.

How it stays fast in numpy (issue 13): nothing is rebuilt per pass. The live faces
carry their candidates per corner (corner j of face f: collapse F[f, j] into F[f, j+1],
and the reverse on boundary half-edges) with their costs. The cost of a -> b is
Q_a(V_b) + E_b (E the vertices' own errors), one dot product of Q_a with the fixed
monomials of V_b; after a pass it is recomputed on the half-edges from v and into v from
u's former faces, and shifted by v's change of E into v from v's own faces. A candidate
found invalid gets an infinite cost and waits in a list until a collapse comes near it.
Per pass, one selection round: the 1-ring minima of the priorities come from a face-wise
minimum scatter (``np.minimum.at``, faster here than sorted segment reductions), and two
scans over the faces find the corners at the winners' u and at their v. Removed faces point
to a sink vertex until a quarter of the rows are dead, and the vertices are renumbered
whenever half of them are gone. Gathers use ``np.take`` (2-4x faster than fancy indexing
here, except with 32-bit indices, which it first copies to 64 bits).

Why not a compiled dependency: numba 0.68.1 (numpy 1.26.4, Python 3.11; it also imports
with numpy 2.5.5 on Python 3.13) ran two kernels of one igea pass (all corners' costs with
each vertex's cheapest, one 2-ring minimum step) in 10 ms against 25 ms for this numpy, but
every fresh process pays about 0.4 s to import numba and 0.2 s to load the cached kernels
(2.2-2.6 s to compile them without a cache, e.g. on a read-only install), and the extension
would carry numba + llvmlite wheels for four platforms and two Pythons: 377 MB. Figures:
BENCHMARKS.md, section pm-speed (benchmarks/bench_pm.py).

Records. Refinement runs the passes backwards. Record r adds vertex
``n_base_vertices + r`` at ``pos[r]`` next to vertex ``v[r]``. ``mask[r]`` says which
of v's faces (sorted by face index, at the moment of the split) go to the new
vertex; the new faces are derived from the ends of that arc of faces, so a record
costs 24 bytes (float32 position, v, 64-bit mask). ``flags[r]`` bit 0 marks a split
that adds one face (on a boundary); bit 1 says which of the two possible faces.
Any prefix of the records is a valid mesh, and all records give back exactly the
input mesh (vertex order: ``vertex_order``; face order: ``face_order``). The mask's
top 12 bits, unused by faces (v has at most 52 of them there), name the two faces that end the
arc (``ENDS_SHIFT``): .pmwm version 2; version 1 had no such bits (``end_ranks``).

Decoding (``decode``) applies a level's records together, touching only the faces around
their vertices: each vertex keeps its corners in a row of 16 slots, and one gather through a
permutation table indexed by the record's mask splits a row into the new vertex's and the old
one's; the arc ends p and q are read from the two faces the mask names, or, without them, from
sums that telescope around the arc. Issue 13: 2.0-2.5 M records/s before, about twice that with
the sums, and more with the named faces (BENCHMARKS.md, pm-speed and core).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable, Optional, Union

import numpy as np

from .adjacency import Adjacency, build_adjacency, stable_order, unique_values
from .features import face_cross
from .errors import MeshError
from .metrics import bbox_diagonal

Progress = Optional[Callable[[float, str], None]]

MAX_FAN = 64  # faces around v at a split: the mask is 64 bits
FLAG_SINGLE = 1  # the split adds one face (boundary collapse)
FLAG_SECOND = 2  # ... and that face is the one holding the half-edge v -> u
# The mask's top 12 bits, when the PM has ``end_ranks`` and v has at most ENDS_SHIFT faces: the ranks
# among v's faces of the moved faces that end the arc, p's (next to u's corner) then q's, 6 bits each;
# NO_END in both when the record has none. The decoder reads p and q from these two faces.
ENDS_SHIFT = 52
NO_END = 63
_NEXT = np.array([1, 2, 0])  # the next corner of a face
_PREV = np.array([2, 0, 1])
_TO_NEXT = _NEXT - np.arange(3)  # flat corner id -> the next corner's, by corner
_TO_PREV = _PREV - np.arange(3)


@dataclass
class ProgressiveMesh:
    """A base mesh and vertex-split records; ``decode`` gives any level of detail."""

    base_vertices: np.ndarray  # (nb, 3) float64
    base_faces: np.ndarray  # (fb, 3) int64
    pos: np.ndarray  # (R, 3) float64: position of the vertex each record adds
    v: np.ndarray  # (R,) int64: the vertex it splits from
    mask: np.ndarray  # (R,) uint64: which of v's faces move to the new vertex
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
        """The mesh after ``records`` vertex splits (or with ``vertices`` vertices); default: all."""
        if records is not None and vertices is not None:
            raise ValueError("give records or vertices, not both")
        if vertices is not None:
            records = self.records_for_vertices(vertices)
        k = self.n_records if records is None else int(np.clip(records, 0, self.n_records))
        return decode(self, k)


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
        raise ValueError(f"with_positions needs one position per vertex of the progressive mesh ({pm.n_vertices}), "
                         f"got {len(X)}")
    order, nb = pm.vertex_order, pm.n_base_vertices
    return dataclasses.replace(pm, base_vertices=X[order[:nb]], pos=X[order[nb:]],
                               float32=bool(np.all(X.astype(np.float32).astype(np.float64) == X)))


# --------------------------------------------------------------------------- decoding


def decode(pm: ProgressiveMesh, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Apply the first k records to the base mesh, level by level; ``(V (nb + k, 3) float64, F (m, 3) int64)``.

    Only the faces around each level's split vertices are touched: every vertex keeps the list of
    its corners (flat ids into F) in a row of a table, in face order, updated as the records move
    corners and add faces (``_split_chunk``). What does not depend on the mesh (the new faces'
    rows, their corners at u and v) is computed for all records at once, and the output arrays
    are allocated at their final sizes. The previous decoder rescanned all faces per level (about
    ten times the final face count in all). The output is byte-identical to that decoder's at every
    prefix (tests/test_progressive_decode.py checks it against a per-record reference; the .pmwm
    test file keeps digests of the old decoder's output).
    """
    nb = pm.n_base_vertices
    nf = len(pm.base_faces)
    rec = _Records.of(pm, k, nb, nf)
    V = np.empty((nb + k, 3), dtype=np.float64)
    V[:nb] = pm.base_vertices
    V[nb:] = pm.pos[:k]
    F = np.empty((rec.n_faces, 3), dtype=np.int64)
    F[:nf] = pm.base_faces
    rec.fill_faces(F[nf:])
    inc = _Incidence.of(F[:nf], nb + k, np.int32 if 3 * rec.n_faces < 2**31 else np.int64)
    bounds = unique_values(np.r_[0, pm.level_records[pm.level_records < k], k]).tolist()
    for a, b in zip(bounds[:-1], bounds[1:]):
        _split_chunk(rec, F, nb + a, a, b, inc)
    return V, F


@dataclass
class _Records:
    """The first k records with what follows from them alone, per record (k,): where its faces go.
    Compact types: fresh memory costs page faults that weigh as much as the arithmetic here."""

    v: np.ndarray  # int64
    mask: np.ndarray  # uint64
    n_new: np.ndarray  # int64: the number of faces it adds
    u: np.ndarray  # (k,) int64: the vertex it adds
    on: np.ndarray  # (2, k) bool: p is in a new face (then the first is [u, v, p], else [u, q, v]); q is
    at: np.ndarray  # (6, k) corner ids (flat ids in F): the new faces' corners at u, u, v, v (the second
    # pair in the second face, or repeating the first face's u and landing on its p slot with one
    # face), then p's and q's slots (the other's when absent)
    n_faces: int
    ends: Optional[np.ndarray]  # (2, k) int64: flat slots in the fast table of v's corners in the faces
    # that end the arc, p's and q's (``ENDS_SHIFT``); None without end ranks
    no_ends: np.ndarray  # (k + 1,) int64: records before each whose ranks are not both in the fast row
    # (NO_END, or a rank past _FAST - 3): a chunk with any of them finds p and q by the sums

    @staticmethod
    def of(pm: ProgressiveMesh, k: int, nb: int, nf: int) -> "_Records":
        flags = pm.flags[:k]
        single = (flags & FLAG_SINGLE).astype(bool)
        two = ~single
        has1 = ~(single & ((flags & FLAG_SECOND) != 0))
        n_faces = nf + k + int(np.count_nonzero(two))
        it = np.int32 if 3 * n_faces < 2**31 else np.int64
        at = np.empty((6, k), dtype=it)
        c1 = at[0]  # corner 0 of each record's first face
        np.cumsum(two, dtype=it, out=c1)
        c1 -= two
        c1 += np.arange(nf, nf + k, dtype=it)
        c1 *= 3
        np.add(c1, np.where(two, 3, 0).astype(it), out=at[1])  # ... of its second face (c1 with one face)
        np.subtract(c1 + 2, has1, out=at[2], casting="unsafe")
        np.add(at[1], 2, out=at[3])
        np.add(c1 + 1, has1, out=at[4], casting="unsafe")
        at[5] = np.where(two, at[3] - 1, at[4])
        v = np.asarray(pm.v[:k], dtype=np.int64)
        u = np.arange(nb, nb + k)
        ends, no_ends = None, np.zeros(k + 1, dtype=np.int64)
        if pm.end_ranks:
            h = (pm.mask[:k] >> np.uint64(ENDS_SHIFT)).view(np.int64)
            ends = np.stack([h & NO_END, h >> 6])
            np.cumsum((ends >= _FAST - 2).any(axis=0), out=no_ends[1:])  # (NO_END among them)
            ends += v * _FAST
        return _Records(v=v, mask=pm.mask[:k], u=u,
                        n_new=two.astype(np.int64) + 1, on=np.stack([has1, ~has1 | two]), at=at,
                        n_faces=n_faces, ends=ends, no_ends=no_ends)

    def fill_faces(self, new: np.ndarray) -> None:
        """Write the faces the records add, ``new`` (m, 3) in record order, as [u, v, v]: each is
        [u, v, p] or [u, q, v], and the decoding writes p or q over the one v out of place (three
        column writes: faster than scattering u and v to their corners)."""
        new[:, 0] = self.u.repeat(self.n_new)
        new[:, 1] = new[:, 2] = self.v.repeat(self.n_new)


_FAST = 16  # row width of the incidence table on the fast path (degrees up to _FAST - 2)
_LOW = np.array([(1 << i) - 1 for i in range(_FAST - 1)], dtype=np.uint64)  # the low i bits
_PERM: list = []  # lazily: the fast path's permutation table and popcounts (2 MB)


def _perm_table() -> tuple[np.ndarray, np.ndarray]:
    """For every mask m of _FAST - 2 bits: (_FAST,) source slots, first the set bits of m
    ascending, then the clear bits descending from the last slot (so that the reversed row lists
    them ascending); and the popcount of m. Built once per process (about 1 ms) from the same
    table for bytes: m's row is its low byte's row with the high byte's row (+ 8) inserted after
    the low byte's set bits."""
    if not _PERM:
        j = np.arange(8)
        bits = np.unpackbits(np.arange(256, dtype=np.uint8)[:, None], axis=1, bitorder="little").astype(bool)
        row8 = np.argsort(np.where(bits, j, 16 - j), axis=1, kind="stable").astype(np.uint8)
        pop8 = bits.sum(axis=1)
        n_hi = 1 << (_FAST - 10)
        perm = np.empty((n_hi, 256, _FAST), dtype=np.uint8)  # [high byte, low byte]
        for pl in range(9):
            lo = np.flatnonzero(pop8 == pl)
            perm[:, lo, :pl] = row8[lo, :pl]
            perm[:, lo, pl : pl + 8] = (row8[:n_hi] + 8)[:, None, :]
            perm[:, lo, pl + 8 :] = row8[lo, pl:]
        pop = (pop8[:n_hi, None] + pop8[None, :]).reshape(-1)
        _PERM[:] = [perm.reshape(-1, _FAST).astype(np.int64), pop.astype(np.int64)]  # int64: adds in place
    return _PERM[0], _PERM[1]


@dataclass
class _Incidence:
    """Each vertex's corners (flat ids into F), ascending, in slots: the first _FAST in ``main``, the
    rest (high degrees, rare) in ``extra``; ``deg`` of them are live, slots past it are stale.

    ``extra`` starts empty and widens on demand; ``main`` never changes shape, so that the fast path
    always moves whole rows.
    """

    main: np.ndarray  # (n, _FAST) corner ids
    extra: np.ndarray  # (n, X) corner ids, X a multiple of 8
    deg: np.ndarray  # (n,) int64

    @staticmethod
    def of(F: np.ndarray, n: int, dtype) -> "_Incidence":
        flat = F.reshape(-1)
        deg = np.bincount(flat, minlength=n)
        inc = _Incidence(np.zeros((n, _FAST), dtype=dtype), np.zeros((n, 0), dtype=dtype), deg)
        order, vert = stable_order(flat)  # corners grouped by vertex, ascending in each group
        start = np.cumsum(deg) - deg
        inc.put(vert, np.arange(len(flat)) - np.take(start, vert), order)
        return inc

    @property
    def width(self) -> int:
        return _FAST + self.extra.shape[1]

    def fit(self, need: int) -> None:
        """Make room for ``need`` corners per vertex."""
        X = self.extra.shape[1]
        if need > _FAST + X:
            wider = np.zeros((len(self.main), -(-max(need - _FAST, X + X // 2) // 8) * 8), dtype=self.main.dtype)
            wider[:, :X] = self.extra
            self.extra = wider

    def get(self, x: np.ndarray) -> np.ndarray:
        """(len(x), width) the slots of vertices x."""
        rows = np.take(self.main, x, axis=0)
        return np.concatenate([rows, np.take(self.extra, x, axis=0)], axis=1) if self.extra.shape[1] else rows

    def put_rows(self, x, rows: np.ndarray) -> None:
        """Slots 0..rows.shape[1]-1 of vertices x (an index array or a slice) = rows."""
        self.main[x] = rows[:, :_FAST]
        if rows.shape[1] > _FAST:
            self.extra[x, : rows.shape[1] - _FAST] = rows[:, _FAST:]

    def put(self, x: np.ndarray, slot: np.ndarray, val: np.ndarray) -> None:
        """Slot ``slot[i]`` of vertex ``x[i]`` = ``val[i]``, the table widened as needed."""
        top = int(slot.max(initial=0))
        if top >= _FAST:
            self.fit(top + 1)
            big = slot >= _FAST
            s = np.flatnonzero(big)
            self.extra.reshape(-1)[np.take(x, s) * self.extra.shape[1] + np.take(slot, s) - _FAST] = np.take(val, s)
            s = np.flatnonzero(~big)
            x, slot, val = np.take(x, s), np.take(slot, s), np.take(val, s)
        self.main.reshape(-1)[x * _FAST + slot] = val


def _split_chunk(rec: _Records, F: np.ndarray, nv: int, a: int, b: int, inc: _Incidence) -> None:
    """Apply independent records a..b-1 (one level or a prefix of it) in place.

    Record r moves the corners of its vertex v whose rank among v's faces (in face order) is set
    in ``mask[r]`` to the new vertex u = nv + r - a; its new faces [u, v, p] and/or [u, q, v]
    (already in F but for p and q) take the ends p, q of the moved arc. The records' v, p and q
    are distinct, no moved face holds another record's v (``_select``'s rule): the chunk is one
    batch.
    """
    cnt = b - a
    v = rec.v[a:b]
    u = rec.u[a:b]
    deg = inc.deg
    d = deg.take(v)
    mask = rec.mask[a:b]
    flat = F.reshape(-1)
    # move the corners: records of degree above _FAST - 2 (rare) on the general path, first (it may
    # widen the table), the others through the permutation table
    # the lists are read again (not after the last records): they get the new faces' corners at u, v
    new = rec.at[:4, a:b] if b < len(rec.v) else None
    if d.max(initial=0) <= _FAST - 2:
        # the corners that end the arcs, read before the lists change (p after, q before them)
        ends = None if rec.ends is None or rec.no_ends[b] > rec.no_ends[a] else inc.main.reshape(-1).take(rec.ends[:, a:b])
        hit, n_mv = _move_fast(inc, v, slice(nv, nv + cnt), mask, d, new)
        flat[hit] = u.repeat(n_mv)
        # (a rank past v's degree, only in corrupt data, reads a stale slot: a corner of an earlier
        # face, whose vertices are written; p and q are then wrong but vertices of the mesh)
        pq = _arc_ends(flat, hit, n_mv, nv + cnt) if ends is None else flat.take(ends + _ENDS_OFF.take(ends % 3 + _ENDS_ROW))
    else:
        n_mv = np.empty(cnt, dtype=np.int64)
        pq = np.empty((2, cnt), dtype=np.int64)
        fast = d <= _FAST - 2
        fast, wide = np.flatnonzero(fast), np.flatnonzero(~fast)
        for sel, move in [(wide, _move_wide), (fast, _move_fast)]:
            ug = u.take(sel)
            hit, n_g = move(inc, v.take(sel), ug, mask.take(sel), d.take(sel), None if new is None else new[:, sel])
            flat[hit] = ug.repeat(n_g)
            n_mv[sel] = n_g
            pq[:, sel] = _arc_ends(flat, hit, n_g, nv + cnt)
    on = rec.on[:, a:b]  # p's and q's slots: the other's when one is absent
    pq_at = rec.at[4:, a:b].reshape(-1)
    flat[pq_at] = np.where(on, pq, pq[::-1]).reshape(-1)
    if new is None:
        return
    # the lists: one corner at the end of p's and of q's
    n_kp = d - n_mv
    on = on.reshape(-1)
    pq = pq.reshape(-1)[on]
    dpq = deg.take(pq)
    inc.put(pq, dpq, pq_at[on])
    deg[pq] = dpq + 1
    n_new = rec.n_new[a:b]
    deg[nv : nv + cnt] = n_mv + n_new
    deg[v] = n_kp + n_new


def _move_fast(inc: _Incidence, v: np.ndarray, u, mask: np.ndarray, d: np.ndarray,
               new: Optional[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Split the lists of v (degrees <= 14, rows of 16) into u's (the corners whose rank bit is set)
    and v's (the rest), each followed by its new corners ``new`` (4, cnt): u's two, v's two (the
    second ones past the degree with one new face; None: the lists are not kept). u: an index array
    or a slice. Returns the moved corners grouped by record, ascending, and their counts.

    One gather through the permutation table puts the moved corners first and the kept ones last in
    reverse; u's row is that row, v's row the same row reversed (slots past the lists: stale). The
    new corners go into the free middle of the row (at least two slots), u's before u's row is
    stored and v's, which may overwrite them, after.
    """
    perm, pop = _perm_table()
    m = (mask & _LOW.take(d)).view(np.int64)
    rows = inc.main
    at = perm.take(m, axis=0)
    at += (v * _FAST)[:, None]
    row = rows.reshape(-1).take(at)
    n_mv = pop.take(m)
    hit = row.reshape(-1).take(_packed(n_mv, _FAST)).astype(np.int64)
    if new is not None:
        flat = row.reshape(-1)
        at = np.arange(0, _FAST * len(v), _FAST) + n_mv
        flat[at] = new[0]
        at += 1
        flat[at] = new[1]
        rows[u] = row
        at += _FAST - 2 - d  # slot n_kp of v's row, counted from the row's end
        flat[at] = new[2]
        at -= 1
        flat[at] = new[3]
        whole = np.dtype((np.void, row.strides[0]))  # a row as one item: a scatter of rows, 2x faster
        inc.main.view(whole).reshape(-1).put(v, np.ascontiguousarray(row[:, ::-1]).view(whole).reshape(-1))
    return hit, n_mv


def _packed(n: np.ndarray, width: int) -> np.ndarray:
    """Flat ids of the first n[i] slots of each row i of a (len(n), width) array."""
    ends = n.cumsum()
    return (np.arange(0, width * len(n), width) - ends + n).repeat(n) + np.arange(int(ends[-1]) if len(n) else 0)


def _move_wide(inc: _Incidence, v: np.ndarray, u: np.ndarray, mask: np.ndarray, d: np.ndarray,
               new: Optional[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``_move_fast`` for any degree: rank masks by shifts and cumulative sums (ranks past 63, only in
    corrupt data, read bit 63)."""
    take = np.take
    cnt = len(v)
    W = int(d.max(initial=0))
    col = np.arange(W)
    moved = ((mask[:, None] >> np.minimum(col, 63).astype(np.uint64)) & np.uint64(1)).astype(bool)
    moved &= col < d[:, None]
    below = np.cumsum(moved, axis=1) - moved  # moved corners before each one
    n_mv = np.count_nonzero(moved, axis=1).astype(np.int64)
    # room for the lists read and for the new ones with their new corners
    inc.fit(max(W, int(np.maximum(n_mv, d - n_mv).max(initial=0)) + 2))
    C = inc.width
    G = inc.get(v)[:, :W]
    # u's row and v's row side by side in a scratch block; corners past deg(v) land past the new degree
    rel = np.where(moved, below, (col + C) - below)
    buf = np.zeros((cnt, 2, C), dtype=inc.main.dtype)  # zeros: slots past the lists stay valid ids
    base = np.arange(0, 2 * C * cnt, 2 * C)
    buf.reshape(-1)[rel + base[:, None]] = G
    if new is not None:
        at_u, at_v = base + n_mv, base + C + d - n_mv
        buf.reshape(-1)[np.concatenate([at_u, at_u + 1, at_v, at_v + 1])] = new.reshape(-1)
        inc.put_rows(u, buf[:, 0])
        inc.put_rows(v, buf[:, 1])
    return take(buf.reshape(-1), _packed(n_mv, 2 * C)).astype(np.int64), n_mv


_ENDS_OFF = np.concatenate([_TO_NEXT, _TO_PREV])  # p: the vertex after an end face's corner; q: before
_ENDS_ROW = np.array([[0], [3]])


def _arc_ends(flat: np.ndarray, hit: np.ndarray, n_mv: np.ndarray, n: int) -> np.ndarray:
    """Per record, the ends p, q of its moved arc of faces (the moved corners ``hit``, grouped by
    record) as (2, cnt) int64.

    Around the arc, each face's previous vertex is the next one of its neighbour, so the sums of
    (next - previous) and (next^2 - previous^2) over a record's faces telescope to p - q and
    p^2 - q^2 (exact in wrapping 64-bit integers for vertex ids below 2^31). Records whose arc is
    empty or closed, or whose sums give no vertex below ``n`` (only in corrupt data) fall back to
    matching the ends by a tag table (then every end is a vertex of the mesh).
    """
    take = np.take
    corner = hit % 3
    nxt = flat.take(hit + _TO_NEXT.take(corner))
    prv = flat.take(hit + _TO_PREV.take(corner))
    if len(hit) and n < 2**31:  # (a record without moved corners gets s1 == 0 or garbage)
        s = np.empty((2, len(hit)), dtype=np.int64)
        np.subtract(nxt, prv, out=s[0])
        np.multiply(s[0], nxt + prv, out=s[1])
        s = s.cumsum(axis=1).take(n_mv.cumsum() - 1, axis=1)  # sums per record (wrapping is fine)
        s[:, 1:] -= s[:, :-1].copy()
        s1, s2 = s
        if (s1 != 0).all():
            both = s2 // s1  # p + q
            pq = np.concatenate([both + s1, both - s1]).reshape(2, -1)
            pq >>= 1
            if (pq.view(np.uint64) < n).all():
                return pq
    cnt = len(n_mv)
    rec = np.repeat(np.arange(cnt), n_mv)
    tag = np.full(int(max(nxt.max(initial=0), prv.max(initial=0))) + 1, -1, dtype=np.int64)
    tag[prv] = rec
    pe = np.flatnonzero(take(tag, nxt) != rec)
    tag[prv] = -1
    tag[nxt] = rec
    qe = np.flatnonzero(take(tag, prv) != rec)
    pq = np.zeros((2, cnt), dtype=np.int64)
    pq[0, take(rec, pe)] = take(nxt, pe)
    pq[1, take(rec, qe)] = take(prv, qe)
    return pq


# --------------------------------------------------------------------------- encoding


def _plane_rows(n: np.ndarray, d: np.ndarray, w: np.ndarray):
    """The 10 coefficient rows (k,) of the planes n . x + d = 0 weighted by w, one at a time (``out``:
    one (k,) buffer reused, so that a row is only valid until the next is made)."""
    a, b, c = (np.ascontiguousarray(x) for x in n.T)
    wa, wb, wc = w * a, w * b, w * c
    out = np.empty(len(w))
    for x, y in ((wa, a), (wa, b), (wa, c), (wa, d), (wb, b), (wb, c), (wb, d), (wc, c), (wc, d)):
        yield np.multiply(x, y, out=out)
    np.multiply(w, d, out=out)
    out *= d
    yield out


def _plane_quadric(n: np.ndarray, d: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(10, k) coefficients of the planes n . x + d = 0 weighted by w."""
    return np.stack([row.copy() for row in _plane_rows(n, d, w)])


def _quadric_eval_t(Q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Quadric error Q(p) of quadrics Q (10, k) (upper triangle of the 4x4 matrix) at points p (3, k)."""
    x, y, z = p
    return (
        (Q[0] * x + 2 * (Q[1] * y + Q[2] * z + Q[3])) * x
        + (Q[4] * y + 2 * (Q[5] * z + Q[6])) * y
        + (Q[7] * z + 2 * Q[8]) * z
        + Q[9]
    )


def _monomials(V: np.ndarray) -> np.ndarray:
    """(n, 10) per point: the factors of a quadric's coefficients (``_quadric_eval_t``'s order) in
    its value, so that Q(p) is one dot product of two rows."""
    x, y, z = (np.ascontiguousarray(c) for c in V.T)
    M = np.empty((len(V), 10))
    for j, (s, c) in enumerate(((x, x), (x, 2 * y), (x, 2 * z), (2, x), (y, y), (y, 2 * z), (2, y), (z, z), (2, z))):
        np.multiply(s, c, out=M[:, j])
    M[:, 9] = 1.0
    return M


def _vertex_quadrics(V: np.ndarray, F: np.ndarray, bnd: np.ndarray) -> np.ndarray:
    """Sum of face quadrics per vertex, plus boundary-edge constraint planes; (n, 10).

    ``bnd`` (m, 3) bool marks the boundary half-edges F[f, j] -> F[f, j+1].
    """
    n = len(V)
    cr = face_cross(V, F)  # the same bits as np.cross, without (m, 3) gathers of the corners
    area2 = np.sqrt(np.einsum("ij,ij->i", cr, cr))
    normals = cr / np.maximum(area2, 1e-300)[:, None]
    d = -np.einsum("ij,ij->i", normals, np.take(V, F[:, 0], axis=0))
    cols = [np.ascontiguousarray(F[:, j]) for j in range(3)]
    QT = np.empty((10, n))
    # the faces' area-weighted plane quadrics, a coefficient at a time (no (10, m) array)
    for j, q in enumerate(_plane_rows(normals, d, 0.5 * area2)):
        QT[j] = np.bincount(cols[0], weights=q, minlength=n)
        QT[j] += np.bincount(cols[1], weights=q, minlength=n)
        QT[j] += np.bincount(cols[2], weights=q, minlength=n)
    fb, jb = np.nonzero(bnd)
    if len(fb):
        e0, e1 = F[fb, jb], F[fb, _NEXT[jb]]
        ev = V[e1] - V[e0]
        pn = np.cross(ev, normals[fb])
        ln = np.linalg.norm(pn, axis=1)
        pn = pn / np.maximum(ln, 1e-300)[:, None]
        d = -np.einsum("ij,ij->i", pn, V[e0])
        Qb = _plane_quadric(pn, d, 10.0 * np.einsum("ij,ij->i", ev, ev))
        for j in range(10):
            QT[j] += np.bincount(e0, weights=Qb[j], minlength=n) + np.bincount(e1, weights=Qb[j], minlength=n)
    return np.ascontiguousarray(QT.T)


def _boundary_half_edges(F: np.ndarray, adj: Adjacency) -> np.ndarray:
    """(m, 3) bool: the half-edge F[f, j] -> F[f, j+1] has no twin (looked up only between boundary vertices)."""
    a, b = F.ravel(), F[:, _NEXT].ravel()
    bnd = np.zeros(len(a), bool)
    both = np.flatnonzero(adj.boundary_vertex[a] & adj.boundary_vertex[b])
    if len(both):
        bnd[both] = adj.edge_face_count[adj.edge_index(a[both], b[both])] == 1
    return bnd.reshape(-1, 3)


@dataclass
class _Pass:
    u: np.ndarray  # removed vertices (input ids)
    v: np.ndarray  # survivors (input ids)
    flags: np.ndarray
    dead: np.ndarray  # (k, 2) input face ids of the removed faces [f1 (u->v), f2 (v->u)], -1 if absent
    fan_ptr: np.ndarray  # CSR over records: faces around v after the collapse (input face ids)
    fan: np.ndarray
    arc: np.ndarray  # bool per fan entry: goes back to u on the split
    ends: np.ndarray  # (2, fan entries) bool: the arc face ending at p (next to u), at q (before u)


@dataclass
class _Ctx:
    """What stays fixed while encoding: geometry, quadrics (updated in place) and vertex flags."""

    V: np.ndarray  # (n + 1, 3) positions (the last row: the sink)
    VT: np.ndarray  # (3, n + 1) the same, by coordinate
    M: np.ndarray  # (n + 1, 10) the positions' monomials: a quadric's value at V[i] is Q . M[i]
    order: np.ndarray  # (n,) int64: a fixed permutation, the tiebreak of equal cost buckets
    Q: np.ndarray  # (n + 1, 10) vertex quadrics (a row per vertex: one gather is one cache line); v absorbs u
    E: np.ndarray  # (n,) each vertex's own error Q_v(V_v)
    go: np.ndarray  # (n,) bool: may be removed
    locked: np.ndarray  # (n,) bool: may not absorb (non-manifold, isolated)
    bvert: np.ndarray  # (n,) bool: on the boundary (stays so: collapses keep the boundary)
    area_eps: float

    @property
    def n(self) -> int:
        return len(self.V)


@dataclass
class _Live:
    """The live mesh while encoding, with per-corner candidates kept across passes.

    Corner j of face f is the half-edge F[f, j] -> F[f, j+1]; its forward candidate collapses
    F[f, j] into F[f, j+1], its reverse candidate (boundary half-edges only) F[f, j+1] into
    F[f, j]. Costs are recomputed only on the half-edges from and to each pass's survivors.
    Removed faces become (n, n, n) (a sink vertex, tagged never) until the arrays are compacted.
    """

    F: np.ndarray  # (m, 3) int64 input vertex ids (n: removed face)
    fid: np.ndarray  # (m,) input face ids
    bnd: np.ndarray  # (m, 3) bool: the half-edge is on the boundary
    cost: np.ndarray  # (m, 3) forward cost, inf where the vertex flags forbid it or the candidate
    # was found invalid (until its neighbourhood changes)
    rcost: np.ndarray  # (m, 3) reverse cost, inf off the boundary, where forbidden or found invalid
    failed: list = field(default_factory=list)  # arrays of flat corners whose candidate was found invalid
    n_dead: int = 0

    def keep(self, rows: np.ndarray) -> None:
        """Keep the faces ``rows`` ((m,) bool), in order."""
        idx = np.flatnonzero(rows)
        for name in ("F", "fid", "bnd", "cost", "rcost"):
            setattr(self, name, np.take(getattr(self, name), idx, axis=0))
        if self.failed:
            c = np.concatenate(self.failed)
            new = np.cumsum(rows) - 1
            c = c[np.take(rows, c // 3)]
            self.failed = [np.take(new, c // 3) * 3 + c % 3]

    def faces(self, n: int) -> np.ndarray:
        """The live faces (rows without the sink)."""
        return self.F[self.F[:, 0] < n]




_CHUNK = 1 << 15  # corners per block of quadric work (its temporaries stay in cache)


def _update_costs(ctx: _Ctx, live: _Live, corners: np.ndarray) -> None:
    """Recompute the forward (and, on the boundary, reverse) candidates of flat ``corners``.

    Costs are quadric errors, inf where the vertex flags forbid the collapse.
    """
    for s in range(0, len(corners), _CHUNK):
        _update_block(ctx, live, corners[s : s + _CHUNK])


def _update_block(ctx: _Ctx, live: _Live, corners: np.ndarray) -> None:
    # cost of a -> b: (Q_a + Q_b)(V_b) = Q_a(V_b) + E_b, with E_b = Q_b(V_b) kept per vertex
    take = np.take
    Fl = live.F.ravel()
    a = take(Fl, corners)
    b = take(Fl, corners + take(_TO_NEXT, corners % 3))
    bnd = take(live.bnd.ravel(), corners)
    allowed = take(ctx.go, a) & ~take(ctx.locked, b) & (bnd == take(ctx.bvert, a))
    into_b = np.einsum("ij,ij->i", take(ctx.Q, a, axis=0), take(ctx.M, b, axis=0)) + take(ctx.E, b)
    into_b[~allowed] = np.inf
    live.cost.ravel()[corners] = into_b
    # (off the boundary the reverse cost stays inf, as it was made: a corner's side of the boundary
    # never changes)
    rc = live.rcost.ravel()
    on = np.flatnonzero(bnd)
    if len(on):
        a, b = a[on], b[on]
        r = np.einsum("ij,ij->i", take(ctx.Q, b, axis=0), take(ctx.M, a, axis=0)) + take(ctx.E, a)
        r[~(ctx.go[b] & ~ctx.locked[a])] = np.inf
        rc[corners[on]] = r


def _pick(mask: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """``a[mask]`` for each array (1-D, same length as the bool ``mask``), through one flatnonzero and
    gathers: several times faster than boolean indexing when the mask is irregular."""
    i = np.flatnonzero(mask)
    return tuple(np.take(a, i) for a in arrays)


def _bucket(thr: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``np.searchsorted(thr, x, side="right")`` for a few sorted bounds (uint8): one comparison per
    bound, branch-free (a binary search per element mispredicts on unsorted x, ten times slower)."""
    out = np.zeros(len(x), np.uint8)
    for t in thr:
        out += x >= t
    return out


def _any3(m: np.ndarray) -> np.ndarray:
    """Row-wise any of an (m, 3) bool array (faster than .any(axis=1))."""
    return m[:, 0] | m[:, 1] | m[:, 2]


def _corners_of(F: np.ndarray, tag: np.ndarray, rows: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
    """Flat corner ids (into F) whose vertex has tag >= 0, and their tags (int64); only faces ``rows``
    if given."""
    t = np.take(tag, F.ravel() if rows is None else np.take(F, rows, axis=0).ravel())
    c = np.flatnonzero(t >= 0)
    tc = np.take(t, c).astype(np.int64, copy=False)
    if rows is None:
        return c, tc
    return rows[c // 3] * 3 + c % 3, tc


def _tags(nn: int, x: np.ndarray) -> np.ndarray:
    """(nn + 1,) int32: i at vertex x[i] (x distinct), -1 elsewhere (entry nn: the sink's, or none)."""
    tag = np.full(nn + 1, -1, np.int32)
    tag[x] = np.arange(len(x), dtype=np.int32)
    return tag


def _ring_min(F: np.ndarray, val: np.ndarray) -> np.ndarray:
    """Minimum of ``val`` over each vertex's closed 1-ring (through its faces)."""
    g = np.take(val, F)
    fm = np.minimum(np.minimum(g[:, 0], g[:, 1]), g[:, 2])
    out = val.copy()
    for j in range(3):
        np.minimum.at(out, F[:, j], fm)
    return out


# per round, a constant XOR-ed into the tiebreak (a bijection of 32-bit values: ties stay impossible)
_SALTS = np.array([0, 0x5BD1E995, 0x2545F491, 0x7FEB352D, 0x68E31DA4, 0x1B873593, 0x3C6EF372, 0x6A09E667])


@dataclass
class _Chosen:
    """Accepted collapses of a pass and the corners around them (flat ids into the live F)."""

    u: np.ndarray  # (k,)
    v: np.ndarray  # (k,)
    cu: np.ndarray  # corners at u
    ru: np.ndarray  # their record
    cv: np.ndarray  # corners at v
    rv: np.ndarray
    near: np.ndarray  # u's faces (failed candidates on faces touching their vertices get a new chance)

    @staticmethod
    def join(parts: list["_Chosen"]) -> "_Chosen":
        if not parts:
            z = np.zeros(0, np.int64)
            return _Chosen(z, z, z, z, z, z, z)
        off = np.cumsum([0] + [len(p.u) for p in parts[:-1]])
        cat = np.concatenate
        return _Chosen(
            u=cat([p.u for p in parts]), v=cat([p.v for p in parts]),
            cu=cat([p.cu for p in parts]), ru=cat([p.ru + o for p, o in zip(parts, off)]),
            cv=cat([p.cv for p in parts]), rv=cat([p.rv + o for p, o in zip(parts, off)]),
            near=cat([p.near for p in parts]))

    def subset(self, keep: np.ndarray) -> "_Chosen":
        """The records ``keep`` (bool per record), renumbered."""
        new = np.cumsum(keep) - 1
        ku, kv = np.take(keep, self.ru), np.take(keep, self.rv)
        u, v = _pick(keep, self.u, self.v)
        cu, ru = _pick(ku, self.cu, self.ru)
        cv, rv = _pick(kv, self.cv, self.rv)
        return _Chosen(u, v, cu, np.take(new, ru), cv, np.take(new, rv), self.near)


def build_progressive_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    base_vertices: int,
    protected: Union[np.ndarray, Callable[[], np.ndarray], None] = None,
    forced: Optional[np.ndarray] = None,
    progress: Progress = None,
    trace: Optional[list] = None,
    adjacency: Optional[Adjacency] = None,
) -> tuple[ProgressiveMesh, np.ndarray]:
    """Decimate to about ``base_vertices`` vertices; return the PM and the forced pairs applied.

    ``protected`` vertices ((n,) bool) are never removed (they may absorb others); a callable
    returning them is called once the set-up is done, just before the first pass (a caller may start
    the build before it knows them: ``background.Later``). ``forced`` is
    a (k, 2) array of collapses (u, v) performed first, in the first passes, e.g.
    the watermark carriers absorbing their first neighbour. Returns the PM and a
    bool mask of the forced pairs that were applied. ``trace``, when a list, receives
    the faces (input ids) after every pass, for tests of the levels of detail.
    ``adjacency`` may pass the input's adjacency when the caller has it already.
    """
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F0 = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    n = len(V)
    if len(F0) and (F0.min() < 0 or F0.max() >= n):
        raise MeshError("a face refers to a vertex that does not exist; repair the mesh and retry")
    if np.any((F0[:, 0] == F0[:, 1]) | (F0[:, 1] == F0[:, 2]) | (F0[:, 0] == F0[:, 2])):
        raise MeshError("the mesh has faces that repeat a vertex; remove degenerate faces first")
    adj0 = adjacency if adjacency is not None else build_adjacency(F0, n)
    # vertex arrays get one more entry: the sink n that removed faces point to
    locked = np.r_[adj0.nonmanifold_vertex | adj0.isolated_vertex, True]
    keep = np.zeros(n + 1, bool)
    if protected is not None and not callable(protected):
        keep[:n] = np.asarray(protected, bool)
    bbox = bbox_diagonal(V) if n else 1.0
    bnd = _boundary_half_edges(F0, adj0)
    Q = np.zeros((n + 1, 10))
    Q[:n] = _vertex_quadrics(V, F0, bnd)
    Vs = np.zeros((n + 1, 3))
    Vs[:n] = V
    ctx = _Ctx(V=Vs, VT=np.ascontiguousarray(Vs.T), M=_monomials(Vs), order=np.r_[np.random.default_rng(n).permutation(n), n], Q=Q, E=_quadric_eval_t(Q.T, Vs.T),
               go=~locked & ~keep, locked=locked, bvert=np.r_[adj0.boundary_vertex, False], area_eps=(1e-12 * bbox) ** 2)
    m = len(F0)
    live = _Live(F=F0.copy(), fid=np.arange(m, dtype=np.int64), bnd=bnd, cost=np.empty((m, 3)),
                 rcost=np.full((m, 3), np.inf))
    _update_costs(ctx, live, np.arange(3 * m))
    if callable(protected):
        _protect(ctx, live, np.asarray(protected(), bool))

    alive = np.ones(n, bool)  # by input id
    ids = np.arange(n, dtype=np.int64)  # input id of each local vertex (the arrays shrink as vertices go)
    n_alive = n
    target = max(int(base_vertices), 4)
    passes: list[_Pass] = []
    forced_pairs = np.zeros((0, 2), np.int64) if forced is None else np.asarray(forced, np.int64).reshape(-1, 2)
    forced_done = np.zeros(len(forced_pairs), bool)
    total = max(n_alive - target, 1)
    stalls = 0
    cnt = np.bincount(live.F.ravel(), minlength=n + 1)  # faces per vertex (_collapse keeps it up to date)
    while True:
        todo = np.flatnonzero(~forced_done)
        forced_phase = len(todo) > 0 and stalls < 4
        if not forced_phase and n_alive <= target:
            break
        nl = len(ids)  # local vertices; nl is the sink
        if forced_phase:
            local = np.full(n, nl, np.int64)  # a removed vertex maps to the sink: no edge
            local[ids] = np.arange(nl)
            pairs = local[forced_pairs[todo]]
            ch = _select_forced(ctx, live, cnt, pairs)
            hit = np.isin(pairs[:, 0] * (nl + 1) + pairs[:, 1], ch.u * (nl + 1) + ch.v)
            forced_done[todo[hit]] = True
        else:
            ch = _select(ctx, live, cnt)
            room = n_alive - target
            if len(ch.u) > room:
                qs = ctx.Q[ch.u] + ctx.Q[ch.v]
                first = np.argsort(_quadric_eval_t(qs.T, ctx.V[ch.v].T), kind="stable")[:room]
                keep_rec = np.zeros(len(ch.u), bool)
                keep_rec[first] = True
                ch = ch.subset(keep_rec)
        if len(ch.u) == 0:
            stalls += 1
            if not forced_phase:
                break
            continue
        p = _collapse(ctx, live, ch, cnt)
        p.u, p.v = ids[p.u], ids[p.v]
        passes.append(p)
        alive[p.u] = False
        n_alive -= len(p.u)
        if progress is not None:
            progress(min(1.0, (n - n_alive) / total), f"progressive mesh: {n_alive} vertices")
        if trace is not None:
            trace.append(ids[live.faces(nl)])
        if 2 * n_alive < nl:
            ctx, ids = _compact(ctx, live, ids, alive[ids])
            cnt = np.bincount(live.F.ravel(), minlength=len(ids) + 1)
    F_end = live.F[:, 0] < len(ids)
    pm = _assemble(V, F0, ids[live.F[F_end]], live.fid[F_end], alive, passes)
    return pm, forced_done


def _protect(ctx: _Ctx, live: _Live, protected: np.ndarray) -> None:
    """Forbid removing the ``protected`` vertices ((n,) bool) after the costs were first computed:
    the candidates from and (reverse, on the boundary) into them computed again, the others as they
    were, so that the costs are those of a build protecting them from the start."""
    n = len(ctx.go) - 1
    if protected.shape != (n,):
        raise ValueError(f"protected: expected ({n},) bool, got shape {protected.shape}")
    ctx.go[:n] &= ~protected
    hit = np.take(np.r_[protected, False], live.F)
    _update_costs(ctx, live, np.flatnonzero((hit | hit[:, _NEXT]).ravel()))


def _compact(ctx: _Ctx, live: _Live, ids: np.ndarray, keep: np.ndarray) -> tuple[_Ctx, np.ndarray]:
    """Renumber the live vertices 0..k-1 (sink k) so per-vertex work follows the shrinking mesh."""
    nl = len(ids)
    kept = np.flatnonzero(keep)
    k = len(kept)
    new_id = np.full(nl + 1, k, np.int64)
    new_id[kept] = np.arange(k)
    live.keep(live.F[:, 0] < nl)
    live.n_dead = 0
    live.F = new_id[live.F]
    sel = np.r_[kept, nl]  # the old sink's entries (locked, zero quadric) serve the new sink
    return _Ctx(V=ctx.V[sel], VT=np.take(ctx.VT, sel, axis=1), M=ctx.M[sel], order=ctx.order[sel], Q=ctx.Q[sel], E=ctx.E[sel], go=ctx.go[sel],
                locked=ctx.locked[sel], bvert=ctx.bvert[sel], area_eps=ctx.area_eps), ids[kept]


_BUCKETS = 16
_PLAY_BUCKETS = 8  # a pass's winners come from the cheaper buckets only
_SAMPLE = 4096  # costs the bucket bounds are taken from
_BIG = np.iinfo(np.int64).max


def _best(ctx: _Ctx, live: _Live) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per vertex, the cost of its cheapest live candidate; and the live cost arrays."""
    fwd, rev = live.cost, live.rcost
    best = np.full(len(ctx.go), np.inf)
    F = live.F
    for j in range(3):
        np.minimum.at(best, F[:, j], fwd[:, j])
    b = np.flatnonzero(np.isfinite(rev.ravel()))
    if len(b):
        np.minimum.at(best, F.ravel()[(b // 3) * 3 + _NEXT[b % 3]], rev.ravel()[b])
    return best, fwd, rev


def _around(live: _Live, nn: int, wv, cu, ru) -> tuple[np.ndarray, ...]:
    """Corners at each winner's v, the faces touching each winner's closed 1-ring by record, and
    who holds each vertex in a 1-ring (``_owners``' triple).

    The winners' closed 1-rings are disjoint (their u are three edges apart), so one tag table
    labels them all: as ``_owners``' triple, the least and the greatest holder are both that tag, and no
    vertex has a third.
    """
    F = live.F
    tag = np.full(nn, -1, np.int64)
    tag[np.take(F, cu // 3, axis=0)] = ru[:, None]
    c2, r2 = _corners_of(F, tag)
    at_v = np.take(F.ravel(), c2) == np.take(wv, r2)
    return c2[at_v], r2[at_v], c2 // 3, r2, (tag, tag, np.zeros(nn, bool))


def _owners(nn: int, x: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Who holds each vertex in their 1-ring: the least and the greatest record ``r`` paired with it in
    ``x`` ((nn + 1,) int64 each; for none, outside 0..k-1: _BIG and -1) and whether a third record also
    does ((nn + 1,) bool).

    The winners' 1-rings may overlap (their u are only non-adjacent), so one tag per vertex is not
    enough; two are, but for vertices between three winners (few), where membership is undecided.
    """
    lo = np.full(nn + 1, _BIG, np.int64)
    np.minimum.at(lo, x, r)
    hi = np.full(nn + 1, -1, np.int64)
    np.maximum.at(hi, x, r)
    many = np.zeros(nn + 1, bool)
    many[x[(r != np.take(lo, x)) & (r != np.take(hi, x))]] = True
    return lo, hi, many


def _member(own: tuple[np.ndarray, np.ndarray, np.ndarray], x: np.ndarray,
            r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether vertex x[i] is in record r[i]'s 1-ring (by ``_owners``), and whether that is undecided."""
    lo, hi, many = own
    yes = (np.take(lo, x) == r) | (np.take(hi, x) == r)
    return yes, ~yes & np.take(many, x)


_ROUNDS = 1  # Luby rounds per pass (more are only run while none was accepted)


@dataclass
class _Round:
    """What the selection rounds of one pass share (arrays updated in place)."""

    ctx: _Ctx
    live: _Live
    cnt: np.ndarray  # (nn + 1,) faces per vertex at the start of the pass
    best: np.ndarray  # (nn,) each vertex's cheapest candidate cost (inf: out of play)
    key: np.ndarray  # (nn,) priorities
    thr: np.ndarray  # cost bucket bounds
    held: np.ndarray  # (nn + 1,) bool: K vertices of the accepted collapses (entry nn: no vertex)
    acc_v: np.ndarray  # (nn,) v of each accepted u, else -1
    parts: list


def _attempt(s: _Round, rows, wu: np.ndarray, val: np.ndarray, last: bool) -> None:
    """Try each winner's cheapest candidate (winners: pairwise non-adjacent vertices of the faces in
    play, rows ``rows`` of the live faces or all when None; ``val``: their priorities by vertex).
    Accepted collapses go to ``s.parts``; ``last``: no round follows if any is accepted."""
    take = np.take
    ctx, live, best = s.ctx, s.live, s.best
    fwd, rev = live.cost, live.rcost
    nn = len(ctx.go)
    F = live.F
    Fl = F.reshape(-1)
    k = len(wu)
    cu, ru = _corners_of(F, _tags(nn, wu), rows)  # the corners at the winners
    # each winner's cheapest candidate, among its corners: forward u -> next, reverse u -> previous
    pc = cu + take(_TO_PREV, cu % 3)  # the corner of the half-edge arriving at u
    cf, cr = take(fwd, cu), take(rev, pc)
    bw = take(take(best, wu), ru)
    cand = np.concatenate([np.where(cf == bw, 2 * cu, _BIG), np.where(cr == bw, 2 * pc + 1, _BIG)])
    pick = np.full(k, _BIG, np.int64)
    np.minimum.at(pick, np.concatenate([ru, ru]), cand)
    rev_pick = (pick & 1).astype(bool)
    pcorner = pick >> 1
    wv = take(Fl, np.where(rev_pick, pcorner, pcorner + take(_TO_NEXT, pcorner % 3)))
    # K = v, a, b (nn where a face is absent, on the boundary)
    f3 = cu - cu % 3
    nxt = take(Fl, f3 + take(_NEXT, cu % 3))
    prv = take(Fl, f3 + take(_PREV, cu % 3))
    K = np.full((3, k), nn, np.int64)
    K[0] = wv
    vu = take(wv, ru)
    i = np.flatnonzero(nxt == vu)
    K[1, take(ru, i)] = take(prv, i)
    i = np.flatnonzero(prv == vu)
    K[2, take(ru, i)] = take(nxt, i)
    pri = take(val, wu)
    least = np.full(nn + 1, _BIG, np.int64)
    np.minimum.at(least, K.reshape(-1), np.tile(pri, 3))
    Kv = take(least, K) == pri
    Kv |= K == nn
    free = Kv[0] & Kv[1] & Kv[2]  # no winner of a better priority shares a K vertex
    sel = free
    if s.parts:  # (later rounds) not a K vertex of an accepted collapse
        hk = take(s.held, K)
        sel = sel & ~(hk[0] | hk[1] | hk[2])
    if not sel.any():
        return
    # go on with the selected winners (renumbered)
    new = np.cumsum(sel) - 1
    (ku,) = np.nonzero(take(sel, ru))
    cu, ru, nxt, prv, pc = (take(x, ku) for x in (cu, ru, nxt, prv, pc))
    ru = take(new, ru)
    wu, wv, pcorner, rev_pick, pri = _pick(sel, wu, wv, pcorner, rev_pick, pri)
    K = K[:, np.flatnonzero(sel)]
    k = len(wu)
    cv, rv = _corners_of(F, _tags(nn, wv), rows)  # the corners at their v (distinct)
    own = _owners(nn, np.concatenate([nxt, prv]), np.concatenate([ru, ru]))
    ok, undecided = _valid(ctx, live, s.cnt, wu, wv, cu, ru, cv, rv, own, check_flips=True)
    # the third rule: v_i by u_j and v_j by u_i, with j accepted or a winner of a better priority
    late = np.zeros(k, bool)
    if s.parts:
        fv3 = cv - cv % 3
        y = np.concatenate([take(Fl, fv3 + take(_NEXT, cv % 3)), take(Fl, fv3 + take(_PREV, cv % 3))])
        yr = np.concatenate([rv, rv])
        (i,) = np.nonzero(take(s.acc_v, y) >= 0)  # an accepted u by v_i: does its v lie by u_i?
        yes, unsure = _member(own, take(s.acc_v, take(y, i)), take(yr, i))
        late[take(yr, i)[yes | unsure]] = True
    lo, hi, many = own
    lose = take(many, wv)  # v_i held by a third winner: left for later
    for oj in (lo, hi):
        j = take(oj, wv)  # a winner holding v_i in its 1-ring
        i = np.flatnonzero((j >= 0) & (j < k) & (j != np.arange(k)))
        j = take(j, i)
        yes, unsure = _member(own, take(wv, j), i)
        lose[i[(yes | unsure) & take(ok, j) & (take(pri, j) < take(pri, i))]] = True
    acc = ok & ~lose & ~late
    # failed candidates leave the running; their vertices try their next candidate
    bad = ~ok & ~undecided
    live.failed.append(pcorner[bad])
    fwd.ravel()[pcorner[bad & ~rev_pick]] = np.inf
    rev.ravel()[pcorner[bad & rev_pick]] = np.inf
    if acc.any():
        (fa,) = _pick(take(acc, ru), cu // 3)
        s.parts.append(_Chosen(wu, wv, cu, ru, cv, rv, fa).subset(acc))
        if last:  # (what follows only serves later rounds of the pass)
            return
    best[wu[bad]] = np.inf
    sb = bad[ru]
    if sb.any():
        np.minimum.at(best, wu[ru[sb]], np.minimum(fwd.ravel()[cu[sb]], rev.ravel()[pc[sb]]))
        wb = wu[bad]
        s.key[wb] = (_bucket(s.thr, best[wb]).astype(np.int64) << 32) | ctx.order[wb]
    if acc.any():
        best[take(F, fa, axis=0)] = np.inf  # the accepted u's closed 1-rings leave the running
        ka = np.flatnonzero(acc)
        s.held[take(K, ka, axis=1)] = True
        s.held[nn] = False
        s.acc_v[take(wu, ka)] = take(wv, ka)


def _select(ctx: _Ctx, live: _Live, cnt: np.ndarray, rounds: Optional[int] = None) -> _Chosen:
    """Independent valid collapses u -> v, cheapest first.

    Independent: for any two collapses i and j of a pass, u_i and u_j are not adjacent; their
    vertices K = {v, a, b} (a, b: the third vertices of the faces that vanish) are disjoint; and
    not both v_i is a neighbour of u_j and v_j one of u_i (both would create the edge v_i v_j).
    Then no face holds two u, nothing one collapse changes is read by another's tests, and the
    vertex splits of a level touch disjoint vertex lists, so the pass is applied, and its splits
    undone, at once (``_collapse``, ``_split_chunk``). The former rule (the closed 1-rings of
    the u disjoint) took four rounds per pass for about 10 % of the vertices; this one takes
    9-10 % in one round, at a fraction of the cost (more rounds take more per pass but cost more
    than the passes they save: BENCHMARKS.md, pm-speed).

    A round: a vertex in play whose priority (its cheapest candidate's cost quantile bucket,
    then a fixed pseudo-random order, Luby-style) is the least in its closed 1-ring wins, if its
    bucket is among the cheaper half (without that, a 1-ring minimum is often an expensive
    collapse among more expensive ones: the levels' Hausdorff distances were up to 12 times
    larger; BENCHMARKS.md, pm-speed); winners
    sharing a K vertex with one of a better priority or with an accepted collapse drop out; the
    rest are validated (``_valid``) and the pairs of the third rule settled by priority
    (``_attempt``). Accepted collapses take their closed 1-ring out of play; failed candidates
    are marked, so that the vertex tries its next one. Rounds go on (up to ``rounds``, or while
    none was accepted) on the faces around the vertices still in play.
    """
    rounds = _ROUNDS if rounds is None else rounds
    nn = len(ctx.go)
    F = live.F
    take = np.take
    best, fwd, rev = _best(ctx, live)
    fin = best[np.isfinite(best)]
    if len(fin) == 0:
        return _Chosen.join([])
    step = max(1, len(fin) // _SAMPLE)  # bucket bounds from a fixed subsample: they need not be exact
    # (sorted first: numpy's SIMD sort and a selection in sorted data beat the selection alone)
    thr = np.quantile(np.sort(fin[::step]), np.arange(1, _BUCKETS) / _BUCKETS)
    key = (_bucket(thr, best).astype(np.int64) << 32) | ctx.order  # priority
    s = _Round(ctx, live, cnt, best, key, thr, np.zeros(nn + 1, bool), np.full(nn, -1, np.int64), [])
    rows = None  # faces in play (None: all)
    Fr = F
    for r in range(64):
        if r >= rounds and s.parts:
            break
        bu = np.flatnonzero(np.isfinite(best))
        if len(bu) == 0:
            break
        if r >= 2:  # keep the faces within one ring of a vertex still in play
            in_play = np.zeros(nn, bool)
            in_play[bu] = True
            in_play[take(Fr, np.flatnonzero(_any3(take(in_play, Fr))), axis=0)] = True
            keep = np.flatnonzero(_any3(take(in_play, Fr)))
            rows = keep if rows is None else take(rows, keep)
            Fr = take(Fr, keep, axis=0)
        # only the cheaper half of the costs may win: the levels stay close to a greedy order
        cheap = bu[(take(key, bu) >> 32) < _PLAY_BUCKETS]
        cheap = cheap if len(cheap) else bu
        salt = _SALTS[r % len(_SALTS)]
        val = np.full(nn, _BIG, np.int64)
        val[cheap] = take(key, cheap) ^ salt
        (wu,) = _pick(take(val, cheap) == take(_ring_min(Fr, val), cheap), cheap)
        _attempt(s, rows, wu, val, last=r + 1 >= rounds)
    return _Chosen.join(s.parts)


def _select_forced(ctx: _Ctx, live: _Live, cnt: np.ndarray, pairs: np.ndarray) -> _Chosen:
    """The forced collapses that can go in this pass, earliest first, u three edges apart."""
    nn = len(ctx.go)
    F = live.F
    rank = np.full(nn, _BIG, np.int64)
    np.minimum.at(rank, pairs[:, 0], np.arange(len(pairs), dtype=np.int64))
    parts: list[_Chosen] = []
    for _ in range(64):
        bu = np.flatnonzero(rank < _BIG)
        if len(bu) == 0:
            break
        m2 = _ring_min(F, _ring_min(F, rank))
        wu = bu[rank[bu] == m2[bu]]
        wv = pairs[rank[wu], 1]
        tag = np.full(nn, -1, np.int64)
        tag[wu] = np.arange(len(wu))
        cu, ru = _corners_of(F, tag)
        cv, rv, near_f, near_r, own = _around(live, nn, wv, cu, ru)
        Fl = F.ravel()
        fu, ju = cu // 3, cu % 3
        edge = (Fl[fu * 3 + _NEXT[ju]] == wv[ru]) | (Fl[fu * 3 + _PREV[ju]] == wv[ru])
        if np.any(np.bincount(ru[edge], minlength=len(wu)) == 0):
            raise MeshError("internal error: a forced collapse is not an edge of the mesh")
        ok, _ = _valid(ctx, live, cnt, wu, wv, cu, ru, cv, rv, own, check_flips=False)
        rank[wu[~ok]] = _BIG
        if ok.any():
            acc = ok[near_r]
            rank[F[near_f[acc]]] = _BIG
            parts.append(_Chosen(wu, wv, cu, ru, cv, rv, (cu // 3)[ok[ru]]).subset(ok))
    return _Chosen.join(parts)


def _valid(ctx: _Ctx, live: _Live, cnt, u, v, cu, ru, cv, rv, own, check_flips=True) -> tuple[np.ndarray, np.ndarray]:
    """Link condition, enough edges left, no new boundary, no flipped faces (optionally).

    ``cu``, ``ru`` / ``cv``, ``rv``: the flat corners at the u / at the v and their record;
    ``own``: which records hold each vertex in their u's 1-ring (``_owners``). Returns which
    collapses are valid, and which could not be decided (a common neighbour of u and v held by
    three records: not valid, but not found invalid either).
    """
    k = len(u)
    if k == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    take = np.take
    Fl = live.F.ravel()
    bl = live.bnd.ravel()
    fu, ju = cu // 3, cu % 3
    vu = take(v, ru)
    has_v = (take(Fl, fu * 3 + take(_NEXT, ju)) == vu) | (take(Fl, fu * 3 + take(_PREV, ju)) == vu)
    rd, fd = _pick(has_v, ru, fu)
    ndead = np.bincount(rd, minlength=k)
    # common neighbours of u and v: v's neighbours (each once: the next vertex of every face at v,
    # and the previous one across a boundary half-edge) that lie in u's 1-ring
    fv, jv = cv // 3, cv % 3
    w = take(Fl, fv * 3 + take(_NEXT, jv))
    pb = fv * 3 + take(_PREV, jv)
    on_b = take(bl, pb)
    pbb, rvb = _pick(on_b, pb, rv)
    w = np.concatenate([w, take(Fl, pbb)])
    wr = np.concatenate([rv, rvb])
    yes, unsure = _member(own, w, wr)
    undecided = np.zeros(k, bool)
    undecided[wr[unsure]] = True
    w, crec = _pick(yes & (w != take(u, wr)), w, wr)
    n_common = np.bincount(crec, minlength=k)
    bedge = ndead == 1
    ok = (ndead >= 1) & (n_common == np.where(bedge, 1, 2))
    # the opposite vertices must keep enough edges (no two faces folded onto each other)
    valence = take(cnt, w) + take(ctx.bvert, w)
    ok[crec[valence < take(np.where(bedge, 3, 4), crec)]] = False
    ok &= cnt[u] > ndead  # an arc of faces remains to hand back
    ok &= cnt[u] + cnt[v] - 2 * ndead <= MAX_FAN
    # the removed faces hold no boundary edge but the collapsed one (the boundary stays as it is)
    # (counted as integers: a face with two boundary edges, an ear, must not pass for one with one)
    nbd = np.bincount(rd, weights=np.take(live.bnd, fd, axis=0).sum(axis=1), minlength=k)
    ok &= nbd == bedge
    if check_flips:
        # a face (u, b, c) that stays becomes (v, b, c): its normal (b - u) x (c - b) turns into
        # (b - v) x (c - b); no flip (cosine of the turn at least 0.2) and no sliver
        mv = np.flatnonzero(~has_v)
        f3, j = take(fu, mv) * 3, take(ju, mv)
        r = take(ru, mv)
        b = take(Fl, f3 + take(_NEXT, j))
        c = take(Fl, f3 + take(_PREV, j))
        e, du, dv = [], [], []
        for X in ctx.VT:
            xb = take(X, b)
            e.append(take(X, c) - xb)
            du.append(xb - take(take(X, u), r))
            dv.append(xb - take(take(X, v), r))
        dot = nb2 = na2 = 0.0
        for i in range(3):
            j1, j2 = (i + 1) % 3, (i + 2) % 3
            nb_i = du[j1] * e[j2] - du[j2] * e[j1]
            na_i = dv[j1] * e[j2] - dv[j2] * e[j1]
            dot = dot + nb_i * na_i
            nb2 = nb2 + nb_i * nb_i
            na2 = na2 + na_i * na_i
        prod = np.sqrt(nb2 * na2)
        bad = (dot < 0.2 * prod) | (prod == 0) | (na2 < ctx.area_eps * ctx.area_eps)
        ok[r[bad]] = False
    return ok & ~undecided, undecided


def _arc_end_faces(nxt: np.ndarray, prv: np.ndarray, r: np.ndarray, pq: np.ndarray) -> np.ndarray:
    """Which faces end each collapse's arc, (2, len(r)) bool (p's end, q's), as the decoder will find
    them: ``nxt``, ``prv`` the vertices after and before u in each arc face, ``r`` their records; ``pq``
    (2, k) each record's p and q, the third vertices of its vanishing faces, -1 for a face it has not
    (on a boundary): then that end follows from the other and the sum of (next - previous) around the
    arc, p - q (the sum telescopes; exact in float64 below 2^53)."""
    miss = pq < 0
    if miss.any():
        s1 = np.bincount(r, weights=nxt - prv, minlength=pq.shape[1]).astype(np.int64)
        pq = np.where(miss, pq[::-1] + np.stack([s1, -s1]), pq)
    return np.stack([nxt == np.take(pq[0], r), prv == np.take(pq[1], r)])


def _collapse(ctx: _Ctx, live: _Live, ch: _Chosen, cnt: np.ndarray) -> _Pass:
    """Apply independent collapses u -> v to the live mesh, and to ``cnt`` (nn + 1,) int64, its corners
    per vertex (as ``np.bincount(live.F.ravel())``: the sink's entry counts the retired faces' corners);
    returns the records' data."""
    u, v = ch.u, ch.v
    k = len(u)
    n = len(ctx.go) - 1
    F = live.F
    Fl = F.ravel()
    cu, ru, cv, rv = ch.cu, ch.ru, ch.cv, ch.rv
    fu, ju = cu // 3, cu % 3
    vu = np.take(v, ru)
    d1 = np.take(Fl, fu * 3 + np.take(_NEXT, ju)) == vu  # f1 holds the half-edge u -> v
    d2 = np.take(Fl, fu * 3 + np.take(_PREV, ju)) == vu  # f2 holds v -> u
    dead = np.full((k, 2), -1, np.int64)
    pq = np.full((2, k), -1, np.int64)  # the split's p and q: the vanishing faces' third vertices
    for col, (d, to) in enumerate(((d1, _TO_PREV), (d2, _TO_NEXT))):
        r_d, f_d, c_d = _pick(d, ru, fu, cu)
        dead[r_d, col] = np.take(live.fid, f_d)
        pq[col, r_d] = np.take(Fl, c_d + np.take(to, c_d % 3))
    single = (dead < 0).any(axis=1)
    flags = np.where(single, FLAG_SINGLE | np.where(dead[:, 0] < 0, FLAG_SECOND, 0), 0).astype(np.uint8)
    arc = ~(d1 | d2)
    fv = cv // 3
    (gone,) = _pick(~arc, fu)
    is_gone = np.zeros(len(F), bool)
    is_gone[gone] = True
    vkeep = ~np.take(is_gone, fv)
    # the faces around v after the collapse: u's arc, then v's own; their corners at v
    cu_a, ru_a = _pick(arc, cu, ru)
    cv_k, rv_k = _pick(vkeep, cv, rv)
    at = np.concatenate([cu_a, cv_k])
    j_at = at % 3
    into = at + np.take(_TO_PREV, j_at)  # the corners before them: the half-edges into v
    n_arc = len(cu_a)
    nxt_a = np.take(Fl, cu_a + np.take(_TO_NEXT, j_at[:n_arc]))
    ends_a = _arc_end_faces(nxt_a, np.take(Fl, into[:n_arc]), ru_a, pq)
    all_r = np.concatenate([ru_a, rv_k])
    all_f = at // 3
    all_arc = np.concatenate([np.ones(len(cu_a), bool), np.zeros(len(cv_k), bool)])
    order, _ = stable_order(all_r)
    fan_ptr = np.zeros(k + 1, np.int64)
    np.cumsum(np.bincount(all_r, minlength=k), out=fan_ptr[1:])
    p = _Pass(u=u.copy(), v=v.copy(), flags=flags, dead=dead, fan_ptr=fan_ptr,
              fan=np.take(live.fid, np.take(all_f, order)), arc=np.take(all_arc, order),
              ends=np.take(np.pad(ends_a, ((0, 0), (0, len(cv_k)))), order, axis=1))
    # apply: rewrite u -> v in the arc faces, retire the dead faces to the sink, merge the quadrics
    Fl[cu_a] = np.take(v, ru_a)
    g3 = (gone * 3)[:, None] + np.arange(3)
    # faces per vertex: the vanishing faces leave their vertices, u's others go to v (each face holds
    # one u at most; the v are distinct, and no vanishing face of one collapse holds another's u or v)
    np.subtract.at(cnt, np.take(Fl, g3).ravel(), 1)
    cnt[v] += np.take(cnt, u)
    cnt[u] = 0
    cnt[n] += 3 * len(gone)
    Fl[g3] = n
    live.cost.reshape(-1)[g3] = np.inf
    live.rcost.reshape(-1)[g3] = np.inf
    live.n_dead += len(gone)
    Qv = np.take(ctx.Q, v, axis=0)
    Qv += np.take(ctx.Q, u, axis=0)
    ctx.Q[v] = Qv
    Ev = np.einsum("ij,ij->i", Qv, np.take(ctx.M, v, axis=0))
    dE = Ev - np.take(ctx.E, v)
    ctx.E[v] = Ev
    # costs change on the half-edges from and to v (the corners at v and the previous ones). Into v
    # from its own faces, Q_a(V_v) stays: the cost moves by v's own error's change (off the boundary,
    # where no reverse candidate needs Q_v; the full updates that follow overwrite any corner from
    # another record's v). Failed candidates get another chance nearby.
    own = into[n_arc:]
    on_b = np.take(live.bnd.reshape(-1), own)
    shift = np.flatnonzero(~on_b)
    live.cost.reshape(-1)[np.take(own, shift)] += np.take(dE, np.take(all_r[n_arc:], shift))
    _update_costs(ctx, live, np.concatenate([at, into[:n_arc], *_pick(on_b, own)]))
    if live.failed:
        c = np.concatenate(live.failed)
        ring = np.zeros(n + 1, bool)  # the u's former 1-rings (their faces now hold v)
        ring[np.take(F, ch.near, axis=0)] = True
        ring[n] = False
        at_v = np.zeros(len(F), bool)
        at_v[fv] = True
        f = c // 3
        again = _any3(np.take(ring, np.take(F, f, axis=0))) | np.take(at_v, f)
        _update_costs(ctx, live, *_pick(again, c))
        live.failed = list(_pick(~again, c))
    if live.n_dead * 4 > len(F):
        live.keep(F[:, 0] < n)
        live.n_dead = 0
        cnt[n] = 0
    return p


def _end_ranks(ends: np.ndarray, rec: np.ndarray, rank: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The top bits of a pass's masks (``ENDS_SHIFT``), (k,) uint64: the ranks of the fan entries that
    end each record's arc (``ends`` (2, fan entries) bool, sorted as ``rank``; ``rec`` their records);
    NO_END for a record without exactly one end of each kind; nothing for a record with more than
    ENDS_SHIFT faces (its top bits are rank bits)."""
    k = len(sizes)
    r = np.full((2, k), NO_END, np.uint64)
    one = np.ones(k, bool)
    for j in range(2):
        at = np.flatnonzero(ends[j])
        r[j, np.take(rec, at)] = np.take(rank, at)
        one &= np.bincount(np.take(rec, at), minlength=k) == 1
    r[:, ~one] = NO_END
    out = (r[0] | (r[1] << np.uint64(6))) << np.uint64(ENDS_SHIFT)
    return np.where(sizes > ENDS_SHIFT, np.uint64(0), out)


def _assemble(V, F0, F_end, fid_end, alive, passes: list[_Pass]) -> ProgressiveMesh:
    """Number vertices and faces in refinement order and encode the records."""
    n = len(V)
    base_ids = np.flatnonzero(alive)
    rev = passes[::-1]
    u_ref = np.concatenate([p.u for p in rev]) if rev else np.zeros(0, np.int64)
    v_ref = np.concatenate([p.v for p in rev]) if rev else np.zeros(0, np.int64)
    flags = np.concatenate([p.flags for p in rev]) if rev else np.zeros(0, np.uint8)
    dead = np.concatenate([p.dead for p in rev]) if rev else np.zeros((0, 2), np.int64)
    R = len(u_ref)
    vertex_order = np.concatenate([base_ids, u_ref])
    pm_of = np.empty(n, np.int64)
    pm_of[vertex_order] = np.arange(n)

    base_f = np.sort(fid_end)
    new_faces = dead.reshape(-1)
    new_faces = new_faces[new_faces >= 0]
    face_order = np.concatenate([base_f, new_faces])
    fpm_of = np.empty(len(F0), np.int64)
    fpm_of[face_order] = np.arange(len(face_order))

    # masks: fan entries of each record sorted by PM face index; arc entries set bits (pass by pass:
    # the temporaries stay small)
    mask = np.zeros(R, np.uint64)
    r0 = 0
    for p in rev:
        k = len(p.u)
        sizes = np.diff(p.fan_ptr)
        rec = np.repeat(np.arange(k, dtype=np.int64), sizes)
        order, _ = stable_order(rec * len(face_order) + np.take(fpm_of, p.fan))  # (unique keys)
        rank = (np.arange(len(rec)) - p.fan_ptr[rec]).astype(np.uint64)  # rec is sorted already
        bits = np.where(p.arc[order], np.left_shift(np.uint64(1), rank), np.uint64(0))
        nonempty = np.flatnonzero(sizes > 0)
        mask[r0 + nonempty] = np.bitwise_or.reduceat(bits, p.fan_ptr[nonempty])
        mask[r0 : r0 + k] |= _end_ranks(np.take(p.ends, order, axis=1), rec, rank, sizes)
        r0 += k
    level_records = np.cumsum([len(p.u) for p in rev]).astype(np.int64)
    base_faces = pm_of[F_end[np.argsort(fid_end)]]
    return ProgressiveMesh(
        base_vertices=V[base_ids].copy(),
        base_faces=base_faces,
        pos=V[u_ref].copy(),
        v=pm_of[v_ref],
        mask=mask,
        flags=flags,
        level_records=level_records,
        float32=bool(np.all(V.astype(np.float32).astype(np.float64) == V)),
        end_ranks=True,
        vertex_order=vertex_order,
        face_order=face_order,
    )
