"""Progressive mesh: batched half-edge collapses down to a base mesh, exact vertex splits back up.

Encoding. Each pass picks a set of independent half-edge collapses u -> v (u vanishes,
v keeps its position) in quadric-error order: a vertex u is collapsed when the
priority of its cheapest valid collapse (the cost's quantile bucket, then a fixed
pseudo-random order, Luby-style) is the best among all vertices within two rings,
so the closed 1-rings of the collapsed vertices are disjoint and the whole pass can
be applied (and undone) at once with numpy. One pass is one level of detail.

Records. Refinement runs the passes backwards. Record r adds vertex
``n_base_vertices + r`` at ``pos[r]`` next to vertex ``v[r]``. ``mask[r]`` says which
of v's faces (sorted by face index, at the moment of the split) go to the new
vertex; the new faces are derived from the ends of that arc of faces, so a record
costs 24 bytes (float32 position, v, 64-bit mask). ``flags[r]`` bit 0 marks a split
that adds one face (on a boundary); bit 1 says which of the two possible faces.
Any prefix of the records is a valid mesh, and all records give back exactly the
input mesh (vertex order: ``vertex_order``; face order: ``face_order``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from .adjacency import Adjacency, build_adjacency, ranges, segment_reduce
from .errors import MeshError

Progress = Optional[Callable[[float, str], None]]

MAX_FAN = 64  # faces around v at a split: the mask is 64 bits
FLAG_SINGLE = 1  # the split adds one face (boundary collapse)
FLAG_SECOND = 2  # ... and that face is the one holding the half-edge v -> u


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


# --------------------------------------------------------------------------- decoding


def decode(pm: ProgressiveMesh, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Apply the first k records to the base mesh; vectorised per level."""
    nb = pm.n_base_vertices
    n_new_faces = 2 - (pm.flags[:k] & FLAG_SINGLE).astype(np.int64)
    nf_total = len(pm.base_faces) + int(n_new_faces.sum())
    V = np.empty((nb + k, 3), dtype=np.float64)
    V[:nb] = pm.base_vertices
    V[nb:] = pm.pos[:k]
    F = np.empty((nf_total, 3), dtype=np.int64)
    nf = len(pm.base_faces)
    F[:nf] = pm.base_faces
    bounds = np.unique(np.r_[0, pm.level_records[pm.level_records < k], k])
    slot = np.full(nb + k, -1, dtype=np.int64)  # scratch tables, reset after each level
    tag = np.full(nb + k, -1, dtype=np.int64)
    for a, b in zip(bounds[:-1], bounds[1:]):
        nf = _split_chunk(pm, F, nf, nb + a, a, b, slot, tag)
    return V, F


def _split_chunk(pm: ProgressiveMesh, F: np.ndarray, nf: int, nv: int, a: int, b: int,
                 slot: np.ndarray, tag: np.ndarray) -> int:
    """Apply independent records a..b-1 (one level or a prefix of it) in place; returns the face count.

    ``slot`` and ``tag`` are all -1 on entry and are left so.
    """
    cnt = b - a
    u = nv + np.arange(cnt, dtype=np.int64)
    v = pm.v[a:b]
    mask = pm.mask[a:b]
    flags = pm.flags[a:b]
    slot[v] = np.arange(cnt)
    flat = F[:nf].reshape(-1)
    s = slot[flat]
    slot[v] = -1
    hit = np.flatnonzero(s >= 0)
    rec = s[hit]
    # group the hits by record, keeping face order (radix sort when records fit 16 bits)
    order = np.argsort(rec.astype(np.uint16) if cnt < 65536 else rec, kind="stable")
    hit = hit[order]
    rec = rec[order]
    starts = np.searchsorted(rec, np.arange(cnt))
    rank = np.arange(len(rec)) - starts[rec]
    if np.any(rank >= MAX_FAN):
        rank = np.minimum(rank, MAX_FAN - 1)  # only in corrupt data; the checksum guards files
    sel = ((mask[rec] >> rank.astype(np.uint64)) & np.uint64(1)).astype(bool)
    hit = hit[sel]
    rec = rec[sel]
    flat[hit] = u[rec]
    face = hit // 3
    corner = hit % 3
    nxt = F[face, (corner + 1) % 3]
    prv = F[face, (corner + 2) % 3]
    # ends of the arc: p is a "next" vertex that is no "previous" of the same record, q the
    # reverse; the records' rings are disjoint, so one tag table serves them all
    tag[prv] = rec
    pm_ = tag[nxt] != rec
    tag[prv] = -1
    tag[nxt] = rec
    qm_ = tag[prv] != rec
    tag[nxt] = -1
    p = np.zeros(cnt, dtype=np.int64)
    q = np.zeros(cnt, dtype=np.int64)
    p[rec[pm_]] = nxt[pm_]
    q[rec[qm_]] = prv[qm_]
    single = (flags & FLAG_SINGLE).astype(bool)
    second = (flags & FLAG_SECOND).astype(bool)
    f1 = np.stack([u, v, p], axis=1)
    f2 = np.stack([u, q, v], axis=1)
    has1 = ~single | ~second
    has2 = ~single | second
    new = np.empty((cnt, 2, 3), dtype=np.int64)
    new[:, 0] = np.where(has1[:, None], f1, f2)
    new[:, 1] = f2
    keep = np.stack([np.ones(cnt, bool), has1 & has2], axis=1)
    new = new[keep]
    F[nf : nf + len(new)] = new
    return nf + len(new)


