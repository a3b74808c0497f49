"""Attacks on a watermarked mesh, for both evaluation protocols (DESIGN.md section 6).

Every attack is ``attack(vertices, faces, <params>, seed=None) -> (vertices, faces)``: it takes plain
arrays, never mutates them, and returns new ``(n, 3) float64`` / ``(m, 3) int64`` arrays. Every random
choice comes from ``np.random.default_rng(seed)``; deterministic attacks accept and ignore ``seed`` so
that all attacks can be called alike. ``ATTACKS`` maps a name to its function (used by ``pmwm attack``).

Paper protocol (the paper's tables 2-4):
  ``noise_paper``       uniform noise per coordinate in [-A*Rmax, A*Rmax], Rmax = max norm about the
                        vertex mean.
  ``smooth_laplacian``  uniform-weight Laplacian smoothing, simultaneous update (paper lambda 0.03,
                        benchmark lambda 0.1).
  ``crop_paper``        removes a fraction of the vertices as ONE connected patch (a geodesic disc).

Benchmark protocol (Wang, Lavoue, Denis, Baskurt, SMI 2010):
  ``noise_benchmark``   uniform noise per coordinate in [-A*dbar, A*dbar], dbar = mean norm about the
                        vertex mean.
  ``quantize``          per-axis uniform quantization over the bounding box.
  ``similarity``        translation, random rotation, uniform scale.
  ``reorder``           random vertex and face permutation, random rotation of each face's indices.
  ``crop_plane``        removes the vertices beyond a random plane.
  ``simplify``          quadric simplification (optional dependency fast-simplification).
  ``subdivide``         one step of midpoint, Loop, sqrt(3) or Catmull-Clark subdivision.

Beyond both protocols:
  ``retriangulate``     adjacent triangles joined into quads and split along the other diagonal.

Amplitudes and fractions are plain fractions: ``amplitude=0.001`` is the benchmark's "0.1 %".
"""

from __future__ import annotations

import math
import typing
from typing import Callable

import numpy as np

from .adjacency import build_adjacency, flip_edges, gather_rows, segment_owner, twin_half_edges, unique_values
from .errors import ParameterError
from .features import vertex_areas
from .smoothing import neighbour_pairs
from .validate import check_mesh

MeshArrays = tuple[np.ndarray, np.ndarray]


# ----------------------------------------------------------------------------------------------
# helpers


def _check_fraction(value: float, name: str, allow_one: bool = False) -> float:
    value = float(value)
    hi_ok = value <= 1.0 if allow_one else value < 1.0
    if not (value >= 0.0 and hi_ok):
        bound = "[0, 1]" if allow_one else "[0, 1)"
        raise ParameterError(f"{name} must be a fraction in {bound}, got {value}")
    return value


def _centre_norms(v: np.ndarray) -> np.ndarray:
    """Vertex norms about the vertex mean (the centre both protocols use)."""
    if len(v) == 0:
        return np.zeros(0)
    return np.linalg.norm(v - v.mean(axis=0), axis=1)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """Rotation matrix uniform over SO(3) (normalised Gaussian quaternion)."""
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def remove_vertices(vertices: np.ndarray, faces: np.ndarray, remove: np.ndarray) -> MeshArrays:
    """Delete the vertices flagged in ``remove`` and every face touching one.

    The survivors keep their relative order (the vertex array is compacted), as Blender's
    "delete vertices" does; a survivor that loses all its faces stays as a loose vertex so that
    exactly the requested vertices disappear.
    """
    keep = ~np.asarray(remove, dtype=bool)
    new_index = np.cumsum(keep) - 1
    face_keep = keep[faces].all(axis=1) if len(faces) else np.zeros(0, bool)
    return vertices[keep].copy(), new_index[faces[face_keep]].astype(np.int64)


# ----------------------------------------------------------------------------------------------
# paper protocol


def _uniform_noise(vertices, faces, amplitude: float, seed, scale_of_norms) -> MeshArrays:
    """Uniform noise in [-A*s, A*s] per coordinate, s = scale_of_norms(vertex norms about the mean)."""
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    if amplitude < 0:
        raise ParameterError(f"amplitude must be >= 0, got {amplitude}")
    scale = float(scale_of_norms(_centre_norms(v))) if len(v) else 0.0
    a = float(amplitude) * scale
    return v + np.random.default_rng(seed).uniform(-a, a, size=v.shape), f


