"""Applying a pass of independent collapses u -> v to the encoder's live mesh, and recording what the
vertex splits that undo them need.

A pass retires the faces that vanish to the sink, rewrites u to v in u's other faces (its arc), merges
u's quadric into v's and updates the costs on the half-edges from and to v. Into v from v's own faces
the cost of a -> v is Q_a(V_v) + E_v, and only E_v changed: those costs move by E_v's change instead of
being recomputed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..adjacency import stable_order
from .records import FLAG_SECOND, FLAG_SINGLE, NEXT_CORNER, PREV_CORNER, TO_NEXT_CORNER, TO_PREV_CORNER
from .select import Collapses
from .state import EncoderVertices, LiveMesh, any_in_row, compress, update_costs


@dataclass
class CollapsedPass:
    """One pass's collapses (k records) as the vertex splits that undo them will need them."""

    u: np.ndarray  # (k,) removed vertices (input ids)
    v: np.ndarray  # (k,) survivors (input ids)
    flags: np.ndarray  # (k,) uint8: FLAG_SINGLE, FLAG_SECOND
    dead: np.ndarray  # (k, 2) input face ids of the removed faces [f1 (u->v), f2 (v->u)], -1 if absent
    fan_ptr: np.ndarray  # (k + 1,) CSR over records into ``fan``: faces around v after the collapse
    fan: np.ndarray  # (fan entries,) their input face ids
    arc: np.ndarray  # (fan entries,) bool: goes back to u on the split
    ends: np.ndarray  # (2, fan entries) bool: the arc face ending at p (next to u), at q (before u)


def _arc_end_faces(nxt: np.ndarray, prv: np.ndarray, r: np.ndarray, pq: np.ndarray) -> np.ndarray:
    """Which faces end each collapse's arc, (2, len(r)) bool (p's end, q's), as the decoder will find
    them: ``nxt``, ``prv`` the vertices after and before u in each arc face, ``r`` their records; ``pq``
    (2, k) each record's p and q, the third vertices of its vanishing faces, -1 for a face it has not
    (on a boundary): then that end follows from the other and the sum of (next - previous) around the
    arc, p - q (the sum telescopes; exact in float64 below 2^53)."""
    missing = pq < 0
    if missing.any():
        s1 = np.bincount(r, weights=nxt - prv, minlength=pq.shape[1]).astype(np.int64)
        pq = np.where(missing, pq[::-1] + np.stack([s1, -s1]), pq)
    return np.stack([nxt == np.take(pq[0], r), prv == np.take(pq[1], r)])


