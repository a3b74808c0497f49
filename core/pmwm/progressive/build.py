"""Encoding: a progressive mesh built by passes of independent half-edge collapses, in quadric-error order.

Each pass picks a set of independent half-edge collapses u -> v (u vanishes, v keeps its position):
a vertex u is collapsed when the priority of its cheapest valid collapse is the best in its closed
1-ring and the collapse shares no vertex of its vanishing faces with a better one (``select`` gives the
rule), so that the whole pass can be applied, and undone, at once with numpy. One pass is one level of
detail; the records run the passes backwards. The state kept between passes (quadrics, per-corner
candidates and their costs) is in ``state``, the quadrics in ``quadrics``, a pass's changes in
``collapse``. Why numpy alone: docs/decisions/060-progressive-numpy.md.
"""

from __future__ import annotations

from typing import Callable, Optional, Union

import numpy as np

from ..adjacency import Adjacency, build_adjacency, stable_order
from ..errors import MeshError
from ..metrics import bbox_diagonal
from .collapse import CollapsedPass, apply_collapses
from .mesh import ProgressiveMesh
from .quadrics import boundary_half_edges, monomials, quadric_values, vertex_quadrics
from .records import ENDS_SHIFT, NO_END
from .select import SELECTION_ROUNDS, select_collapses, select_forced_collapses
from .state import EncoderVertices, LiveMesh, cheapest_costs, compact, protect, update_costs