def noise_paper(vertices, faces, amplitude: float = 0.005, seed: int | None = None) -> MeshArrays:
    """Add uniform noise in [-A*Rmax, A*Rmax] to every coordinate (paper table 2).

    Rmax is the largest vertex distance from the vertex mean, so ``amplitude`` is the paper's "Amp"
    (0.005 ... 0.05). The per-coordinate standard deviation is A*Rmax/sqrt(3).
    """
    return _uniform_noise(vertices, faces, amplitude, seed, np.max)


def smooth_laplacian(vertices, faces, lam: float = 0.03, iterations: int = 5, seed: int | None = None) -> MeshArrays:
    """Uniform-weight Laplacian smoothing: v <- v + lam * (mean(neighbours) - v), all at once.

    All vertices are updated simultaneously from the previous iterate. Boundary vertices (on an edge
    with one face) average only their neighbours along boundary edges, i.e. the open border is
    smoothed as a curve and does not shrink into the surface (MeshLab's "1D boundary smoothing"
    default; ``smoothing.neighbour_pairs``). Isolated vertices do not move. ``seed`` is ignored
    (deterministic).
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    iterations = int(iterations)
    if iterations < 0:
        raise ParameterError(f"iterations must be >= 0, got {iterations}")
    n = len(v)
    if iterations == 0 or len(f) == 0:
        return v, f
    owner, nbr = neighbour_pairs(f, n)
    count = np.bincount(owner, minlength=n).astype(np.float64)
    moving = count > 0
    inv = np.zeros(n)
    inv[moving] = 1.0 / count[moving]
    lam = float(lam)
    for _ in range(iterations):
        mean = np.stack([np.bincount(owner, weights=v[nbr, a], minlength=n) for a in range(3)], axis=1)
        mean *= inv[:, None]
        v = np.where(moving[:, None], v + lam * (mean - v), v)
    return v, f


def crop_paper(vertices, faces, fraction: float = 0.1, seed: int | None = None) -> MeshArrays:
    """Cut off ``fraction`` of the vertices as one connected patch (paper table 4).

    The patch is a geodesic disc: a seed vertex is drawn with probability proportional to its
    surface area (a uniform random surface point), then vertices are taken breadth-first over the
    mesh edges; the last ring is trimmed to the exact count by Euclidean distance to the seed. Each
    ring vertex touches the previous ring, so the removed region is connected (if the seed's
    component is smaller than the request, the disc continues from the nearest remaining vertex).
    Faces touching a removed vertex are deleted; survivors keep their relative order.
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    fraction = _check_fraction(fraction, "fraction")
    n = len(v)
    k = int(round(fraction * n))
    remove = np.zeros(n, bool)
    if k == 0:
        return remove_vertices(v, f, remove)
    rng = np.random.default_rng(seed)
    adj = build_adjacency(f, n)
    area = vertex_areas(v, f)
    p = area / area.sum() if area.sum() > 0 else np.full(n, 1.0 / n)
    seed_vertex = int(rng.choice(n, p=p))
    centre = v[seed_vertex]
    taken = 0
    frontier = np.array([seed_vertex], dtype=np.int64)
    while taken < k:
        if len(frontier) == 0:  # component exhausted: continue from the nearest remaining vertex
            rest = np.flatnonzero(~remove)
            frontier = rest[[np.argmin(np.linalg.norm(v[rest] - centre, axis=1))]]
        if taken + len(frontier) > k:
            d = np.linalg.norm(v[frontier] - centre, axis=1)
            frontier = frontier[np.argsort(d, kind="stable")[: k - taken]]
        remove[frontier] = True
        taken += len(frontier)
        nxt = unique_values(gather_rows(adj.ring_ptr, adj.ring_idx, frontier))
        frontier = nxt[~remove[nxt]]
    return remove_vertices(v, f, remove)


# ----------------------------------------------------------------------------------------------
# benchmark protocol


def noise_benchmark(vertices, faces, amplitude: float = 0.001, seed: int | None = None) -> MeshArrays:
    """Add uniform noise in [-A*dbar, A*dbar] to every coordinate (benchmark noise attack).

    dbar is the mean vertex distance from the vertex mean; the benchmark's levels 0.05/0.1/0.3/0.5 %
    are ``amplitude`` 0.0005/0.001/0.003/0.005.
    """
    return _uniform_noise(vertices, faces, amplitude, seed, np.mean)