def apply_collapses(verts: EncoderVertices, live: LiveMesh, chosen: Collapses, face_count: np.ndarray) -> CollapsedPass:
    """Apply independent collapses ``chosen`` to the live mesh, and to ``face_count`` (n + 1,) int64, its
    corners per local vertex (as ``np.bincount(live.faces.ravel())``: the sink's entry counts the
    retired faces' corners); returns the records' data (local vertex ids)."""
    u, v = chosen.u, chosen.v
    k = len(u)
    sink = len(verts.removable) - 1
    F = live.faces
    flat = F.ravel()
    cu, ru, cv, rv = chosen.u_corners, chosen.u_records, chosen.v_corners, chosen.v_records
    fu, ju = cu // 3, cu % 3
    vu = np.take(v, ru)
    in_f1 = np.take(flat, fu * 3 + np.take(NEXT_CORNER, ju)) == vu  # f1 holds the half-edge u -> v
    in_f2 = np.take(flat, fu * 3 + np.take(PREV_CORNER, ju)) == vu  # f2 holds v -> u
    dead = np.full((k, 2), -1, np.int64)
    pq = np.full((2, k), -1, np.int64)  # the split's p and q: the vanishing faces' third vertices
    for col, (in_f, to_third) in enumerate(((in_f1, TO_PREV_CORNER), (in_f2, TO_NEXT_CORNER))):
        r_f, f_f, c_f = compress(in_f, ru, fu, cu)
        dead[r_f, col] = np.take(live.face_ids, f_f)
        pq[col, r_f] = np.take(flat, c_f + np.take(to_third, c_f % 3))
    single = (dead < 0).any(axis=1)
    flags = np.where(single, FLAG_SINGLE | np.where(dead[:, 0] < 0, FLAG_SECOND, 0), 0).astype(np.uint8)
    arc = ~(in_f1 | in_f2)
    fv = cv // 3
    (gone,) = compress(~arc, fu)
    is_gone = np.zeros(len(F), bool)
    is_gone[gone] = True
    v_keeps = ~np.take(is_gone, fv)
    # the faces around v after the collapse: u's arc, then v's own; their corners at v
    cu_arc, ru_arc = compress(arc, cu, ru)
    cv_kept, rv_kept = compress(v_keeps, cv, rv)
    at_v = np.concatenate([cu_arc, cv_kept])
    j_at = at_v % 3
    into = at_v + np.take(TO_PREV_CORNER, j_at)  # the corners before them: the half-edges into v
    n_arc = len(cu_arc)
    nxt_arc = np.take(flat, cu_arc + np.take(TO_NEXT_CORNER, j_at[:n_arc]))
    ends_arc = _arc_end_faces(nxt_arc, np.take(flat, into[:n_arc]), ru_arc, pq)
    fan_rec = np.concatenate([ru_arc, rv_kept])
    fan_face = at_v // 3
    fan_arc = np.concatenate([np.ones(len(cu_arc), bool), np.zeros(len(cv_kept), bool)])
    order, _ = stable_order(fan_rec)
    fan_ptr = np.zeros(k + 1, np.int64)
    np.cumsum(np.bincount(fan_rec, minlength=k), out=fan_ptr[1:])
    done = CollapsedPass(
        u=u.copy(),
        v=v.copy(),
        flags=flags,
        dead=dead,
        fan_ptr=fan_ptr,
        fan=np.take(live.face_ids, np.take(fan_face, order)),
        arc=np.take(fan_arc, order),
        ends=np.take(np.pad(ends_arc, ((0, 0), (0, len(cv_kept)))), order, axis=1),
    )
    # apply: rewrite u -> v in the arc faces, retire the dead faces to the sink, merge the quadrics
    flat[cu_arc] = np.take(v, ru_arc)
    gone_c = (gone * 3)[:, None] + np.arange(3)
    # faces per vertex: the vanishing faces leave their vertices, u's others go to v (each face holds
    # one u at most; the v are distinct, and no vanishing face of one collapse holds another's u or v)
    np.subtract.at(face_count, np.take(flat, gone_c).ravel(), 1)
    face_count[v] += np.take(face_count, u)
    face_count[u] = 0
    face_count[sink] += 3 * len(gone)
    flat[gone_c] = sink
    live.forward_cost.reshape(-1)[gone_c] = np.inf
    live.reverse_cost.reshape(-1)[gone_c] = np.inf
    live.n_retired += len(gone)
    Qv = np.take(verts.quadrics, v, axis=0)
    Qv += np.take(verts.quadrics, u, axis=0)
    verts.quadrics[v] = Qv
    Ev = np.einsum("ij,ij->i", Qv, np.take(verts.monomials, v, axis=0))
    dE = Ev - np.take(verts.own_error, v)
    verts.own_error[v] = Ev
    # costs change on the half-edges from and to v (the corners at v and the previous ones). Into v
    # from its own faces, Q_a(V_v) stays: the cost moves by v's own error's change (off the boundary,
    # where no reverse candidate needs Q_v; the full updates that follow overwrite any corner from
    # another record's v). Failed candidates get another chance nearby.
    own = into[n_arc:]
    on_boundary = np.take(live.boundary.reshape(-1), own)
    shift = np.flatnonzero(~on_boundary)
    live.forward_cost.reshape(-1)[np.take(own, shift)] += np.take(dE, np.take(fan_rec[n_arc:], shift))
    update_costs(verts, live, np.concatenate([at_v, into[:n_arc], *compress(on_boundary, own)]))
    if live.failed:
        c = np.concatenate(live.failed)
        ring = np.zeros(sink + 1, bool)  # the u's former 1-rings (their faces now hold v)
        ring[np.take(F, chosen.near_faces, axis=0)] = True
        ring[sink] = False
        at_v_face = np.zeros(len(F), bool)
        at_v_face[fv] = True
        f = c // 3
        again = any_in_row(np.take(ring, np.take(F, f, axis=0))) | np.take(at_v_face, f)
        update_costs(verts, live, *compress(again, c))
        live.failed = list(compress(~again, c))
    if live.n_retired * 4 > len(F):
        live.keep_rows(F[:, 0] < sink)
        live.n_retired = 0
        face_count[sink] = 0
    return done
