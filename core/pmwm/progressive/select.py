"""The encoder's selection: which collapses u -> v one pass applies together.

Independent collapses, cheapest first. For any two collapses i and j of a pass, u_i and u_j are not
adjacent; their vertices K = {v, a, b} (a, b: the third vertices of the faces that vanish) are
disjoint; and not both v_i is a neighbour of u_j and v_j one of u_i (both would create the edge
v_i v_j). Then no face holds two u, nothing one collapse changes is read by another's tests, and the
vertex splits of a level touch disjoint vertex lists, so the pass is applied, and its splits undone,
at once (``collapse.apply_collapses``, ``decode``).

A round (Luby-style): a vertex in play whose priority (its cheapest candidate's cost quantile bucket,
then a fixed pseudo-random order) is the least in its closed 1-ring wins, if its bucket is among the
cheaper half (so that the levels stay close to a greedy order); winners sharing a K vertex with one of
a better priority or with an accepted collapse drop out; the rest are validated (``_valid_collapses``)
and the pairs of the third rule settled by priority (``_try_winners``). Accepted collapses take their
closed 1-ring out of play; failed candidates are marked, so that the vertex tries its next one. Why one
round per pass and the cheaper half: docs/decisions/061-progressive-selection.md.

Names in the code: ``wu``, ``wv`` the winners' u and v (k,); ``cu``, ``ru`` the flat corners at the u
and the record (winner) of each; ``cv``, ``rv`` the same at the v; ``K`` (3, k) each collapse's v, a, b
(the sink's id where a face is absent); ``n_with_sink`` the local vertices and the sink.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..errors import MeshError
from .records import MAX_FAN, NEXT_CORNER, PREV_CORNER, TO_NEXT_CORNER, TO_PREV_CORNER
from .state import (
    EncoderVertices,
    LiveMesh,
    any_in_row,
    cheapest_costs,
    compress,
    inverse_index,
    ring_minimum,
    tagged_corners,
)

SELECTION_ROUNDS = 1  # Luby rounds per pass (more are only run while none was accepted)
_N_BUCKETS = 16  # cost quantile buckets of the priorities
_PLAYING_BUCKETS = 8  # a pass's winners come from the cheaper buckets only
_BOUND_SAMPLE = 4096  # costs the bucket bounds are taken from
_INT_INF = np.iinfo(np.int64).max  # no priority, no record
# per round, a constant XOR-ed into the tiebreak (a bijection of 32-bit values: ties stay impossible)
_ROUND_SALTS = np.array([0, 0x5BD1E995, 0x2545F491, 0x7FEB352D, 0x68E31DA4, 0x1B873593, 0x3C6EF372, 0x6A09E667])


@dataclass
class Collapses:
    """Accepted collapses u -> v of a pass (k of them, by record) and the corners around them (flat ids
    into the live faces)."""

    u: np.ndarray  # (k,) the vertices that vanish
    v: np.ndarray  # (k,) the vertices that absorb them
    u_corners: np.ndarray  # the corners at the u
    u_records: np.ndarray  # ... and their record
    v_corners: np.ndarray  # the corners at the v
    v_records: np.ndarray  # ... and their record
    near_faces: np.ndarray  # u's faces (failed candidates on faces touching their vertices get a new chance)

    @staticmethod
    def join(parts: list["Collapses"]) -> "Collapses":
        """The collapses of ``parts``, records numbered in order."""
        if not parts:
            z = np.zeros(0, np.int64)
            return Collapses(z, z, z, z, z, z, z)
        off = np.cumsum([0] + [len(p.u) for p in parts[:-1]])
        cat = np.concatenate
        return Collapses(
            u=cat([p.u for p in parts]),
            v=cat([p.v for p in parts]),
            u_corners=cat([p.u_corners for p in parts]),
            u_records=cat([p.u_records + o for p, o in zip(parts, off)]),
            v_corners=cat([p.v_corners for p in parts]),
            v_records=cat([p.v_records + o for p, o in zip(parts, off)]),
            near_faces=cat([p.near_faces for p in parts]),
        )

    def subset(self, keep: np.ndarray) -> "Collapses":
        """The records ``keep`` ((k,) bool), renumbered."""
        new = np.cumsum(keep) - 1
        keep_u, keep_v = np.take(keep, self.u_records), np.take(keep, self.v_records)
        u, v = compress(keep, self.u, self.v)
        cu, ru = compress(keep_u, self.u_corners, self.u_records)
        cv, rv = compress(keep_v, self.v_corners, self.v_records)
        return Collapses(u, v, cu, np.take(new, ru), cv, np.take(new, rv), self.near_faces)


def _corners_around(live: LiveMesh, n_with_sink: int, wv, cu, ru) -> tuple[np.ndarray, ...]:
    """Corners at each winner's v, the faces touching each winner's closed 1-ring by record, and
    who holds each vertex in a 1-ring (``_ring_owners``' triple).

    The winners' closed 1-rings are disjoint (their u are three edges apart), so one tag table
    labels them all: as ``_ring_owners``' triple, the least and the greatest holder are both that tag,
    and no vertex has a third.
    """
    F = live.faces
    tag = np.full(n_with_sink, -1, np.int64)
    tag[np.take(F, cu // 3, axis=0)] = ru[:, None]
    ring_c, ring_r = tagged_corners(F, tag)
    at_v = np.take(F.ravel(), ring_c) == np.take(wv, ring_r)
    return ring_c[at_v], ring_r[at_v], ring_c // 3, ring_r, (tag, tag, np.zeros(n_with_sink, bool))


def _ring_owners(n_with_sink: int, x: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Who holds each vertex in their 1-ring: the least and the greatest record ``r`` paired with it in
    ``x`` ((n_with_sink + 1,) int64 each; for none, outside 0..k-1: _INT_INF and -1) and whether a third
    record also does ((n_with_sink + 1,) bool).

    The winners' 1-rings may overlap (their u are only non-adjacent), so one tag per vertex is not
    enough; two are, but for vertices between three winners (few), where membership is undecided.
    """
    lo = np.full(n_with_sink + 1, _INT_INF, np.int64)
    np.minimum.at(lo, x, r)
    hi = np.full(n_with_sink + 1, -1, np.int64)
    np.maximum.at(hi, x, r)
    many = np.zeros(n_with_sink + 1, bool)
    many[x[(r != np.take(lo, x)) & (r != np.take(hi, x))]] = True
    return lo, hi, many


def _in_ring(
    owners: tuple[np.ndarray, np.ndarray, np.ndarray], x: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Whether vertex x[i] is in record r[i]'s 1-ring (by ``_ring_owners``), and whether that is undecided."""
    lo, hi, many = owners
    yes = (np.take(lo, x) == r) | (np.take(hi, x) == r)
    return yes, ~yes & np.take(many, x)


@dataclass
class SelectionRound:
    """What the selection rounds of one pass share (arrays updated in place); n: local vertices with
    the sink."""

    verts: EncoderVertices
    live: LiveMesh
    face_count: np.ndarray  # (n + 1,) faces per vertex at the start of the pass
    cheapest: np.ndarray  # (n,) each vertex's cheapest candidate cost (inf: out of play)
    priority: np.ndarray  # (n,) int64: cost bucket << 32 | tiebreak
    bucket_bounds: np.ndarray  # (_N_BUCKETS - 1,) the cost buckets' bounds
    taken: np.ndarray  # (n + 1,) bool: K vertices of the accepted collapses (entry n: no vertex)
    accepted_v: np.ndarray  # (n,) v of each accepted u, else -1
    accepted: list  # Collapses accepted so far


def _try_winners(shared: SelectionRound, rows, wu: np.ndarray, value: np.ndarray, last: bool) -> None:
    """Try each winner's cheapest candidate (winners ``wu``: pairwise non-adjacent vertices of the faces
    in play, rows ``rows`` of the live faces or all when None; ``value``: their priorities by vertex).
    Accepted collapses go to ``shared.accepted``; ``last``: no round follows if any is accepted."""
    take = np.take
    verts, live, cheapest = shared.verts, shared.live, shared.cheapest
    forward, reverse = live.forward_cost, live.reverse_cost
    n_with_sink = len(verts.removable)
    F = live.faces
    flat = F.reshape(-1)
    k = len(wu)
    cu, ru = tagged_corners(F, inverse_index(n_with_sink, wu), rows)  # the corners at the winners
    # each winner's cheapest candidate, among its corners: forward u -> next, reverse u -> previous
    pc = cu + take(TO_PREV_CORNER, cu % 3)  # the corner of the half-edge arriving at u
    cost_f, cost_r = take(forward, cu), take(reverse, pc)
    cheapest_w = take(take(cheapest, wu), ru)
    cand = np.concatenate(
        [np.where(cost_f == cheapest_w, 2 * cu, _INT_INF), np.where(cost_r == cheapest_w, 2 * pc + 1, _INT_INF)]
    )
    chosen = np.full(k, _INT_INF, np.int64)
    np.minimum.at(chosen, np.concatenate([ru, ru]), cand)
    is_reverse = (chosen & 1).astype(bool)
    cand_corner = chosen >> 1
    wv = take(flat, np.where(is_reverse, cand_corner, cand_corner + take(TO_NEXT_CORNER, cand_corner % 3)))
    # K = v, a, b (n_with_sink where a face is absent, on the boundary)
    f3 = cu - cu % 3
    nxt = take(flat, f3 + take(NEXT_CORNER, cu % 3))
    prv = take(flat, f3 + take(PREV_CORNER, cu % 3))
    K = np.full((3, k), n_with_sink, np.int64)
    K[0] = wv
    vu = take(wv, ru)
    i = np.flatnonzero(nxt == vu)
    K[1, take(ru, i)] = take(prv, i)
    i = np.flatnonzero(prv == vu)
    K[2, take(ru, i)] = take(nxt, i)
    prio = take(value, wu)
    least = np.full(n_with_sink + 1, _INT_INF, np.int64)
    np.minimum.at(least, K.reshape(-1), np.tile(prio, 3))
    K_free = take(least, K) == prio
    K_free |= K == n_with_sink
    sel = K_free[0] & K_free[1] & K_free[2]  # no winner of a better priority shares a K vertex
    if shared.accepted:  # (later rounds) not a K vertex of an accepted collapse
        held = take(shared.taken, K)
        sel = sel & ~(held[0] | held[1] | held[2])
    if not sel.any():
        return
    # go on with the selected winners (renumbered)
    new = np.cumsum(sel) - 1
    (kept_c,) = np.nonzero(take(sel, ru))
    cu, ru, nxt, prv, pc = (take(x, kept_c) for x in (cu, ru, nxt, prv, pc))
    ru = take(new, ru)
    wu, wv, cand_corner, is_reverse, prio = compress(sel, wu, wv, cand_corner, is_reverse, prio)
    K = K[:, np.flatnonzero(sel)]
    k = len(wu)
    cv, rv = tagged_corners(F, inverse_index(n_with_sink, wv), rows)  # the corners at their v (distinct)
    owners = _ring_owners(n_with_sink, np.concatenate([nxt, prv]), np.concatenate([ru, ru]))
    ok, undecided = _valid_collapses(verts, live, shared.face_count, wu, wv, cu, ru, cv, rv, owners, check_flips=True)
    # the third rule: v_i by u_j and v_j by u_i, with j accepted or a winner of a better priority
    late = np.zeros(k, bool)
    if shared.accepted:
        fv3 = cv - cv % 3
        y = np.concatenate([take(flat, fv3 + take(NEXT_CORNER, cv % 3)), take(flat, fv3 + take(PREV_CORNER, cv % 3))])
        y_rec = np.concatenate([rv, rv])
        (i,) = np.nonzero(take(shared.accepted_v, y) >= 0)  # an accepted u by v_i: does its v lie by u_i?
        yes, unsure = _in_ring(owners, take(shared.accepted_v, take(y, i)), take(y_rec, i))
        late[take(y_rec, i)[yes | unsure]] = True
    lo, hi, many = owners
    lose = take(many, wv)  # v_i held by a third winner: left for later
    for holder in (lo, hi):
        j = take(holder, wv)  # a winner holding v_i in its 1-ring
        i = np.flatnonzero((j >= 0) & (j < k) & (j != np.arange(k)))
        j = take(j, i)
        yes, unsure = _in_ring(owners, take(wv, j), i)
        lose[i[(yes | unsure) & take(ok, j) & (take(prio, j) < take(prio, i))]] = True
    acc = ok & ~lose & ~late
    # failed candidates leave the running; their vertices try their next candidate
    bad = ~ok & ~undecided
    live.failed.append(cand_corner[bad])
    forward.ravel()[cand_corner[bad & ~is_reverse]] = np.inf
    reverse.ravel()[cand_corner[bad & is_reverse]] = np.inf
    if acc.any():
        (accepted_faces,) = compress(take(acc, ru), cu // 3)
        shared.accepted.append(Collapses(wu, wv, cu, ru, cv, rv, accepted_faces).subset(acc))
        if last:  # (what follows only serves later rounds of the pass)
            return
    cheapest[wu[bad]] = np.inf
    bad_c = bad[ru]
    if bad_c.any():
        np.minimum.at(cheapest, wu[ru[bad_c]], np.minimum(forward.ravel()[cu[bad_c]], reverse.ravel()[pc[bad_c]]))
        w_bad = wu[bad]
        bucket = _bucket_of(shared.bucket_bounds, cheapest[w_bad]).astype(np.int64)
        shared.priority[w_bad] = (bucket << 32) | verts.tiebreak[w_bad]
    if acc.any():
        cheapest[take(F, accepted_faces, axis=0)] = np.inf  # the accepted u's closed 1-rings leave the running
        acc_i = np.flatnonzero(acc)
        shared.taken[take(K, acc_i, axis=1)] = True
        shared.taken[n_with_sink] = False
        shared.accepted_v[take(wu, acc_i)] = take(wv, acc_i)


def _bucket_of(bounds: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``np.searchsorted(bounds, x, side="right")`` (uint8) for a few sorted bounds: one comparison per
    bound, branch-free (a binary search per element mispredicts on unsorted x, ten times slower)."""
    out = np.zeros(len(x), np.uint8)
    for t in bounds:
        out += x >= t
    return out


def select_collapses(
    verts: EncoderVertices, live: LiveMesh, face_count: np.ndarray, rounds: Optional[int] = None
) -> Collapses:
    """Independent valid collapses u -> v, cheapest first (the module's rule), for one pass.

    ``face_count`` (n + 1,) the faces per local vertex; ``rounds``: Luby rounds (SELECTION_ROUNDS when
    None; more are run only while none was accepted), on the faces around the vertices still in play.
    """
    rounds = SELECTION_ROUNDS if rounds is None else rounds
    n_with_sink = len(verts.removable)
    F = live.faces
    take = np.take
    cheapest, forward, reverse = cheapest_costs(verts, live)
    finite = cheapest[np.isfinite(cheapest)]
    if len(finite) == 0:
        return Collapses.join([])
    step = max(1, len(finite) // _BOUND_SAMPLE)  # bucket bounds from a fixed subsample: they need not be exact
    # (sorted first: numpy's SIMD sort and a selection in sorted data beat the selection alone)
    bounds = np.quantile(np.sort(finite[::step]), np.arange(1, _N_BUCKETS) / _N_BUCKETS)
    priority = (_bucket_of(bounds, cheapest).astype(np.int64) << 32) | verts.tiebreak
    shared = SelectionRound(
        verts,
        live,
        face_count,
        cheapest,
        priority,
        bounds,
        np.zeros(n_with_sink + 1, bool),
        np.full(n_with_sink, -1, np.int64),
        [],
    )
    rows = None  # faces in play (None: all)
    F_play = F
    for r in range(64):
        if r >= rounds and shared.accepted:
            break
        playing = np.flatnonzero(np.isfinite(cheapest))
        if len(playing) == 0:
            break
        if r >= 2:  # keep the faces within one ring of a vertex still in play
            in_play = np.zeros(n_with_sink, bool)
            in_play[playing] = True
            in_play[take(F_play, np.flatnonzero(any_in_row(take(in_play, F_play))), axis=0)] = True
            keep = np.flatnonzero(any_in_row(take(in_play, F_play)))
            rows = keep if rows is None else take(rows, keep)
            F_play = take(F_play, keep, axis=0)
        # only the cheaper half of the costs may win: the levels stay close to a greedy order
        cheap = playing[(take(priority, playing) >> 32) < _PLAYING_BUCKETS]
        cheap = cheap if len(cheap) else playing
        salt = _ROUND_SALTS[r % len(_ROUND_SALTS)]
        value = np.full(n_with_sink, _INT_INF, np.int64)
        value[cheap] = take(priority, cheap) ^ salt
        (wu,) = compress(take(value, cheap) == take(ring_minimum(F_play, value), cheap), cheap)
        _try_winners(shared, rows, wu, value, last=r + 1 >= rounds)
    return Collapses.join(shared.accepted)


def select_forced_collapses(
    verts: EncoderVertices, live: LiveMesh, face_count: np.ndarray, pairs: np.ndarray
) -> Collapses:
    """The forced collapses ``pairs`` (k, 2) local (u, v) that can go in this pass, earliest first, u
    three edges apart."""
    n_with_sink = len(verts.removable)
    F = live.faces
    rank = np.full(n_with_sink, _INT_INF, np.int64)
    np.minimum.at(rank, pairs[:, 0], np.arange(len(pairs), dtype=np.int64))
    parts: list[Collapses] = []
    for _ in range(64):
        waiting = np.flatnonzero(rank < _INT_INF)
        if len(waiting) == 0:
            break
        two_ring_min = ring_minimum(F, ring_minimum(F, rank))
        wu = waiting[rank[waiting] == two_ring_min[waiting]]
        wv = pairs[rank[wu], 1]
        tag = np.full(n_with_sink, -1, np.int64)
        tag[wu] = np.arange(len(wu))
        cu, ru = tagged_corners(F, tag)
        cv, rv, near_f, near_r, owners = _corners_around(live, n_with_sink, wv, cu, ru)
        flat = F.ravel()
        fu, ju = cu // 3, cu % 3
        edge = (flat[fu * 3 + NEXT_CORNER[ju]] == wv[ru]) | (flat[fu * 3 + PREV_CORNER[ju]] == wv[ru])
        if np.any(np.bincount(ru[edge], minlength=len(wu)) == 0):
            raise MeshError("internal error: a forced collapse is not an edge of the mesh")
        ok, _ = _valid_collapses(verts, live, face_count, wu, wv, cu, ru, cv, rv, owners, check_flips=False)
        rank[wu[~ok]] = _INT_INF
        if ok.any():
            acc = ok[near_r]
            rank[F[near_f[acc]]] = _INT_INF
            parts.append(Collapses(wu, wv, cu, ru, cv, rv, (cu // 3)[ok[ru]]).subset(ok))
    return Collapses.join(parts)


def _valid_collapses(
    verts: EncoderVertices, live: LiveMesh, face_count, u, v, cu, ru, cv, rv, owners, check_flips=True
) -> tuple[np.ndarray, np.ndarray]:
    """Link condition, enough edges left, no new boundary, no flipped faces (optionally).

    ``u``, ``v`` (k,): the collapses; ``cu``, ``ru`` / ``cv``, ``rv``: the flat corners at the u / at
    the v and their record; ``owners``: which records hold each vertex in their u's 1-ring
    (``_ring_owners``). Returns (k,) bool which collapses are valid, and (k,) bool which could not be
    decided (a common neighbour of u and v held by three records: not valid, but not found invalid
    either).
    """
    k = len(u)
    if k == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    take = np.take
    flat = live.faces.ravel()
    boundary = live.boundary.ravel()
    fu, ju = cu // 3, cu % 3
    vu = take(v, ru)
    has_v = (take(flat, fu * 3 + take(NEXT_CORNER, ju)) == vu) | (take(flat, fu * 3 + take(PREV_CORNER, ju)) == vu)
    dead_rec, dead_face = compress(has_v, ru, fu)
    n_dead = np.bincount(dead_rec, minlength=k)
    # common neighbours of u and v: v's neighbours (each once: the next vertex of every face at v,
    # and the previous one across a boundary half-edge) that lie in u's 1-ring
    fv, jv = cv // 3, cv % 3
    nbr = take(flat, fv * 3 + take(NEXT_CORNER, jv))
    prev_c = fv * 3 + take(PREV_CORNER, jv)
    prev_c, prev_rec = compress(take(boundary, prev_c), prev_c, rv)
    nbr = np.concatenate([nbr, take(flat, prev_c)])
    nbr_rec = np.concatenate([rv, prev_rec])
    yes, unsure = _in_ring(owners, nbr, nbr_rec)
    undecided = np.zeros(k, bool)
    undecided[nbr_rec[unsure]] = True
    common, common_rec = compress(yes & (nbr != take(u, nbr_rec)), nbr, nbr_rec)
    n_common = np.bincount(common_rec, minlength=k)
    boundary_edge = n_dead == 1
    ok = (n_dead >= 1) & (n_common == np.where(boundary_edge, 1, 2))
    # the opposite vertices must keep enough edges (no two faces folded onto each other)
    valence = take(face_count, common) + take(verts.on_boundary, common)
    ok[common_rec[valence < take(np.where(boundary_edge, 3, 4), common_rec)]] = False
    ok &= face_count[u] > n_dead  # an arc of faces remains to hand back
    ok &= face_count[u] + face_count[v] - 2 * n_dead <= MAX_FAN
    # the removed faces hold no boundary edge but the collapsed one (the boundary stays as it is)
    # (counted as integers: a face with two boundary edges, an ear, must not pass for one with one)
    n_boundary = np.bincount(dead_rec, weights=np.take(live.boundary, dead_face, axis=0).sum(axis=1), minlength=k)
    ok &= n_boundary == boundary_edge
    if check_flips:
        # a face (u, b, c) that stays becomes (v, b, c): its normal (b - u) x (c - b) turns into
        # (b - v) x (c - b); no flip (cosine of the turn at least 0.2) and no sliver
        kept = np.flatnonzero(~has_v)
        f3, j = take(fu, kept) * 3, take(ju, kept)
        r = take(ru, kept)
        b = take(flat, f3 + take(NEXT_CORNER, j))
        c = take(flat, f3 + take(PREV_CORNER, j))
        e, du, dv = [], [], []
        for X in verts.coords:
            xb = take(X, b)
            e.append(take(X, c) - xb)
            du.append(xb - take(take(X, u), r))
            dv.append(xb - take(take(X, v), r))
        dot = before2 = after2 = 0.0
        for i in range(3):
            j1, j2 = (i + 1) % 3, (i + 2) % 3
            before_i = du[j1] * e[j2] - du[j2] * e[j1]
            after_i = dv[j1] * e[j2] - dv[j2] * e[j1]
            dot = dot + before_i * after_i
            before2 = before2 + before_i * before_i
            after2 = after2 + after_i * after_i
        prod = np.sqrt(before2 * after2)
        bad = (dot < 0.2 * prod) | (prod == 0) | (after2 < verts.area_eps * verts.area_eps)
        ok[r[bad]] = False
    return ok & ~undecided, undecided