def quantize(vertices, faces, bits: int = 9, seed: int | None = None) -> MeshArrays:
    """Quantize each coordinate to ``bits`` bits over the bounding box (benchmark: 11 down to 7).

    Axis a is mapped to the 2**bits levels lo_a + i * (hi_a - lo_a) / (2**bits - 1), i = 0 ...
    2**bits - 1 (the box corners are levels), rounding to the nearest level. A flat axis is kept.
    ``seed`` is ignored (deterministic).
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    bits = int(bits)
    if not 1 <= bits <= 52:
        raise ParameterError(f"bits must be in 1..52, got {bits}")
    if len(v) == 0:
        return v, f
    lo = v.min(axis=0)
    extent = v.max(axis=0) - lo
    levels = float(2**bits - 1)
    step = np.where(extent > 0, extent / levels, 1.0)
    q = np.rint((v - lo) / step)
    return np.where(extent > 0, lo + q * step, v), f


def similarity(
    vertices,
    faces,
    seed: int | None = None,
    max_translation: float = 5.0,
    scale_range: tuple[float, float] = (0.1, 10.0),
) -> MeshArrays:
    """Random similarity transform v -> s * R v + t (benchmark similarity attack).

    R is uniform over rotations, s is drawn log-uniformly in ``scale_range`` (so shrinking and
    growing are equally likely) and each component of t uniformly in +-max_translation * dbar, dbar
    being the mean vertex distance from the vertex mean.
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    if isinstance(scale_range, str):  # "0.1,10" from the command line
        scale_range = tuple(scale_range.replace(":", ",").split(","))
    lo, hi = (float(x) for x in scale_range)
    if not 0 < lo <= hi:
        raise ParameterError(f"scale_range must be 0 < low <= high, got {scale_range}")
    rng = np.random.default_rng(seed)
    rot = _random_rotation(rng)
    scale = math.exp(rng.uniform(math.log(lo), math.log(hi)))
    d_bar = float(_centre_norms(v).mean()) if len(v) else 0.0
    t = rng.uniform(-1.0, 1.0, size=3) * float(max_translation) * d_bar
    return scale * (v @ rot.T) + t, f


def reorder(vertices, faces, seed: int | None = None) -> MeshArrays:
    """Randomly permute the vertices and the faces, and rotate each face's index triple.

    The geometry and the orientation of every face are unchanged; only the numbering differs.
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    rng = np.random.default_rng(seed)
    n, m = len(v), len(f)
    perm = rng.permutation(n)  # new vertex i is old vertex perm[i]
    new_of_old = np.empty(n, dtype=np.int64)
    new_of_old[perm] = np.arange(n)
    f2 = new_of_old[f[rng.permutation(m)]] if m else f
    if m:
        shift = rng.integers(0, 3, size=m)
        cols = (np.arange(3)[None, :] + shift[:, None]) % 3
        f2 = np.take_along_axis(f2, cols, axis=1)
    return v[perm], f2


def crop_plane(vertices, faces, fraction: float = 0.1, seed: int | None = None) -> MeshArrays:
    """Remove the ``fraction`` of vertices beyond a plane of random direction (benchmark cropping).

    The plane normal is uniform on the sphere; the offset is chosen so that exactly
    round(fraction * n) vertices (those with the largest projection on the normal) are removed.
    Faces touching a removed vertex are deleted; survivors keep their relative order.
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    fraction = _check_fraction(fraction, "fraction")
    n = len(v)
    k = int(round(fraction * n))
    rng = np.random.default_rng(seed)
    d = rng.standard_normal(3)
    d /= np.linalg.norm(d)
    remove = np.zeros(n, bool)
    if k:
        remove[np.argsort(-(v @ d), kind="stable")[:k]] = True
    return remove_vertices(v, f, remove)


