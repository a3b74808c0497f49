"""Per-vertex smoothness feature of the paper (section 4.1), vectorised over CSR arrays.

For a vertex with 1-ring faces f_1..f_m, with unit face normals n_i and their
average n̄, the feature is the set of angles θ_i = arccos(n_i · n̄): all ≈ 0 on a
flat patch, large on peaks and creases.

Choices the paper leaves open:

- n̄ is the **area-weighted** mean (the sum of the faces' unnormalised cross
  products, then normalised), so sliver triangles do not swing it.
- Degenerate (zero-area) faces have no normal and are left out of their
  vertices' angle lists.
- Fixed length for the SOM: a vertex's angles are sorted ascending and resampled
  by linear interpolation at k evenly spaced positions from the smallest to the
  largest; a valence-6 interior vertex (six faces, k = 6) gives its six angles
  exactly, as in the paper's source. A vertex with no (non-degenerate) face gets
  zeros; a vertex whose normals cancel out (n̄ = 0) gets angles of π/2.
"""

from __future__ import annotations

import numpy as np

from .adjacency import Adjacency, segment_owner, stable_order


def face_cross(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, 3) float64: the cross products (v1 - v0) x (v2 - v0) of the triangles, exactly as
    ``np.cross`` forms them (a1 b2 - a2 b1, ...), from one coordinate column at a time."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    col = [np.ascontiguousarray(v[:, a]) for a in range(3)]
    c0, c1, c2 = (np.ascontiguousarray(f[:, k]) for k in range(3))
    a = [x[c1] - x[c0] for x in col]  # edge v1 - v0, per coordinate
    b = [x[c2] - x[c0] for x in col]  # edge v2 - v0
    cross = np.empty((len(f), 3))
    for i in range(3):  # cp_i = a_j b_k - a_k b_j, (i, j, k) cyclic
        j, k = (i + 1) % 3, (i + 2) % 3
        np.multiply(a[j], b[k], out=cross[:, i])
        cross[:, i] -= a[k] * b[j]
    return cross


def squared_norms(x: np.ndarray) -> np.ndarray:
    """The squared Euclidean lengths of the vectors x (..., 3), shape (...,) float64, summed
    (x^2 + y^2) + z^2 a coordinate at a time: the bits of np.linalg.norm's sum of squares and of the
    KD-trees' distances (``pmwm.spatial``), without a (..., 3) temporary or a reduction over a short axis."""
    x = np.asarray(x, dtype=np.float64)
    a, b, c = x[..., 0], x[..., 1], x[..., 2]
    return (a * a + b * b) + c * c


def row_norms(x: np.ndarray) -> np.ndarray:
    """The Euclidean lengths of the vectors x (..., 3), (...,) float64: the bits of
    np.linalg.norm(x, axis=-1), faster (``squared_norms``; docs/decisions/083-numpy-fast-paths.md)."""
    return np.sqrt(squared_norms(x))