Progress = Optional[Callable[[float, str], None]]


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
    selection_rounds: int = SELECTION_ROUNDS,
    self_check: bool = False,
) -> tuple[ProgressiveMesh, np.ndarray]:
    """Decimate ``vertices`` (n, 3) float64, ``faces`` (m, 3) int64 to about ``base_vertices`` vertices;
    return the progressive mesh and (k,) bool: which forced pairs were applied.

    ``protected`` vertices ((n,) bool) are never removed (they may absorb others); a callable
    returning them is called once the set-up is done, just before the first pass (a caller may start
    the build before it knows them: ``background.Later``). ``forced`` is a (k, 2) array of collapses
    (u, v) performed first, in the first passes, e.g. the watermark carriers absorbing their first
    neighbour. ``trace``, when a list, receives the faces (input ids) after every pass, for tests of
    the levels of detail. ``adjacency`` may pass the input's adjacency when the caller has it already.
    ``selection_rounds``: selection rounds per pass (more rounds collapse more vertices per pass, in
    fewer, costlier passes; a different progressive mesh). ``self_check``: after every pass, compare
    the faces per vertex the passes keep up to date (the link and valence checks read them) with a
    recount, and raise RuntimeError if they differ (slower; for tests).
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
    keep = np.zeros(n, bool)
    if protected is not None and not callable(protected):
        keep[:] = np.asarray(protected, bool)
    bbox = bbox_diagonal(V) if n else 1.0
    boundary = boundary_half_edges(F0, adj0)
    verts, live = _start(
        V,
        F0,
        vertex_quadrics(V, F0, boundary),
        removable=~locked & ~keep,
        locked=locked,
        on_boundary=adj0.boundary_vertex,
        boundary=boundary,
        tiebreak=np.random.default_rng(n).permutation(n),
        area_eps=(1e-12 * bbox) ** 2,
    )
    if callable(protected):
        protect(verts, live, np.asarray(protected(), bool))

    alive = np.ones(n, bool)  # by input id
    ids = np.arange(n, dtype=np.int64)  # input id of each local vertex (the arrays shrink as vertices go)
    n_alive = n
    target = max(int(base_vertices), 4)
    passes: list[CollapsedPass] = []
    forced_pairs = np.zeros((0, 2), np.int64) if forced is None else np.asarray(forced, np.int64).reshape(-1, 2)
    forced_done = np.zeros(len(forced_pairs), bool)
    total = max(n_alive - target, 1)
    stalls = 0
    face_count = np.bincount(live.faces.ravel(), minlength=n + 1)  # faces per vertex (kept by apply_collapses)
    while True:
        todo = np.flatnonzero(~forced_done)
        forced_phase = len(todo) > 0 and stalls < 4
        if not forced_phase and n_alive <= target:
            break
        n_local = len(ids)  # local vertices; n_local is the sink
        if forced_phase:
            local = np.full(n, n_local, np.int64)  # a removed vertex maps to the sink: no edge
            local[ids] = np.arange(n_local)
            pairs = local[forced_pairs[todo]]
            chosen = select_forced_collapses(verts, live, face_count, pairs)
            hit = np.isin(pairs[:, 0] * (n_local + 1) + pairs[:, 1], chosen.u * (n_local + 1) + chosen.v)
            forced_done[todo[hit]] = True
        else:
            chosen = select_collapses(verts, live, face_count, selection_rounds)
            room = n_alive - target
            if len(chosen.u) > room:
                qs = verts.quadrics[chosen.u] + verts.quadrics[chosen.v]
                first = np.argsort(quadric_values(qs.T, verts.positions[chosen.v].T), kind="stable")[:room]
                keep_rec = np.zeros(len(chosen.u), bool)
                keep_rec[first] = True
                chosen = chosen.subset(keep_rec)
        if len(chosen.u) == 0:
            stalls += 1
            if not forced_phase:
                break
            continue
        done = apply_collapses(verts, live, chosen, face_count)
        if self_check and not np.array_equal(face_count, np.bincount(live.faces.ravel(), minlength=len(face_count))):
            raise RuntimeError("internal error: the faces per vertex kept by the passes differ from a recount")
        done.u, done.v = ids[done.u], ids[done.v]
        passes.append(done)
        alive[done.u] = False
        n_alive -= len(done.u)
        if progress is not None:
            progress(min(1.0, (n - n_alive) / total), f"progressive mesh: {n_alive} vertices")
        if trace is not None:
            trace.append(ids[live.current_faces(n_local)])
        if 2 * n_alive < n_local:
            verts, ids = compact(verts, live, ids, alive[ids])
            face_count = np.bincount(live.faces.ravel(), minlength=len(ids) + 1)
    final = live.faces[:, 0] < len(ids)
    pm = _assemble(V, F0, ids[live.faces[final]], live.face_ids[final], alive, passes)
    return pm, forced_done


def _start(
    V: np.ndarray,
    F: np.ndarray,
    quadrics: np.ndarray,
    *,
    removable: np.ndarray,
    locked: np.ndarray,
    on_boundary: np.ndarray,
    boundary: np.ndarray,
    tiebreak: np.ndarray,
    area_eps: float,
) -> tuple[EncoderVertices, LiveMesh]:
    """The encoder's state before the first pass, every corner's costs computed: V (n, 3), F (m, 3),
    ``quadrics`` (n, 10), per vertex (n,) ``removable``, ``locked``, ``on_boundary`` and ``tiebreak``,
    ``boundary`` (m, 3) the boundary half-edges. The vertex arrays get one more entry: the sink n
    that retired faces point to (locked, not removable, a zero quadric)."""
    n, m = len(V), len(F)
    Q = np.zeros((n + 1, 10))
    Q[:n] = quadrics
    Vs = np.zeros((n + 1, 3))
    Vs[:n] = V
    locked = np.r_[locked, True]
    verts = EncoderVertices(
        positions=Vs,
        coords=np.ascontiguousarray(Vs.T),
        monomials=monomials(Vs),
        tiebreak=np.r_[tiebreak, n],
        quadrics=Q,
        own_error=quadric_values(Q.T, Vs.T),
        removable=np.r_[removable, False],
        locked=locked,
        on_boundary=np.r_[on_boundary, False],
        area_eps=area_eps,
    )
    live = LiveMesh(
        faces=F.copy(),
        face_ids=np.arange(m, dtype=np.int64),
        boundary=boundary,
        forward_cost=np.empty((m, 3)),
        reverse_cost=np.full((m, 3), np.inf),
    )
    update_costs(verts, live, np.arange(3 * m))
    return verts, live


def collapse_costs(vertices: np.ndarray, faces: np.ndarray, quadrics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every corner's collapse cost (m, 3) and each vertex's cheapest (n,), for ``vertices`` (n, 3),
    ``faces`` (m, 3) int64 and vertex ``quadrics`` (n, 10), every vertex removable and none on a
    boundary: the cost work of the encoder's set-up, which each pass redoes around its collapses.
    benchmarks/bench_pm.py times it (with ``state.ring_minimum``, the selection's other kernel) beside
    a compiled version."""
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    n = len(V)
    none = np.zeros(n, bool)
    verts, live = _start(
        V,
        F,
        quadrics,
        removable=~none,
        locked=none,
        on_boundary=none,
        boundary=np.zeros(F.shape, bool),
        tiebreak=np.arange(n),
        area_eps=0.0,
    )
    cheapest, forward, _ = cheapest_costs(verts, live)
    return forward, cheapest[:n]