def simplify(vertices, faces, ratio: float = 0.5, seed: int | None = None) -> MeshArrays:
    """Quadric-error simplification removing ``ratio`` of the faces (~ the same share of edges).

    Uses fast-simplification (optional dependency). The benchmark's levels run from 10 % to 97.5 %.
    ``seed`` is ignored (deterministic).
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    ratio = _check_fraction(ratio, "ratio")
    if ratio == 0 or len(f) == 0:
        return v, f
    try:
        import fast_simplification
    except ImportError as exc:  # optional dependency
        raise ImportError("the simplify attack needs fast-simplification: pip install fast-simplification") from exc
    v2, f2 = fast_simplification.simplify(v, f.astype(np.int32), target_reduction=ratio)
    return np.asarray(v2, dtype=np.float64), np.asarray(f2, dtype=np.int64)


def subdivide(vertices, faces, scheme: str = "midpoint", seed: int | None = None) -> MeshArrays:
    """One step of subdivision: ``midpoint`` (1:4, vertices kept), ``loop``, ``sqrt3`` or
    ``catmull-clark``.

    midpoint: every edge gets its midpoint; the original vertices keep their indices and positions.
    loop: trimesh.remesh.subdivide_loop (original vertices are smoothed by the Loop masks).
    sqrt3: Kobbelt's sqrt(3) scheme: a centroid per face, original edges flipped, original vertices
    relaxed with alpha_n = (4 - 2 cos(2 pi / n)) / 9; boundary (and inconsistently oriented) edges
    are not flipped and boundary vertices are not moved.
    catmull-clark: what Blender's Subdivision Surface modifier (one level, without its limit surface)
    and its exporters make of a triangle mesh: a point per face (its centroid) and per edge, each
    triangle three quads (corner, next edge point, face point, previous edge point), each quad written
    as two triangles split from its corner, as Blender's OBJ, PLY, STL and glTF exporters and its own
    triangulation leave them; the Catmull-Clark rules, boundaries by the cubic B-spline's (the same
    positions and triangles as the modifier's: tests/blender).
    ``seed`` is ignored (deterministic).
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    if scheme == "midpoint":
        return _subdivide_midpoint(v, f)
    if scheme == "loop":
        try:
            from trimesh.remesh import subdivide_loop
        except ImportError as exc:
            raise ImportError("Loop subdivision needs trimesh: pip install trimesh") from exc
        v2, f2 = subdivide_loop(v, f)
        return np.asarray(v2, dtype=np.float64), np.asarray(f2, dtype=np.int64)
    if scheme == "sqrt3":
        return _subdivide_sqrt3(v, f)
    if scheme == "catmull-clark":
        return _subdivide_catmull_clark(v, f)
    raise ParameterError(f"unknown subdivision scheme {scheme!r}; use 'midpoint', 'loop', 'sqrt3' or 'catmull-clark'")


def _subdivide_midpoint(v: np.ndarray, f: np.ndarray) -> MeshArrays:
    n = len(v)
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    he = np.stack([np.stack([a, b], 1), np.stack([b, c], 1), np.stack([c, a], 1)], axis=1)  # (m, 3, 2)
    keys = np.minimum(he[..., 0], he[..., 1]) * n + np.maximum(he[..., 0], he[..., 1])
    ukeys, inverse = np.unique(keys.ravel(), return_inverse=True)
    e0, e1 = ukeys // n, ukeys % n
    mids = 0.5 * (v[e0] + v[e1])
    m_idx = (n + inverse).reshape(-1, 3)  # midpoint of edges ab, bc, ca
    mab, mbc, mca = m_idx[:, 0], m_idx[:, 1], m_idx[:, 2]
    new_f = np.concatenate(
        [np.stack(t, axis=1) for t in ((a, mab, mca), (mab, b, mbc), (mca, mbc, c), (mab, mbc, mca))]
    )
    return np.vstack([v, mids]), new_f.astype(np.int64)


