"""Generated shapes for held-out evaluation: families of meshes that nobody tuned a reader on.

``generate(family, seed)`` returns ``(vertices (n, 3) float64, faces (m, 3) int64)``: a manifold,
consistently oriented (outward) triangle mesh without degenerate faces, closed except for the "open"
family (a sheet with one boundary loop) and the "scan" family (small holes), of about 3,000 to 30,000
vertices, in a random pose and scale (bounding-box diagonals from 0.05 to 50 units, as real files
differ). The same (family, seed) always gives the same arrays; each family draws everything from
``numpy.random.default_rng([family number, seed])``.

Families (``FAMILIES``):

- ``organic``   smooth blobs: a chain of metaballs with noise-driven bumps (sums of random waves)
- ``cad``       boolean solids: a box or a cylinder, with bosses added and holes and slots cut out
- ``scan``      an organic blob sampled unevenly (a warped grid), with noise along the normals and
                small holes
- ``thin``      elongated and thin parts: branching rods (capsules) and a thin fin
- ``open``      a bent, bumpy sheet with one boundary (a square or a disk)
- ``ellipsoid`` an ellipsoid with distinct axes and one small bump (near its three mirror planes)
- ``bilateral`` a figure symmetric about a plane (mirrored metaballs and waves)
- ``cad2``      a part with a 2-fold rotational symmetry (and its holes and bosses in pairs)
- ``cad4``      a flange with a 4-fold rotational symmetry

The near-symmetric families are symmetric in their geometry and not in their triangulation. The closed
shapes are level sets of a field (negative inside) polygonised by marching tetrahedra on a grid (a
surface that is a closed 2-manifold by construction), then relaxed along the surface and projected
back onto the level set so that the triangles are not slivers. ``mesh_report`` checks the properties.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from pmwm.adjacency import build_adjacency, component_labels

__all__ = ["CLOSED_FAMILIES", "FAMILIES", "generate", "mesh_report"]

Field = Callable[[np.ndarray], np.ndarray]  # (k, 3) points -> (k,) values, negative inside

# the six tetrahedra of a grid cube along its main diagonal (corner id = dx + 2 dy + 4 dz): the paths
# 0 -> e_a -> e_a + e_b -> 7 over the permutations (a, b); adjacent cubes agree on their shared faces
_TETS = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
_CORNERS = np.array([[(c >> 0) & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])


def _case_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each of the 16 sign patterns of a tetrahedron (bit i: corner i positive): up to two
    triangles, each three tetrahedron edges (local corner pairs), and a positive corner that each
    triangle's normal must face. Returns edges (16, 2, 3, 2), positive corner (16, 2), count (16,)."""
    edges = np.zeros((16, 2, 3, 2), np.int64)
    pos_corner = np.zeros((16, 2), np.int64)
    count = np.zeros(16, np.int64)
    for code in range(1, 15):
        pos = [i for i in range(4) if code >> i & 1]
        neg = [i for i in range(4) if not code >> i & 1]
        if len(pos) in (1, 3):
            lone, others = (pos[0], neg) if len(pos) == 1 else (neg[0], pos)
            edges[code, 0] = [[lone, o] for o in others]
            pos_corner[code, 0] = pos[0]
            count[code] = 1
        else:
            (a, b), (c, d) = pos, neg
            quad = [[a, c], [a, d], [b, d], [b, c]]
            edges[code, 0] = [quad[0], quad[1], quad[2]]
            edges[code, 1] = [quad[0], quad[2], quad[3]]
            pos_corner[code] = a
            count[code] = 2
    return edges, pos_corner, count


_CASE_EDGES, _CASE_POS, _CASE_COUNT = _case_table()


def _evaluate(field: Field, points: np.ndarray, chunk: int = 400_000) -> np.ndarray:
    return np.concatenate([field(points[i:i + chunk]) for i in range(0, len(points), chunk)]) if len(points) else \
        np.zeros(0)