def _end_rank_bits(ends: np.ndarray, rec: np.ndarray, rank: np.ndarray, sizes: np.ndarray) -> np.ndarray:
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


def _assemble(
    V: np.ndarray,
    F0: np.ndarray,
    F_end: np.ndarray,
    fid_end: np.ndarray,
    alive: np.ndarray,
    passes: list[CollapsedPass],
) -> ProgressiveMesh:
    """Number vertices and faces in refinement order and encode the records: V (n, 3) and F0 (m, 3) the
    input, F_end (fb, 3) the base faces (input vertex ids) and fid_end (fb,) their input face ids,
    ``alive`` (n,) bool the base vertices, ``passes`` in build order."""
    n = len(V)
    base_ids = np.flatnonzero(alive)
    rev = passes[::-1]
    u_ref = np.concatenate([p.u for p in rev]) if rev else np.zeros(0, np.int64)
    v_ref = np.concatenate([p.v for p in rev]) if rev else np.zeros(0, np.int64)
    flags = np.concatenate([p.flags for p in rev]) if rev else np.zeros(0, np.uint8)
    dead = np.concatenate([p.dead for p in rev]) if rev else np.zeros((0, 2), np.int64)
    n_records = len(u_ref)
    vertex_order = np.concatenate([base_ids, u_ref])
    pm_of = np.empty(n, np.int64)
    pm_of[vertex_order] = np.arange(n)

    base_f = np.sort(fid_end)
    new_faces = dead.reshape(-1)
    new_faces = new_faces[new_faces >= 0]
    face_order = np.concatenate([base_f, new_faces])
    face_pm_of = np.empty(len(F0), np.int64)
    face_pm_of[face_order] = np.arange(len(face_order))

    # masks: fan entries of each record sorted by PM face index; arc entries set bits (pass by pass:
    # the temporaries stay small)
    mask = np.zeros(n_records, np.uint64)
    r0 = 0
    for p in rev:
        k = len(p.u)
        sizes = np.diff(p.fan_ptr)
        rec = np.repeat(np.arange(k, dtype=np.int64), sizes)
        order, _ = stable_order(rec * len(face_order) + np.take(face_pm_of, p.fan))  # (unique keys)
        rank = (np.arange(len(rec)) - p.fan_ptr[rec]).astype(np.uint64)  # rec is sorted already
        bits = np.where(p.arc[order], np.left_shift(np.uint64(1), rank), np.uint64(0))
        nonempty = np.flatnonzero(sizes > 0)
        mask[r0 + nonempty] = np.bitwise_or.reduceat(bits, p.fan_ptr[nonempty])
        mask[r0 : r0 + k] |= _end_rank_bits(np.take(p.ends, order, axis=1), rec, rank, sizes)
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