def _subdivide_sqrt3(v: np.ndarray, f: np.ndarray) -> MeshArrays:
    n, m = len(v), len(f)
    centroid_idx = n + np.arange(m)
    centroids = v[f].mean(axis=1)
    he_from, he_to, he_face = f.ravel(), f[:, [1, 2, 0]].ravel(), np.repeat(np.arange(m), 3)
    h1, h2 = twin_half_edges(f, n)
    flipped = np.zeros(len(he_from), bool)
    flipped[h1] = True
    flipped[h2] = True
    # flipped edge a->b (face F1, centroid m1) / b->a (face F2, centroid m2): (a, m2, m1), (m2, b, m1)
    a, b = he_from[h1], he_to[h1]
    m1, m2 = centroid_idx[he_face[h1]], centroid_idx[he_face[h2]]
    tri_flip = np.concatenate([np.stack([a, m2, m1], 1), np.stack([m2, b, m1], 1)])
    keep = ~flipped
    tri_keep = np.stack([he_from[keep], he_to[keep], centroid_idx[he_face[keep]]], 1)
    # relax the original vertices (interior only)
    adj = build_adjacency(f, n)
    owner = segment_owner(adj.ring_ptr)
    val = adj.valence.astype(np.float64)
    nsum = np.stack([np.bincount(owner, weights=v[adj.ring_idx, k], minlength=n) for k in range(3)], 1)
    movable = adj.manifold_interior & (val > 0)
    safe_val = np.where(val > 0, val, 1.0)
    alpha = (4.0 - 2.0 * np.cos(2.0 * np.pi / safe_val)) / 9.0
    relaxed = (1.0 - alpha)[:, None] * v + (alpha / safe_val)[:, None] * nsum
    v_new = np.where(movable[:, None], relaxed, v)
    return np.vstack([v_new, centroids]), np.concatenate([tri_flip, tri_keep]).astype(np.int64)


def _subdivide_catmull_clark(v: np.ndarray, f: np.ndarray) -> MeshArrays:
    n, m = len(v), len(f)
    fp = v[f].mean(axis=1)  # (m, 3) face points
    he_from, he_to = f.ravel(), f[:, [1, 2, 0]].ravel()  # half-edge 3 t + k: corner k to k + 1
    keys = np.minimum(he_from, he_to) * n + np.maximum(he_from, he_to)
    ukeys, inverse = np.unique(keys, return_inverse=True)
    e0, e1 = ukeys // n, ukeys % n
    n_e = len(ukeys)
    faces_of = np.bincount(inverse, minlength=n_e)  # 2: interior edge, 1: boundary
    fsum = np.stack([np.bincount(inverse, weights=np.repeat(fp[:, k], 3), minlength=n_e) for k in range(3)], 1)
    mid = 0.5 * (v[e0] + v[e1])
    ep = np.where((faces_of == 2)[:, None], 0.5 * mid + 0.25 * fsum, mid)
    # original vertices: (Q + 2 R + (k - 3) P) / k inside (Q: mean of the k face points, R: of the k edge
    # midpoints); (b0 + 6 P + b1) / 8 on a boundary of two boundary edges; kept anywhere else
    ends = np.concatenate([e0, e1])
    k_edges = np.bincount(ends, minlength=n).astype(np.float64)
    k_faces = np.bincount(he_from, minlength=n).astype(np.float64)
    safe = np.maximum(k_edges, 1.0)
    Q = np.stack([np.bincount(he_from, weights=np.repeat(fp[:, k], 3), minlength=n) for k in range(3)], 1)
    R = np.stack([np.bincount(ends, weights=np.concatenate([mid[:, k], mid[:, k]]), minlength=n) for k in range(3)], 1)
    inner = (Q / np.maximum(k_faces, 1.0)[:, None] + 2.0 * R / safe[:, None] + (safe - 3.0)[:, None] * v) / safe[
        :, None
    ]
    bnd = faces_of == 1
    b_ends = np.concatenate([e0[bnd], e1[bnd]])
    b_count = np.bincount(b_ends, minlength=n)  # boundary edges per vertex
    b_other = np.concatenate([e1[bnd], e0[bnd]])
    B = np.stack([np.bincount(b_ends, weights=v[b_other, k], minlength=n) for k in range(3)], 1)
    interior = (b_count == 0) & (k_edges == k_faces) & (k_edges > 0)  # one closed fan, no boundary edge
    vp = np.where(interior[:, None], inner, np.where((b_count == 2)[:, None], (B + 6.0 * v) / 8.0, v))
    # each corner's quad (corner, edge point to the next corner, face point, edge point from the previous)
    e_idx = (n + inverse).reshape(m, 3)  # edge point of the edges (0, 1), (1, 2), (2, 0)
    f_idx = np.repeat(n + n_e + np.arange(m), 3)
    corner = f.ravel()
    nxt = e_idx.ravel()
    prv = e_idx[:, [2, 0, 1]].ravel()
    tris = np.stack([np.stack([corner, nxt, f_idx], 1), np.stack([corner, f_idx, prv], 1)], 1).reshape(-1, 3)
    return np.vstack([vp, ep, fp]), tris.astype(np.int64)