def _polygonise(field: Field, axes: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The level set field = 0 over the grid of ``axes`` (three increasing coordinate arrays, possibly
    uneven) by marching tetrahedra: vertices (n, 3) on the grid edges that change sign, triangles (m, 3)
    with the positive side (outside) on their normal's side. The field must be positive on the grid's
    boundary (the surface is then closed)."""
    shape = tuple(len(a) for a in axes)
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    P = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    f = _evaluate(field, P)
    f[f == 0] = 1e-12  # no grid point exactly on the surface: every crossing is strictly inside an edge
    pos = (f > 0).reshape(shape)
    cube_pos = np.zeros(tuple(s - 1 for s in shape), np.int64)
    for dx, dy, dz in _CORNERS:
        cube_pos += pos[dx:shape[0] - 1 + dx, dy:shape[1] - 1 + dy, dz:shape[2] - 1 + dz]
    cells = np.argwhere((cube_pos > 0) & (cube_pos < 8))
    strides = np.array([shape[1] * shape[2], shape[2], 1])
    corner_ids = (cells[:, None, :] + _CORNERS[None]) @ strides  # (c, 8)
    tets = corner_ids[:, _TETS].reshape(-1, 4)  # (6c, 4) global point ids
    code = ((f[tets] > 0) * (1 << np.arange(4))).sum(1)
    tris, pos_pts = [], []
    for slot in range(2):
        take = _CASE_COUNT[code] > slot
        t, c = tets[take], code[take]
        local = _CASE_EDGES[c, slot]  # (k, 3, 2)
        tris.append(t[np.arange(len(t))[:, None], local.reshape(len(t), 6)].reshape(-1, 3, 2))
        pos_pts.append(t[np.arange(len(t)), _CASE_POS[c, slot]])
    E = np.concatenate(tris)  # (m, 3, 2) grid point pairs
    positive = np.concatenate(pos_pts)
    a, b = np.minimum(E[..., 0], E[..., 1]), np.maximum(E[..., 0], E[..., 1])
    keys, inverse = np.unique((a * len(P) + b).ravel(), return_inverse=True)
    ea, eb = keys // len(P), keys % len(P)
    t = np.clip(f[ea] / (f[ea] - f[eb]), 0.02, 0.98)
    V = P[ea] + t[:, None] * (P[eb] - P[ea])
    F = inverse.reshape(-1, 3).astype(np.int64)
    q0, q1, q2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    wrong = np.einsum("ij,ij->i", np.cross(q1 - q0, q2 - q0), P[positive] - q0) < 0
    F[wrong] = F[wrong][:, ::-1]
    return V, F


def _keep_largest(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The connected component with most faces, its vertices renumbered in their order."""
    label = component_labels(np.concatenate([F[:, [0, 1]], F[:, [1, 2]]]))[: len(F)]
    values, counts = np.unique(label, return_counts=True)
    F = F[label == values[np.argmax(counts)]]
    used = np.unique(F)
    remap = np.full(len(V), -1, np.int64)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def _neighbour_mean(F: np.ndarray, n: int) -> Callable[[np.ndarray], np.ndarray]:
    from scipy.sparse import coo_matrix

    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    A = coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    A.data[:] = 1.0  # each undirected edge once
    deg = np.asarray(A.sum(1)).ravel()
    return lambda X: (A @ X) / deg[:, None]


def _face_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])


def _gradient(field: Field, X: np.ndarray, h: float) -> np.ndarray:
    g = np.empty_like(X)
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        g[:, k] = (_evaluate(field, X + d) - _evaluate(field, X - d)) / (2 * h)
    return g


def _project(field: Field, X: np.ndarray, h: float, steps: int = 3) -> np.ndarray:
    """Newton steps onto field = 0, each move capped at ``h`` (a point never jumps to another sheet)."""
    for _ in range(steps):
        g = _gradient(field, X, 0.05 * h)
        step = (_evaluate(field, X) / np.maximum((g * g).sum(1), 1e-300))[:, None] * g
        length = np.linalg.norm(step, axis=1, keepdims=True)
        X = X - step * np.minimum(1.0, h / np.maximum(length, 1e-300))
    return X