# --------------------------------------------------------------------------- encoding


def _face_quadrics(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted plane quadrics of the faces as 10 coefficients, and unit normals."""
    p0, p1, p2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    cr = np.cross(p1 - p0, p2 - p0)
    area2 = np.linalg.norm(cr, axis=1)
    n = cr / np.maximum(area2, 1e-300)[:, None]
    d = -np.einsum("ij,ij->i", n, p0)
    return _plane_quadric(n, d, 0.5 * area2), n


def _plane_quadric(n: np.ndarray, d: np.ndarray, w: np.ndarray) -> np.ndarray:
    a, b, c = n[:, 0], n[:, 1], n[:, 2]
    return w[:, None] * np.stack([a * a, a * b, a * c, a * d, b * b, b * c, b * d, c * c, c * d, d * d], axis=1)


def _quadric_eval(Q: np.ndarray, p: np.ndarray) -> np.ndarray:
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    return (
        Q[:, 0] * x * x
        + 2 * Q[:, 1] * x * y
        + 2 * Q[:, 2] * x * z
        + 2 * Q[:, 3] * x
        + Q[:, 4] * y * y
        + 2 * Q[:, 5] * y * z
        + 2 * Q[:, 6] * y
        + Q[:, 7] * z * z
        + 2 * Q[:, 8] * z
        + Q[:, 9]
    )


def _vertex_quadrics(V: np.ndarray, F: np.ndarray, adj: Adjacency) -> np.ndarray:
    """Sum of face quadrics per vertex, plus boundary-edge constraint planes."""
    n = len(V)
    Qf, normals = _face_quadrics(V, F)
    Q = np.zeros((n, 10))
    for j in range(10):
        Q[:, j] = np.bincount(F.ravel(), weights=np.repeat(Qf[:, j], 3), minlength=n)
    bmask = adj.edge_face_count == 1
    if bmask.any():
        e = adj.edges[bmask]
        # the face of each boundary edge: any incident face containing both ends
        fa = _edge_faces(F, e, n)
        ev = V[e[:, 1]] - V[e[:, 0]]
        pn = np.cross(ev, normals[fa])
        ln = np.linalg.norm(pn, axis=1)
        pn = pn / np.maximum(ln, 1e-300)[:, None]
        d = -np.einsum("ij,ij->i", pn, V[e[:, 0]])
        Qb = _plane_quadric(pn, d, 10.0 * np.einsum("ij,ij->i", ev, ev))
        for j in range(10):
            Q[:, j] += np.bincount(e.ravel(), weights=np.repeat(Qb[:, j], 2), minlength=n)
    return Q


def _edge_faces(F: np.ndarray, e: np.ndarray, n: int) -> np.ndarray:
    """For each edge (given once), one face that holds it."""
    a = F.ravel()
    b = F[:, [1, 2, 0]].ravel()
    keys = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(keys)
    want = e.min(axis=1) * n + e.max(axis=1)
    pos = np.searchsorted(keys[order], want)
    return order[pos] // 3


@dataclass
class _Pass:
    u: np.ndarray  # removed vertices (input ids)
    v: np.ndarray  # survivors (input ids)
    flags: np.ndarray
    dead: np.ndarray  # (k, 2) input face ids of the removed faces [f1 (u->v), f2 (v->u)], -1 if absent
    fan_ptr: np.ndarray  # CSR over records: faces around v after the collapse (input face ids)
    fan: np.ndarray
    arc: np.ndarray  # bool per fan entry: goes back to u on the split


def build_progressive_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    base_vertices: int,
    protected: Optional[np.ndarray] = None,
    forced: Optional[np.ndarray] = None,
    progress: Progress = None,
    trace: Optional[list] = None,
    adjacency: Optional[Adjacency] = None,
) -> tuple[ProgressiveMesh, np.ndarray]:
    """Decimate to about ``base_vertices`` vertices; return the PM and the forced pairs applied.

    ``protected`` vertices are never removed (they may absorb others). ``forced`` is
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
    locked = adj0.nonmanifold_vertex | adj0.isolated_vertex
    keep = np.zeros(n, bool) if protected is None else np.asarray(protected, bool).copy()
    Q = _vertex_quadrics(V, F0, adj0)
    bbox = float(np.linalg.norm(V.max(0) - V.min(0))) if n else 1.0
    area_eps = (1e-12 * bbox) ** 2

    F = F0.copy()
    fid = np.arange(len(F0), dtype=np.int64)
    alive = np.ones(n, bool)
    n_alive = n
    target = max(int(base_vertices), 4)
    passes: list[_Pass] = []
    forced_pairs = np.zeros((0, 2), np.int64) if forced is None else np.asarray(forced, np.int64).reshape(-1, 2)
    forced_done = np.zeros(len(forced_pairs), bool)
    total = max(n_alive - target, 1)
    stalls = 0
    failed = np.zeros(0, np.int64)  # keys u * n + v of collapses that failed validation
    while True:
        todo = np.flatnonzero(~forced_done)
        forced_phase = len(todo) > 0 and stalls < 4
        if not forced_phase and n_alive <= target:
            break
        adj = build_adjacency(F, n, detect_pinches=False)
        if forced_phase:
            cost = _forced_candidates(forced_pairs[todo], adj)
        else:
            cost = _candidates(V, Q, adj, locked, keep)
            # collapses found invalid earlier stay out until their neighbourhood changes
            if len(failed):
                keys = adj.ring_owner() * n + adj.ring_idx
                cost[np.isin(keys, failed)] = np.inf
        sel_u, sel_v, bad = _select(V, adj, cost, area_eps, check_flips=not forced_phase)
        if not forced_phase:
            if len(sel_u):
                touched = np.zeros(n, bool)
                touched[sel_u] = True
                touched[sel_v] = True
                touched = _dilate(touched, adj)
                failed = failed[~(touched[failed // n] | touched[failed % n])]
            failed = np.union1d(failed, bad)
        if not forced_phase:
            room = n_alive - target
            if len(sel_u) > room:
                first = np.argsort(_quadric_eval(Q[sel_u] + Q[sel_v], V[sel_v]), kind="stable")[:room]
                sel_u, sel_v = sel_u[first], sel_v[first]
        else:
            hit = np.isin(forced_pairs[todo, 0] * n + forced_pairs[todo, 1], sel_u * n + sel_v)
            forced_done[todo[hit]] = True
        if len(sel_u) == 0:
            stalls += 1
            if not forced_phase:
                break
            continue
        p, F = _collapse(F, fid, adj, sel_u, sel_v)
        passes.append(p)
        Q[sel_v] += Q[sel_u]
        alive[sel_u] = False
        n_alive -= len(sel_u)
        if progress is not None:
            progress(min(1.0, (n - n_alive) / total), f"progressive mesh: {n_alive} vertices")
        fid = fid[_alive_faces(p, fid)]
        if trace is not None:
            trace.append(F.copy())
        del adj, cost  # free before the next pass builds its own
    pm = _assemble(V, F0, F, fid, alive, passes)
    return pm, forced_done


def _alive_faces(p: _Pass, fid: np.ndarray) -> np.ndarray:
    dead = p.dead[p.dead >= 0]
    return ~np.isin(fid, dead)


def _candidates(V, Q, adj: Adjacency, locked, keep):
    """Cost of every half-edge collapse u -> v along the ring entries (inf where invalid)."""
    u = adj.ring_owner()
    v = adj.ring_idx
    e = adj.ring_edge
    nf = np.diff(adj.vf_ptr)
    bedge_e = adj.edge_face_count == 1
    bedge = bedge_e[e]
    dead_faces = 2 - bedge
    can_go = ~locked & ~keep
    ok = can_go[u] & ~locked[v]
    ok &= bedge == adj.boundary_vertex[u]  # boundary vertices slide along the boundary only
    ok &= nf[u] > dead_faces  # an arc of faces remains to hand back
    ok &= nf[u] + nf[v] - 2 * dead_faces <= MAX_FAN
    # quadric sums once per edge, evaluated at either end
    a, b = adj.edges[:, 0], adj.edges[:, 1]
    Qs = Q[a] + Q[b]
    cost_into_b = _quadric_eval(Qs, V[b])
    cost_into_a = _quadric_eval(Qs, V[a])
    cost = np.where(v == b[e], cost_into_b[e], cost_into_a[e])
    cost[~ok] = np.inf
    return cost


def _forced_candidates(pairs: np.ndarray, adj: Adjacency):
    """The forced collapses, ranked by their order, restricted to existing edges."""
    u, v = pairs[:, 0], pairs[:, 1]
    if not (adj.edge_index(u, v) >= 0).all():
        raise MeshError("internal error: a forced collapse is not an edge of the mesh")
    # place each pair's rank on its ring entry; everything else is not a candidate
    cost = np.full(len(adj.ring_idx), np.inf)
    entry = _ring_entry(adj, u, v)
    cost[entry] = np.arange(len(u), dtype=np.float64)
    return cost


def _ring_entry(adj: Adjacency, u, v) -> np.ndarray:
    """Position in ring_idx of v within u's ring (the pair must be an edge)."""
    cnt = np.diff(adj.ring_ptr)[u]
    rec = np.repeat(np.arange(len(u)), cnt)
    pos = ranges(adj.ring_ptr[u], cnt)
    hit = adj.ring_idx[pos] == v[rec]
    out = np.empty(len(u), np.int64)
    out[rec[hit]] = pos[hit]
    return out


def _select(V, adj: Adjacency, cost, area_eps, check_flips, rounds=4):
    """Independent valid collapses, cheapest first, with disjoint closed 1-rings of their u.

    ``cost`` is per ring entry (u = owner, v = neighbour; inf = not a candidate).
    Each round, a vertex whose cheapest remaining candidate has the best priority
    within two rings wins (priority: cost quantile, then a fixed pseudo-random order);
    winners are validated, valid ones accepted (blocking their 2-rings), failed
    candidates dropped so the vertex tries its next one. Later rounds only look
    around the vertices still in play.
    """
    n = adj.n_vertices
    ptr = adj.ring_ptr
    cost = cost.copy()
    best = segment_reduce(ptr, cost, np.minimum, np.inf)  # cheapest live candidate per vertex
    big = np.iinfo(np.int64).max
    acc_u, acc_v, bad_u, bad_v = [], [], [], []
    for r in range(64):
        if r >= rounds and acc_u:
            break  # enough rounds; keep going only while nothing valid was found
        bu = np.flatnonzero(np.isfinite(best))
        if len(bu) == 0:
            break
        # priority: cost quantile bucket first, then a fixed pseudo-random order, so that
        # smooth cost fields still give many local minima (Luby-style selection)
        nb_ = len(bu)
        bucket = np.empty(nb_, np.int64)
        bucket[np.argsort(best[bu], kind="stable")] = np.arange(nb_) * _BUCKETS // nb_
        val = np.full(n, big, np.int64)
        val[bu] = bucket * nb_ + _tiebreak(nb_, r)
        near = np.flatnonzero(_dilate(_mask(n, bu), adj))
        m1 = np.full(n, big, np.int64)
        m1[near] = np.minimum(val[near], _rows_min(adj, near, val, big))
        m2 = np.minimum(m1[bu], _rows_min(adj, bu, m1, big))
        wu = bu[val[bu] == m2]
        # the entry of each winner's cheapest candidate
        cnt = np.diff(ptr)[wu]
        rec = np.repeat(np.arange(len(wu)), cnt)
        pos = ranges(ptr[wu], cnt)
        cand = np.flatnonzero(cost[pos] == best[wu][rec])
        pick = np.full(len(wu), -1, np.int64)
        pick_rec, at = np.unique(rec[cand], return_index=True)
        pick[pick_rec] = pos[cand[at]]
        wv = adj.ring_idx[pick]
        ok = _valid(V, adj, wu, wv, area_eps, check_flips)
        cost[pick[~ok]] = np.inf
        failed = wu[~ok]
        best[failed] = _rows_min(adj, failed, cost, np.inf, per_entry=True)
        bad_u.append(failed)
        bad_v.append(wv[~ok])
        if ok.any():
            acc_u.append(wu[ok])
            acc_v.append(wv[ok])
            best[_dilate(_dilate(_mask(n, wu[ok]), adj), adj)] = np.inf
    if not acc_u:
        acc_u, acc_v = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    bad = (np.concatenate(bad_u) * n + np.concatenate(bad_v)) if bad_u else np.zeros(0, np.int64)
    return np.concatenate(acc_u), np.concatenate(acc_v), bad


def _mask(n: int, idx: np.ndarray) -> np.ndarray:
    m = np.zeros(n, bool)
    m[idx] = True
    return m


def _rows_min(adj: Adjacency, verts: np.ndarray, values: np.ndarray, empty, per_entry: bool = False) -> np.ndarray:
    """Minimum over each vertex's ring of ``values`` (per neighbour, or per ring entry)."""
    cnt = np.diff(adj.ring_ptr)[verts]
    pos = ranges(adj.ring_ptr[verts], cnt)
    vals = values[pos] if per_entry else values[adj.ring_idx[pos]]
    return segment_reduce(np.r_[0, np.cumsum(cnt)], vals, np.minimum, empty)


_BUCKETS = 16


def _tiebreak(k: int, salt: int) -> np.ndarray:
    """A fixed permutation of range(k) (deterministic: seeded by k and the round)."""
    return np.random.default_rng([k, salt]).permutation(k)


def _dilate(mask: np.ndarray, adj: Adjacency) -> np.ndarray:
    """The mask grown by one ring (gathers only the rings of the marked vertices)."""
    idx = np.flatnonzero(mask)
    cnt = np.diff(adj.ring_ptr)[idx]
    out = mask.copy()
    out[adj.ring_idx[ranges(adj.ring_ptr[idx], cnt)]] = True
    return out


def _valid(V, adj: Adjacency, u, v, area_eps, check_flips=True) -> np.ndarray:
    """Link condition, no degenerate neighbours and (optionally) no flipped faces."""
    if len(u) == 0:
        return np.zeros(0, bool)
    val = np.diff(adj.ring_ptr)
    cnt = val[u]
    rec = np.repeat(np.arange(len(u)), cnt)
    w = adj.ring_idx[ranges(adj.ring_ptr[u], cnt)]
    common = (w != v[rec]) & (adj.edge_index(v[rec], w) >= 0)
    n_common = np.bincount(rec, weights=common, minlength=len(u)).astype(np.int64)
    bedge = adj.edge_face_count[adj.edge_index(u, v)] == 1
    ok = n_common == np.where(bedge, 1, 2)
    # the opposite vertices must keep enough edges (no two faces folded onto each other)
    need = np.where(bedge, 3, 4)
    low = common & (val[w] < need[rec])
    ok &= np.bincount(rec, weights=low, minlength=len(u)) == 0
    if check_flips:
        fcnt = np.diff(adj.vf_ptr)[u]
        frec = np.repeat(np.arange(len(u)), fcnt)
        f = adj.vf_idx[ranges(adj.vf_ptr[u], fcnt)]
        tri = adj.faces[f]
        moving = ~np.any(tri == v[frec][:, None], axis=1)
        tri, frec = tri[moving], frec[moving]
        p = V[tri]
        before = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        is_u = tri == u[frec][:, None]
        p = np.where(is_u[:, :, None], V[v[frec]][:, None, :], p)
        after = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        nb = np.linalg.norm(before, axis=1)
        na = np.linalg.norm(after, axis=1)
        cosang = np.einsum("ij,ij->i", before, after) / np.maximum(nb * na, 1e-300)
        bad = (cosang < 0.2) | (na < area_eps)
        ok &= np.bincount(frec, weights=bad, minlength=len(u)) == 0
    return ok


def _collapse(F, fid, adj: Adjacency, u, v) -> tuple[_Pass, np.ndarray]:
    """Apply independent collapses u -> v; returns the records' data and the new face array."""
    k = len(u)
    fcnt = np.diff(adj.vf_ptr)[u]
    frec = np.repeat(np.arange(k), fcnt)
    f = adj.vf_idx[ranges(adj.vf_ptr[u], fcnt)]
    tri = F[f]
    has_v = np.any(tri == v[frec][:, None], axis=1)
    # dead faces: f1 holds half-edge u -> v, f2 holds v -> u
    cu = np.argmax(tri == u[frec][:, None], axis=1)
    forward = tri[np.arange(len(f)), (cu + 1) % 3] == v[frec]
    dead = np.full((k, 2), -1, np.int64)
    d1 = has_v & forward
    d2 = has_v & ~forward
    dead[frec[d1], 0] = fid[f[d1]]
    dead[frec[d2], 1] = fid[f[d2]]
    single = (dead < 0).any(axis=1)
    flags = np.where(single, FLAG_SINGLE | np.where(dead[:, 0] < 0, FLAG_SECOND, 0), 0).astype(np.uint8)
    # fan of v after the collapse: v's faces and u's faces, minus the dead ones
    arc_f = f[~has_v]
    arc_r = frec[~has_v]
    vcnt = np.diff(adj.vf_ptr)[v]
    vrec = np.repeat(np.arange(k), vcnt)
    vf = adj.vf_idx[ranges(adj.vf_ptr[v], vcnt)]
    vkeep = ~np.any(F[vf] == u[vrec][:, None], axis=1)
    vf, vrec = vf[vkeep], vrec[vkeep]
    all_r = np.concatenate([arc_r, vrec])
    all_f = np.concatenate([arc_f, vf])
    all_arc = np.concatenate([np.ones(len(arc_f), bool), np.zeros(len(vf), bool)])
    order = np.argsort(all_r, kind="stable")
    fan_ptr = np.zeros(k + 1, np.int64)
    np.cumsum(np.bincount(all_r, minlength=k), out=fan_ptr[1:])
    p = _Pass(
        u=u.copy(),
        v=v.copy(),
        flags=flags,
        dead=dead,
        fan_ptr=fan_ptr,
        fan=fid[all_f[order]],
        arc=all_arc[order],
    )
    # apply: rewrite u -> v in the arc faces, drop dead faces
    G = F.copy()
    G[arc_f] = np.where(F[arc_f] == u[arc_r][:, None], v[arc_r][:, None], F[arc_f])
    alive = np.ones(len(G), bool)
    alive[f[has_v]] = False
    return p, G[alive]


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

    # masks: fan entries of each record sorted by PM face index; arc entries set bits
    mask = np.zeros(R, np.uint64)
    r0 = 0
    for p in rev:
        k = len(p.u)
        rec = np.repeat(np.arange(k), np.diff(p.fan_ptr))
        fpm = fpm_of[p.fan]
        order = np.lexsort((fpm, rec))
        rec_s = rec[order]
        arc_s = p.arc[order]
        rank = np.arange(len(rec_s)) - p.fan_ptr[rec_s]
        bits = np.where(arc_s, np.left_shift(np.uint64(1), rank.astype(np.uint64)), np.uint64(0))
        m = np.zeros(k, np.uint64)
        np.bitwise_or.at(m, rec_s, bits)
        mask[r0 : r0 + k] = m
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
        vertex_order=vertex_order,
        face_order=face_order,
    )