def retriangulate(vertices, faces, fraction: float = 1.0, seed: int | None = None) -> MeshArrays:
    """Join adjacent triangles into quads and split each along its other diagonal (edge flips).

    What a tool that stores quads, or re-triangulates them its own way, does to a mesh: same vertices,
    other faces. About ``fraction`` of the faces are paired (a few rounds of a random matching over
    the edges); a flip that would duplicate an existing edge is skipped, so a manifold mesh stays one.
    """
    v, f = check_mesh(vertices, faces, need_faces=False, copy=True)
    fraction = _check_fraction(fraction, "fraction", allow_one=True)
    f = f.copy()
    n, m = len(v), len(f)
    rng = np.random.default_rng(seed)
    free = rng.random(m) < fraction  # faces that may still be paired
    for _ in range(4):
        h1, h2 = twin_half_edges(f, n)
        fa, fb = h1 // 3, h2 // 3
        ok = free[fa] & free[fb] & (fa != fb)
        h1, h2, fa, fb = h1[ok], h2[ok], fa[ok], fb[ok]
        # a matching: each edge whose random priority is the smallest around both its faces
        pri = rng.random(len(h1))
        best = np.full(m, np.inf)
        np.minimum.at(best, fa, pri)
        np.minimum.at(best, fb, pri)
        pick = (pri == best[fa]) & (pri == best[fb])
        h1, h2, fa, fb = h1[pick], h2[pick], fa[pick], fb[pick]
        # edge a->b in face fa = (a, b, c), b->a in face fb = (b, a, d): the new edge (c, d) must be new
        c = f[fa, (h1 % 3 + 2) % 3]
        d = f[fb, (h2 % 3 + 2) % 3]
        edge_keys = unique_values(np.sort(np.stack([f.ravel(), f[:, [1, 2, 0]].ravel()], 1), axis=1) @ [n, 1])
        new_keys = np.minimum(c, d) * n + np.maximum(c, d)
        pos = np.minimum(np.searchsorted(edge_keys, new_keys), len(edge_keys) - 1)
        uniq = np.zeros(len(new_keys), bool)
        uniq[np.unique(new_keys, return_index=True)[1]] = True
        go = (edge_keys[pos] != new_keys) & uniq & (c != d)
        flip_edges(f, h1[go], h2[go])
        free[fa[go]] = free[fb[go]] = False
    return v, f


# ----------------------------------------------------------------------------------------------
# registry

Attack = Callable[..., MeshArrays]

ATTACKS: dict[str, Attack] = {
    # paper protocol
    "noise_paper": noise_paper,
    "smooth_laplacian": smooth_laplacian,
    "crop_paper": crop_paper,
    # benchmark protocol
    "noise_benchmark": noise_benchmark,
    "quantize": quantize,
    "similarity": similarity,
    "reorder": reorder,
    "crop_plane": crop_plane,
    "simplify": simplify,
    "subdivide": subdivide,
    # beyond the protocols
    "retriangulate": retriangulate,
}


def attack_parameters(name: str) -> dict[str, tuple[object, object]]:
    """Parameters of attack ``name`` other than vertices/faces: {param: (type, default)}.

    Lets the command line build its options from the functions themselves.
    """
    import inspect

    fn = ATTACKS[name]
    hints = typing.get_type_hints(fn)
    out: dict[str, tuple[object, object]] = {}
    for p in list(inspect.signature(fn).parameters.values())[2:]:
        out[p.name] = (hints.get(p.name, object), p.default)
    return out


__all__ = ["ATTACKS", "attack_parameters", "remove_vertices", *ATTACKS]


def reexport(vertices: np.ndarray, faces: np.ndarray, ext: str) -> tuple[np.ndarray, np.ndarray]:
    """The mesh written to a file of format ``ext`` (".obj", ".ply", ".stl", ".glb", ...) and read back:
    what a re-export does to the coordinates (float32), the vertex order and shared vertices (STL).
    vertices : (n, 3) float64, faces : (m, 3) int64 -> the same, as read."""
    import os
    import tempfile

    from .meshio import read_mesh, write_mesh  # meshio loads trimesh: only when this attack runs

    with tempfile.TemporaryDirectory(prefix="pmwm-reexport-") as tmp:
        path = os.path.join(tmp, "copy" + ext)
        write_mesh(path, vertices, faces)
        src = read_mesh(path)
        return src.vertices, src.faces