def face_normals(
    vertices: np.ndarray, faces: np.ndarray, cross: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (m, 3) and areas (m,) of triangles; degenerate faces get a zero normal.
    ``cross``: the faces' ``face_cross`` when the caller has it already."""
    if cross is None:
        cross = face_cross(vertices, faces)
    norm = np.linalg.norm(cross, axis=1)
    safe = np.where(norm > 0, norm, 1.0)
    return cross / safe[:, None], 0.5 * norm


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, cross: np.ndarray | None = None) -> np.ndarray:
    """Area-weighted unit vertex normals (n, 3); zero for a vertex with no face of positive area.
    ``cross``: the faces' ``face_cross`` when the caller has it already."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if cross is None:
        cross = face_cross(vertices, f)
    vn = np.stack(
        [np.bincount(f.ravel(), weights=np.repeat(cross[:, a], 3), minlength=len(vertices)) for a in range(3)], axis=1
    )
    return vn / np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]


def vertex_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A third of the area of the faces around each vertex, (n,) float64 (0 for a vertex of no face):
    the surface's share per vertex, which the blind scheme weighs its frame with and the paper's crop
    draws its seed by. From ``face_cross``, without ``np.cross``'s temporaries (faster:
    docs/decisions/083-numpy-fast-paths.md)."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    area = 0.5 * row_norms(face_cross(vertices, f))
    out = np.bincount(f.ravel(), weights=np.repeat(area / 3.0, 3), minlength=len(vertices))
    return out.astype(np.float64, copy=False)  # (bincount of no faces gives integers)


def smoothness_feature(vertices: np.ndarray, adj: Adjacency, k: int = 6, cross: np.ndarray | None = None) -> np.ndarray:
    """Sorted 1-ring normal angles (radians) resampled to k values: (n, k) float64. ``cross``: the
    faces' ``face_cross`` (m, 3) when the caller has it already."""
    if k < 1:
        raise ValueError("k must be at least 1")
    n = adj.n_vertices
    normals, areas = face_normals(vertices, adj.faces, cross)
    owner = segment_owner(adj.vf_ptr)
    face = adj.vf_idx
    if (areas > 0).all():  # no degenerate face (the usual case): every incidence counts
        counts = np.diff(adj.vf_ptr)
    else:
        keep = areas[face] > 0
        owner, face = owner[keep], face[keep]
        del keep
        counts = np.bincount(owner, minlength=n)

    # area-weighted mean normal per vertex = normalised sum of the cross products; one column at
    # a time (1-D gathers of the faces' values, the same products as gathering the rows)
    mean = np.zeros((n, 3))
    for axis in range(3):  # 3 bincounts: no per-vertex loop
        mean[:, axis] = np.bincount(owner, weights=(normals[:, axis] * areas)[face], minlength=n)
    mnorm = np.linalg.norm(mean, axis=1)
    mean /= np.where(mnorm > 0, mnorm, 1.0)[:, None]
    cosine = _row_dot(normals, face, mean, owner)
    angle = np.arccos(np.clip(cosine, -1.0, 1.0, out=cosine), out=cosine)
    del face, owner

    # each vertex's angles are consecutive (owner ascending, as the vertex-face lists): the vertices of
    # one valence m (a few distinct ones) sort theirs as the rows of one (r, m) block
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=ptr[1:])

    # resample: position t_j = j (m - 1) / (k - 1) in each vertex's sorted list of m angles; exact
    # integer arithmetic: t_j = lo + w, w = (j (m - 1) mod (k - 1)) / (k - 1). The vertices of one m
    # share lo, hi and w: one column per (m, j); where w = 0 the value is the angle at lo itself
    # (a * 1.0 + b * 0.0 == a for the finite, non-negative angles of arccos)
    out = np.zeros((n, k))
    has = np.flatnonzero(counts > 0)
    by_m, m_sorted = stable_order(counts[has])
    bounds = np.flatnonzero(np.diff(m_sorted)) + 1
    den = max(k - 1, 1)
    valences = m_sorted[np.r_[0, bounds]].tolist() if len(has) else []
    for rows, m in zip(np.split(has[by_m], bounds), valences):  # a few distinct valences
        block = np.take(angle, ptr[rows][:, None] + np.arange(m))
        block.sort(axis=1)
        for j in range(k):  # k (6) columns
            num = (m - 1) * j
            lo, w = num // den, (num % den) / den
            if w == 0.0:
                out[rows, j] = block[:, lo]
            else:
                out[rows, j] = block[:, lo] * (1.0 - w) + block[:, min(lo + 1, m - 1)] * w
    return out


ROW_BLOCK = 1 << 16  # rows gathered at a time by ``_row_dot``


def _row_dot(a: np.ndarray, ia: np.ndarray, b: np.ndarray, ib: np.ndarray) -> np.ndarray:
    """(k,) float64: ``np.einsum("ij,ij->i", a[ia], b[ib])`` for a, b (., 3) float64 and index
    arrays ia, ib (k,), the same einsum on blocks of rows gathered into two reused buffers (each
    row's sum is einsum's own, whatever its summation order; no (k, 3) temporaries)."""
    k = len(ia)
    out = np.empty(k)
    ta = np.empty((min(k, ROW_BLOCK), 3))
    tb = np.empty_like(ta)
    for s in range(0, k, ROW_BLOCK):  # k / 65536 blocks
        e = min(s + ROW_BLOCK, k)
        np.take(a, ia[s:e], axis=0, out=ta[: e - s])
        np.take(b, ib[s:e], axis=0, out=tb[: e - s])
        np.einsum("ij,ij->i", ta[: e - s], tb[: e - s], out=out[s:e])
    return out


def mean_edge_length(V: np.ndarray, adj: Adjacency) -> float:
    """Mean length of the mesh's edges, V : (n, 3) float64 (0 without edges): the scale of every
    mark and tolerance."""
    e = adj.edges
    if len(e) == 0:
        return 0.0
    # one coordinate column at a time: the same sums as norm(V[a] - V[b], axis=1) ((dx^2 + dy^2) + dz^2),
    # without (k, 3) row gathers
    a, b = np.ascontiguousarray(e[:, 0]), np.ascontiguousarray(e[:, 1])
    v = np.asarray(V, dtype=np.float64)
    s = np.zeros(len(e))
    for k in range(3):
        x = np.ascontiguousarray(v[:, k])
        d = np.take(x, a) - np.take(x, b)
        s += d * d
    return float(np.sqrt(s, out=s).mean())
