"""The vectorised decoder against a plain per-record reference, at every kind of prefix.

``pmwm.progressive.decode`` applies a level's records together through per-vertex corner lists.
The reference below applies them one at a time from the definition of a record, with a
vertex -> faces map in Python dictionaries: record r adds vertex u = n_base + r, moves the faces of
v whose rank (faces around v sorted by face index) is set in the mask to u, and appends [u, v, p]
and/or [u, q, v], p and q the ends of the moved arc of faces. The two must give the same arrays,
byte for byte, at the base, at every level boundary, one record either side of it, half way
through a level, and at the end; the end must be the input mesh. The reference also checks that
the masks' top bits name the two faces that end each arc (``ENDS_SHIFT``), which the decoder reads
p and q from; without them (a version-1 file) the decoder's sums must give the same arrays.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

import meshes
from pmwm.progressive import ENDS_SHIFT, FLAG_SECOND, FLAG_SINGLE, NO_END, ProgressiveMesh, build_progressive_mesh


def reference_decode(pm: ProgressiveMesh, ks: list[int]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The mesh after each of the first k records in ``ks``, the records applied one by one (slow,
    straightforward)."""
    nb = pm.n_base_vertices
    F = [list(map(int, f)) for f in pm.base_faces]
    around: dict[int, set] = {}
    for i, f in enumerate(F):
        for x in f:
            around.setdefault(x, set()).add(i)
    out = {}
    for r in range(max(ks) + 1):
        if r in ks:
            V = np.concatenate([pm.base_vertices, pm.pos[:r]]).reshape(-1, 3)
            out[r] = V, np.array(F, dtype=np.int64).reshape(-1, 3)
        if r == pm.n_records:
            break
        u, v, mask, flags = nb + r, int(pm.v[r]), int(pm.mask[r]), int(pm.flags[r])
        corners = [(i, j) for i in sorted(around.get(v, ())) for j in range(3) if F[i][j] == v]
        moved = [c for rank, c in enumerate(corners) if (mask >> min(rank, 63)) & 1]
        nxt = [F[i][(j + 1) % 3] for i, j in moved]
        prv = [F[i][(j + 2) % 3] for i, j in moved]
        for i, j in moved:
            F[i][j] = u
            around.setdefault(u, set()).add(i)
            if v not in F[i]:
                around[v].discard(i)
        p = [x for x in nxt if x not in prv]
        q = [x for x in prv if x not in nxt]
        assert len(p) == 1 and len(q) == 1, f"record {r}: the moved faces are not one open arc"
        p, q = p[0], q[0]
        if pm.end_ranks and len(corners) <= ENDS_SHIFT:  # the mask names the arc's end faces
            rp, rq = mask >> ENDS_SHIFT & NO_END, mask >> (ENDS_SHIFT + 6)
            assert rp < len(corners) and rq < len(corners), f"record {r}: the mask names no end faces"
            (fp, jp), (fq, jq) = corners[rp], corners[rq]
            assert (mask >> rp) & 1 and (mask >> rq) & 1, f"record {r}: an end face that does not move"
            assert F[fp][(jp + 1) % 3] == p and F[fq][(jq + 2) % 3] == q, f"record {r}: wrong end faces"
        new = []
        if not (flags & FLAG_SINGLE) or not (flags & FLAG_SECOND):
            new.append([u, v, p])
        if not (flags & FLAG_SINGLE) or (flags & FLAG_SECOND):
            new.append([u, q, v])
        for f in new:
            for x in f:
                around.setdefault(x, set()).add(len(F))
            F.append(f)
    return out


def _rotated_to_min(F: np.ndarray) -> np.ndarray:
    """Each triangle rotated to start at its smallest index (orientation kept, order kept)."""
    r = np.argmin(F, axis=1)
    return np.take_along_axis(F, (r[:, None] + np.arange(3)) % 3, axis=1)