def _relax(field: Field, V: np.ndarray, F: np.ndarray, h: float, rounds: int = 6) -> np.ndarray:
    """Even out the triangles: tangential neighbour-mean steps, each followed by a projection onto the
    level set; a vertex of a face that would turn over (or shrink to a sliver) moves half as far, or stays."""
    mean = _neighbour_mean(F, len(V))
    normal0 = _face_normals(V, F)
    area0 = np.linalg.norm(normal0, axis=1)
    for _ in range(rounds):
        N = _gradient(field, V, 0.05 * h)
        N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
        d = mean(V) - V
        d -= (d * N).sum(1, keepdims=True) * N
        W = _project(field, V + 0.6 * d, h)
        for attempt in range(8):
            n = _face_normals(W, F)
            bad = ((n * normal0).sum(1) <= 0.1 * area0 * np.linalg.norm(n, axis=1)) | \
                  (np.linalg.norm(n, axis=1) < 0.05 * area0)
            if not bad.any():
                V = W
                break
            back = np.unique(F[bad])
            W[back] = (W[back] + V[back]) / 2 if attempt < 5 else V[back]
    return V


def _surface(field: Field, lo, hi, target: int, rng: np.random.Generator, min_cells: int = 30,
             warp: float = 0.0, relax: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The closed level set of ``field`` inside the box lo..hi with about ``target`` vertices: a first
    grid sizes the second (vertices grow as the square of the resolution). ``min_cells``: at least so
    many cells along the box's longest side (fine shapes keep their parts). ``warp``: the grid's points move by up to this fraction of
    a cell along smooth waves, so the sampling density varies over the surface. The grid is shifted by a
    random fraction of a cell so that no plane of the shape falls on grid points."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    shift = rng.uniform(0.2, 0.8, 3)
    phase = rng.uniform(0, 2 * np.pi, 3)

    def axes_for(h):
        out = []
        for k in range(3):
            n = int(np.ceil((hi[k] - lo[k]) / h)) + 3
            u = lo[k] + (np.arange(n) - 1.5 + shift[k]) * h
            if warp:
                s = (u - lo[k]) / (hi[k] - lo[k])
                u = u + warp * h * 2.5 * np.sin(2 * np.pi * s + phase[k])  # monotone: slope below 1
            out.append(u)
        return tuple(out)

    extent = (hi - lo).max()
    h = extent / 48
    V, _ = _polygonise(field, axes_for(h))
    h = min(h * np.sqrt(len(V) / target), extent / min_cells)
    V, F = _keep_largest(*_polygonise(field, axes_for(h)))
    if relax:
        V = _relax(field, V, F, h)
    return V, F


# ----------------------------------------------------------------------------- fields


def _metaballs(centres: np.ndarray, radii: np.ndarray) -> Field:
    def f(X):
        d2 = sum((X[:, k:k + 1] - centres[:, k]) ** 2 for k in range(3))
        return 1.0 - np.exp(-d2 / radii ** 2).sum(1)
    return f


def _waves(rng: np.random.Generator, n: int, freq: tuple[float, float], amplitude: float) -> Field:
    """A smooth random field: a sum of ``n`` plane waves of random directions, frequencies, phases."""
    D = rng.normal(size=(n, 3))
    D *= (rng.uniform(*freq, n) / np.linalg.norm(D, axis=1))[:, None]
    phase = rng.uniform(0, 2 * np.pi, n)
    amp = amplitude * rng.uniform(0.3, 1.0, n) / np.sqrt(n)
    def f(X):  # the products written out: a (k, 3) @ (3, n) product through BLAS threads is slower here
        arg = X[:, :1] * D[:, 0] + X[:, 1:2] * D[:, 1] + X[:, 2:3] * D[:, 2] + phase
        return np.sin(arg) @ amp
    return f


def _chain(rng: np.random.Generator, n: int, step: float) -> np.ndarray:
    """``n`` metaball centres along a random walk (each near the previous), centred on the origin."""
    C = np.zeros((n, 3))
    for i in range(1, n):
        C[i] = C[rng.integers(0, i)] + step * rng.normal(size=3) / np.sqrt(3)
    return C - C.mean(0)


def _box(centre, half) -> Field:
    c, hl = np.asarray(centre, float), np.asarray(half, float)

    def f(X):
        q = np.abs(X - c) - hl
        outside = np.maximum(q, 0)
        return np.sqrt(np.einsum("ij,ij->i", outside, outside)) + np.minimum(np.maximum(np.maximum(
            q[:, 0], q[:, 1]), q[:, 2]), 0)
    return f


def _cylinder(centre, axis: int, radius: float, half_height: float) -> Field:
    c = np.asarray(centre, float)
    others = [k for k in range(3) if k != axis]

    def f(X):
        r = np.hypot(X[:, others[0]] - c[others[0]], X[:, others[1]] - c[others[1]]) - radius
        z = np.abs(X[:, axis] - c[axis]) - half_height
        return np.hypot(np.maximum(r, 0), np.maximum(z, 0)) + np.minimum(np.maximum(r, z), 0)
    return f


def _capsule(a, b, radius: float) -> Field:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ab = b - a

    def f(X):
        t = np.clip((X - a) @ ab / (ab @ ab), 0, 1)
        return np.linalg.norm(X - a - t[:, None] * ab, axis=1) - radius
    return f


def _union(*fs: Field) -> Field:
    return lambda X: functools.reduce(np.minimum, [g(X) for g in fs])


def _minus(f: Field, *holes: Field) -> Field:
    return lambda X: functools.reduce(np.maximum, [f(X)] + [-g(X) for g in holes])


def _rotated(f: Field, angle: float) -> Field:
    """f after a rotation by ``angle`` about z."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return lambda X: f(X @ R)


def _bounds(field: Field, rng_box: float, probe: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """A box around the region field < 0 (searched on a coarse grid over [-rng_box, rng_box]^3), padded."""
    u = np.linspace(-rng_box, rng_box, probe)
    X, Y, Z = np.meshgrid(u, u, u, indexing="ij")
    P = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    inside = P[_evaluate(field, P) < 0]
    pad = 3 * (u[1] - u[0])
    return inside.min(0) - pad, inside.max(0) + pad


# ----------------------------------------------------------------------------- families


def _organic_field(rng: np.random.Generator) -> Field:
    n = int(rng.integers(3, 9))
    C = _chain(rng, n, 0.9)
    R = rng.uniform(0.5, 0.9, n)
    base = _metaballs(C, R)
    bumps = _waves(rng, 12, (2.0, 6.0), 0.35)
    return lambda X: base(X) + bumps(X)


def _organic(rng, target):
    f = _organic_field(rng)
    return _surface(f, *_bounds(f, 4.0), target, rng)


def _scan(rng, target):
    f = _organic_field(rng)
    V, F = _surface(f, *_bounds(f, 4.0), target, rng, warp=0.35)
    N = np.zeros_like(V)
    np.add.at(N, F, _face_normals(V, F)[:, None, :])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
    edge = np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1).mean()
    V = V + N * rng.normal(0, 0.12 * edge, len(V))[:, None]
    return _holes(V, F, rng, int(rng.integers(2, 6)))


def _holes(V, F, rng, count: int):
    """Cut ``count`` small holes (faces within 1 to 3 rings of random vertices), then remove the faces at
    any vertex where the boundary pinches, until every boundary vertex has one fan."""
    mean = _neighbour_mean(F, len(V))
    near = np.zeros(len(V))
    near[rng.choice(len(V), count, replace=False)] = 1.0
    for _ in range(int(rng.integers(1, 4))):
        near = np.maximum(near, (mean(near[:, None])[:, 0] > 0) * 1.0)
    F = F[~(near[F] > 0).any(1)]
    while True:
        V, F = _keep_largest(V, F)
        adj = build_adjacency(F, len(V))
        if not adj.nonmanifold_vertex.any():
            return V, F
        F = F[~adj.nonmanifold_vertex[F].any(1)]


def _cad_field(rng: np.random.Generator) -> Field:
    if rng.random() < 0.6:
        half = rng.uniform([0.8, 0.5, 0.2], [1.6, 1.0, 0.6])
        base = _box([0, 0, 0], half)
    else:
        r, hh = rng.uniform(0.8, 1.3), rng.uniform(0.2, 0.7)
        half = np.array([r, r, hh])
        base = _cylinder([0, 0, 0], 2, r, hh)
    adds, cuts = [], []
    for _ in range(int(rng.integers(1, 4))):  # bosses on the top face
        c = rng.uniform(-0.6, 0.6, 2) * half[:2]
        h = rng.uniform(0.15, 0.5)
        if rng.random() < 0.5:
            adds.append(_cylinder([c[0], c[1], half[2] + h / 2], 2, rng.uniform(0.15, 0.4), h / 2 + 0.05))
        else:
            adds.append(_box([c[0], c[1], half[2] + h / 2], [*rng.uniform(0.1, 0.4, 2), h / 2 + 0.05]))
    for _ in range(int(rng.integers(1, 5))):  # holes and slots
        c = rng.uniform(-0.7, 0.7, 2) * half[:2]
        if rng.random() < 0.7:
            cuts.append(_cylinder([c[0], c[1], 0], 2, rng.uniform(0.08, 0.25), 3.0 if rng.random() < 0.6 else half[2]))
        else:
            cuts.append(_box([c[0], c[1], half[2]], [*rng.uniform(0.05, 0.3, 2), rng.uniform(0.1, 0.8) * half[2]]))
    return _minus(_union(base, *adds), *cuts)


def _cad(rng, target):
    f = _cad_field(rng)
    return _surface(f, *_bounds(f, 3.0, probe=64), target, rng)


def _thin(rng, target):
    n = int(rng.integers(3, 7))
    r = rng.uniform(0.04, 0.08)
    P = [np.zeros(3)]
    parts = []
    for i in range(n):
        a = P[rng.integers(0, len(P))]
        d = rng.normal(size=3)
        b = a + rng.uniform(0.6, 1.4) * d / np.linalg.norm(d)
        P.append(b)
        parts.append(_capsule(a, b, r * rng.uniform(0.8, 1.3)))
    if rng.random() < 0.5:  # a thin fin on one rod
        a, b = P[0], P[1]
        parts.append(_box((a + b) / 2, [np.linalg.norm(b - a) / 3, 0.25, r * 0.7]))
    f = _union(*parts)
    return _surface(f, *_bounds(f, 2.2 * n ** 0.5, probe=80), target, rng)


def _open(rng, target):
    """A sheet: an (n x n) grid of the unit square, jittered, split along random diagonals, optionally
    mapped onto a disk, bent (a cylinder or a sphere cap) and bumped along its normal."""
    n = int(np.sqrt(target))
    u = np.linspace(-1, 1, n)
    U, W = np.meshgrid(u, u, indexing="ij")
    P = np.stack([U.ravel(), W.ravel()], 1)
    inner = (np.abs(P) < 1).all(1)
    P[inner] += rng.uniform(-0.3, 0.3, (inner.sum(), 2)) * (u[1] - u[0])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    q = np.stack([i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1], -1).reshape(-1, 4)
    flip = rng.random(len(q)) < 0.5
    F = np.concatenate([np.where(flip[:, None], q[:, [0, 1, 2]], q[:, [0, 1, 3]]),
                        np.where(flip[:, None], q[:, [0, 2, 3]], q[:, [1, 2, 3]])])
    x, y = P.T
    if rng.random() < 0.5:  # the square onto the disk (one-to-one)
        x, y = x * np.sqrt(1 - y * y / 2), y * np.sqrt(1 - x * x / 2)
    x, y = x * rng.uniform(0.8, 1.2), y * rng.uniform(0.8, 1.2)
    kind = rng.integers(0, 3)
    bend = rng.uniform(0.5, 1.2)
    if kind == 0:  # a cylinder section
        V = np.stack([np.sin(x * bend) / bend, y, (1 - np.cos(x * bend)) / bend], 1)
    elif kind == 1:  # a sphere cap
        r = np.hypot(x, y)
        s = np.where(r > 0, np.sin(r * bend) / (bend * np.maximum(r, 1e-300)), 1.0)
        V = np.stack([x * s, y * s, (1 - np.cos(r * bend)) / bend], 1)
    else:  # a saddle
        V = np.stack([x, y, 0.3 * bend * (x * x - y * y)], 1)
    N = np.zeros_like(V)
    np.add.at(N, F, _face_normals(V, F)[:, None, :])
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    V = V + N * _waves(rng, 10, (2.0, 7.0), 0.08)(V)[:, None]
    return V, F.astype(np.int64)


def _ellipsoid(rng, target):
    axes = np.sort(rng.uniform(0.5, 1.5, 3))[::-1] * np.array([1.3, 1.0, 0.8])
    c = rng.normal(size=3)
    c = c / np.linalg.norm(c) * axes
    w, a = rng.uniform(0.15, 0.35), rng.uniform(0.02, 0.06)

    def f(X):
        g = np.linalg.norm(X / axes, axis=1) - 1.0
        return g - a * np.exp(-((X - c) ** 2).sum(1) / w**2)
    return _surface(f, -axes * 1.2, axes * 1.2, target, rng)


def _bilateral(rng, target):
    n = int(rng.integers(2, 5))
    C = _chain(rng, n, 0.8)
    C[:, 0] = np.abs(C[:, 0]) + 0.2
    mid = _chain(rng, int(rng.integers(1, 4)), 0.8)
    mid[:, 0] = 0.0
    R = rng.uniform(0.45, 0.8, 2 * n + len(mid))
    R[n:2 * n] = R[:n]
    base = _metaballs(np.concatenate([C, C * [-1, 1, 1], mid]), R)
    bumps = _waves(rng, 10, (2.0, 6.0), 0.3)
    f = lambda X: base(X) + 0.5 * (bumps(X) + bumps(X * [-1, 1, 1]))
    return _surface(f, *_bounds(f, 4.0), target, rng)


def _symmetric_part(rng, fold: int) -> Field:
    """A part invariant under rotations by 2 pi / fold about z: a base (a box with unequal sides for
    fold 2, a disk for fold 4) with bosses added and holes cut, each copied to every rotation."""
    if fold == 2:
        half = rng.uniform([1.0, 0.45, 0.15], [1.6, 0.8, 0.4])
        base = _box([0, 0, 0], half)
        reach = half[:2] * 0.75
    else:
        r, hh = rng.uniform(0.9, 1.4), rng.uniform(0.12, 0.35)
        base = _union(_cylinder([0, 0, 0], 2, r, hh), _cylinder([0, 0, hh], 2, r * rng.uniform(0.3, 0.5), 2 * hh))
        half = np.array([r, r, hh])
        reach = np.array([r, r]) * 0.6
    adds, cuts = [], []
    for _ in range(int(rng.integers(1, 3))):
        c = rng.uniform(0.3, 1.0, 2) * reach
        hb = rng.uniform(0.1, 0.35)
        adds.append(_cylinder([c[0], c[1], half[2] + hb / 2], 2, rng.uniform(0.1, 0.25), hb / 2 + 0.05))
    for _ in range(int(rng.integers(1, 3))):
        c = rng.uniform(0.3, 1.0, 2) * reach
        cuts.append(_cylinder([c[0], c[1], 0], 2, rng.uniform(0.06, 0.15), 3.0))
    turns = [2 * np.pi * k / fold for k in range(fold)]
    adds = [_rotated(g, t) for g in adds for t in turns]
    cuts = [_rotated(g, t) for g in cuts for t in turns]
    if fold == 4:
        cuts.append(_cylinder([0, 0, 0], 2, float(rng.uniform(0.08, 0.2)), 3.0))  # a centre bore
    return _minus(_union(base, *adds), *cuts)


def _cad2(rng, target):
    f = _symmetric_part(rng, 2)
    return _surface(f, *_bounds(f, 2.5, probe=64), target, rng)


def _cad4(rng, target):
    f = _symmetric_part(rng, 4)
    return _surface(f, *_bounds(f, 2.5, probe=64), target, rng)


FAMILIES: dict[str, Callable[[np.random.Generator, int], tuple[np.ndarray, np.ndarray]]] = {
    "organic": _organic, "cad": _cad, "scan": _scan, "thin": _thin, "open": _open,
    "ellipsoid": _ellipsoid, "bilateral": _bilateral, "cad2": _cad2, "cad4": _cad4,
}
#: the families whose shapes are closed (no boundary edge)
CLOSED_FAMILIES = ("organic", "cad", "thin", "ellipsoid", "bilateral", "cad2", "cad4")


def _pose(V: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random rotation, a scale giving a bounding-box diagonal between 0.05 and 50, an offset."""
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q *= np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    V = (V - V.mean(0)) @ Q.T
    diag = np.linalg.norm(V.max(0) - V.min(0))
    scale = np.exp(rng.uniform(np.log(0.05), np.log(50))) / diag
    return V * scale + rng.normal(size=3) * scale


def generate(family: str, seed: int, vertices: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One shape of ``family`` (a key of FAMILIES) from ``seed`` (an integer >= 0): vertices (n, 3)
    float64 and faces (m, 3) int64, manifold, outward, no degenerate face. Deterministic in the seed.
    The seed draws the size too (log-uniform, 3,000 to 28,000 vertices aimed at); ``vertices`` aims at
    that many instead (the shape is the same, sampled more or less finely)."""
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r}; choose one of {', '.join(FAMILIES)}")
    rng = np.random.default_rng([list(FAMILIES).index(family), int(seed)])
    drawn = int(np.exp(rng.uniform(np.log(3000), np.log(28000))))
    V, F = FAMILIES[family](rng, int(vertices) if vertices else drawn)
    return np.ascontiguousarray(_pose(V, rng), dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64)


def mesh_report(vertices: np.ndarray, faces: np.ndarray) -> dict[str, object]:
    """What a benchmark shape must satisfy, measured: counts, the edges with more than two faces,
    the edges whose two faces disagree on orientation, boundary edges and loops, pinched (non-manifold)
    and unreferenced vertices, the smallest face area relative to the mean, connected components,
    the Euler characteristic, and (closed meshes) the signed volume (positive when outward)."""
    V, F = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    adj = build_adjacency(F, len(V))
    a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * len(V) + np.maximum(a, b)
    forward = np.bincount(np.unique(key, return_inverse=True)[1], weights=(a < b).astype(float))
    count = adj.edge_face_count
    boundary = adj.edges[count == 1]
    area = np.linalg.norm(_face_normals(V, F), axis=1) / 2
    c = V[F]
    volume = float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6)
    components = len(np.unique(component_labels(np.concatenate([F[:, [0, 1]], F[:, [1, 2]]]))))
    return {
        "vertices": len(V), "faces": len(F),
        "overfull_edges": int((count > 2).sum()),
        "misoriented_edges": int(((count == 2) & (forward != 1)).sum()),
        "boundary_edges": len(boundary),
        "boundary_loops": len(np.unique(component_labels(boundary))) if len(boundary) else 0,
        "pinched_vertices": int(adj.nonmanifold_vertex.sum()),
        "unreferenced_vertices": int(adj.isolated_vertex.sum()),
        "repeated_corner_faces": int(((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])).sum()),
        "min_area_ratio": float(area.min() / area.mean()),
        "components": components,
        "euler": len(V) - len(adj.edges) + len(F),
        "signed_volume": volume,
    }