def uv_sphere(nu: int = 48, nv: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A UV sphere: its two poles have degree ``nu`` (the decoder's general path for high degrees)."""
    th = np.linspace(0, np.pi, nv + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    V = np.concatenate([[[0.0, 0.0, 1.0]], ring, [[0.0, 0.0, -1.0]]])
    at = lambda i, j: 1 + i * nu + j % nu  # noqa: E731
    j = np.arange(nu)
    F = [np.stack([np.zeros(nu, int), at(0, j), at(0, j + 1)], axis=1)]
    for i in range(nv - 2):
        F += [
            np.stack([at(i, j), at(i + 1, j), at(i, j + 1)], axis=1),
            np.stack([at(i, j + 1), at(i + 1, j), at(i + 1, j + 1)], axis=1),
        ]
    F.append(np.stack([at(nv - 2, j), np.full(nu, len(V) - 1), at(nv - 2, j + 1)], axis=1))
    return V, np.concatenate(F)


MESHES = {
    "blob": meshes.blob,  # closed, organic
    "open_cap": meshes.open_cap,  # a boundary: records that add one face
    "cad_part": meshes.cad_part,  # creases: some splits of degree above 14
    "pinched_torus": meshes.pinched_torus,  # degree 60: the list table widens
    "uv_sphere": uv_sphere,
}


@functools.cache
def _pm(name: str) -> tuple[np.ndarray, np.ndarray, ProgressiveMesh]:
    V, F = meshes.bunny() if name == "bunny" else MESHES[name]()
    pm, _ = build_progressive_mesh(V, F, base_vertices=max(4, int(0.03 * len(V))))
    return V, F, pm


def _prefixes(pm: ProgressiveMesh, every_level: bool) -> list[int]:
    ends = pm.level_records.tolist()
    starts = [0] + ends[:-1]
    ks = {0, 1, pm.n_records - 1, pm.n_records}
    for s, e in zip(starts, ends):
        if every_level or e in (ends[0], ends[len(ends) // 2], ends[-2] if len(ends) > 1 else e):
            ks |= {e, e - 1, e + 1, (s + e) // 2}
    return sorted(k for k in ks if 0 <= k <= pm.n_records)


@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.slow
def test_every_prefix_matches_the_reference(name):
    V, F, pm = _pm(name)
    ks = _prefixes(pm, every_level=len(pm.level_records) <= 50)  # (cad_part has about 150 levels)
    ref = reference_decode(pm, ks)
    for k in ks:
        Vk, Fk = pm.decode(records=k)
        Vr, Fr = ref[k]
        assert Vk.dtype == np.float64 and Fk.dtype == np.int64 and Fk.flags.c_contiguous
        assert np.array_equal(Vk, Vr), (name, k)
        assert np.array_equal(Fk, Fr), (name, k)  # same faces, same order, same starting corner


@pytest.mark.slow
def test_bunny_prefixes_match_the_reference(bunny):
    V, F, pm = _pm("bunny")
    ks = _prefixes(pm, every_level=False)
    ref = reference_decode(pm, ks)
    for k in ks:
        Vk, Fk = pm.decode(records=k)
        assert np.array_equal(Vk, ref[k][0]) and np.array_equal(Fk, ref[k][1]), k


@pytest.mark.parametrize("name", ["bunny"] + list(MESHES))
def test_all_records_give_back_the_input_mesh(name):
    V, F, pm = _pm(name)
    Vd, Fd = pm.decode()
    order = pm.vertex_order
    assert np.array_equal(Vd, V[order])
    assert len(Fd) == pm.n_faces == len(F)
    # face i is input face face_order[i], the same oriented triangle
    assert np.array_equal(_rotated_to_min(order[Fd]), _rotated_to_min(F[pm.face_order]))


@pytest.mark.slow
def test_decoding_again_and_in_another_order_gives_the_same_arrays():
    _, _, pm = _pm("cad_part")
    ks = _prefixes(pm, every_level=False)
    first = {k: pm.decode(records=k) for k in ks}
    for k in reversed(ks):
        V, F = pm.decode(records=k)
        assert np.array_equal(V, first[k][0]) and np.array_equal(F, first[k][1])


@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.slow
def test_without_end_ranks_the_sums_give_the_same_arrays(name):
    """A progressive mesh read from a version-1 file has no end ranks: the decoder finds p and q by
    its sums around each arc, and must give what the end ranks give."""
    _, _, pm = _pm(name)
    plain = dataclasses.replace(pm, end_ranks=False)
    for k in _prefixes(pm, every_level=False):
        V, F = pm.decode(records=k)
        Vs, Fs = plain.decode(records=k)
        assert np.array_equal(V, Vs) and np.array_equal(F, Fs), (name, k)


def test_records_that_name_no_end_faces_are_read_by_the_sums():
    """NO_END in a record's top bits (the build writes it where it finds no single end of each kind)
    sends its level to the sums; the other levels keep the end ranks."""
    _, _, pm = _pm("blob")
    top = np.uint64(0xFFF) << np.uint64(ENDS_SHIFT)
    mask = pm.mask.copy()
    some = np.arange(0, pm.n_records, 3)
    mask[some] = (mask[some] & ~top) | (np.uint64(NO_END | NO_END << 6) << np.uint64(ENDS_SHIFT))
    marked = dataclasses.replace(pm, mask=mask)
    ks = _prefixes(pm, every_level=False)
    ref = reference_decode(dataclasses.replace(marked, end_ranks=False), ks)
    for k in ks:
        V, F = marked.decode(records=k)
        assert np.array_equal(V, ref[k][0]) and np.array_equal(F, ref[k][1]), k
