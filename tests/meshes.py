"""The test meshes, generated here from fixed seeds so that the suite needs nothing beyond the clone.

The one real scan the tests use is the Stanford bunny shipped with the package
(``pmwm/data/bunny.off``; its provenance and terms are in ``core/pmwm/data/README.md``). Every other
mesh is generated: each function's docstring says which property the tests rely on. The same call
always returns the same arrays (fresh copies; the generation is cached per process).

Coordinates are rounded to a fixed number of significant decimal digits, as in a text mesh file, so
that ``mesh_file`` writes exactly the arrays the functions return.
"""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from pathlib import Path

import numpy as np


# ----------------------------------------------------------------------------- the meshes


def bunny() -> tuple[np.ndarray, np.ndarray]:
    """The Stanford bunny shipped with the package: 34,835 vertices, 69,666 faces, closed, genus 0.
    A real scan (uneven vertex density, fine detail), used wherever the tests measure robustness or
    distortion on a mesh of the size the paper uses."""
    return _copy(_bunny())


def blob() -> tuple[np.ndarray, np.ndarray]:
    """A closed, genus-0, manifold organic shape of 2,906 vertices (5,808 faces) in a cow's bounding
    box (1.044 x 0.64 x 0.34): a bumpy body with eight thin limbs, so that the curvature varies
    everywhere and is high on the limbs, and a vertex density that varies smoothly (16 times from one
    end to the other), as over a scan.

    The tests need a *small* real-looking mesh: the robust scheme has to crowd its sites on it (some
    are spoilt by a neighbour's bump, some find no protected ring where the surface curves), it
    holds at most a few hundred bits, and it embeds and verifies in a second, so the command-line
    tests can run it in subprocesses."""
    return _copy(_blob())


def open_cap() -> tuple[np.ndarray, np.ndarray]:
    """An open, manifold, disk-like organic surface (a bumpy head-sized bowl: a closed shape with its
    top cut away): 11,140 vertices, 22,090 faces, one boundary loop of 188 edges, Euler
    characteristic 1.

    The tests need a mesh with a boundary: carriers must avoid it, and the progressive mesh must keep
    exactly one boundary loop (Euler characteristic 1) at every level of detail. It must be large
    enough for 300 carriers whose 2-rings do not touch."""
    return _copy(_open_cap())


def cad_part() -> tuple[np.ndarray, np.ndarray]:
    """A closed, genus-0 CAD-like part of 6,536 vertices (13,068 faces): a block with three planar
    faces and three curved ones (convex, concave, arched) meeting at sharp edges, meshed with an
    irregular triangulation whose edges follow the creases, placed away from the origin.

    The tests need a mesh unlike a scan: large flat regions (where every smoothness angle is zero)
    and sharp creases, on which embedding must still find carriers for a 64-bit payload."""
    return _copy(_cad_part())


def pinched_torus() -> tuple[np.ndarray, np.ndarray]:
    """A closed mesh of 2,881 vertices (5,760 faces) with exactly one non-manifold vertex: a torus
    whose tube narrows to a single point, so that two separate fans of faces meet at that vertex
    (Euler characteristic 1). Every other vertex and every edge is manifold.

    The tests need one pinched vertex: the progressive mesh must keep it (never collapse it) and
    still rebuild the mesh exactly."""
    return _copy(_pinched_torus())


# ----------------------------------------------------------------------------- mesh files

_FOLDER: list[Path] = []


def mesh_file(name: str) -> Path:
    """One of the meshes above as a file, written once per process into a temporary folder removed
    at exit. The files imitate text files found in the wild:

    - ``blob.off``: the ``blob()`` mesh in the style of libigl's OFF files (an edge count in the
      header, several spaces after the face size, a trailing space on each face line);
    - ``open_cap.off``: the ``open_cap()`` mesh with Windows line ends (CRLF) and a trailing space
      on each vertex line.
    """
    writers = {
        "blob.off": lambda p: write_off(p, *_blob(), edges=True, face_sep="   ", face_end=" "),
        "open_cap.off": lambda p: write_off(p, *_open_cap(), newline="\r\n", vertex_end=" "),
    }
    if name not in writers:
        raise KeyError(f"no generated mesh file {name!r}; known: {sorted(writers)}")
    if not _FOLDER:
        folder = Path(tempfile.mkdtemp(prefix="pmwm-test-meshes-"))
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        _FOLDER.append(folder)
    path = _FOLDER[0] / name
    if not path.exists():
        writers[name](path)
    return path


def write_off(
    path: Path,
    V: np.ndarray,
    F: np.ndarray,
    *,
    newline: str = "\n",
    edges: bool = False,
    vertex_end: str = "",
    face_sep: str = " ",
    face_end: str = "",
) -> Path:
    """Write an OFF file; ``repr``-style shortest digits keep the float64 values exactly."""
    n_edges = (
        len(np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0))
        if edges
        else 0
    )
    lines = ["OFF", f"{len(V)} {len(F)} {n_edges}"]
    lines += [f"{x!r} {y!r} {z!r}{vertex_end}" for x, y, z in V.tolist()]
    lines += [f"3{face_sep}{a} {b} {c}{face_end}" for a, b, c in F.tolist()]
    Path(path).write_bytes((newline.join(lines) + newline).encode("ascii"))
    return Path(path)


# ----------------------------------------------------------------------------- generation


def _copy(mesh):
    V, F = mesh
    return V.copy(), F.copy()


def _decimal(V: np.ndarray, digits: int) -> np.ndarray:
    """Round to ``digits`` significant decimal digits, as a text mesh file stores them."""
    return np.array([float(f"{x:.{digits}g}") for x in np.asarray(V, np.float64).ravel()]).reshape(V.shape)


@functools.cache
def _bunny():
    import trimesh

    import pmwm  # here, not at the top: conftest imports this module, and a broken pmwm fails only its users

    m = trimesh.load(str(Path(pmwm.__file__).parent / "data" / "bunny.off"), process=False)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _cube_surface(n: int, seed: int, jitter: float = 0.3, drop=None):
    """The boundary of the lattice cube [0, n]^3 as a triangle mesh: every lattice quad split along a
    random diagonal, every lattice point moved at random within its cube face (within its cube edge
    for edge points; corners stay). Returns (points in [-1, 1]^3, outward triangles, cube face of
    each triangle as 2 * axis + side). ``drop`` = (axis, side) leaves that cube face out."""
    rng = np.random.default_rng(seed)
    g = np.arange(n + 1)
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    on = np.any((lattice == 0) | (lattice == n), axis=-1)
    index = np.full((n + 1,) * 3, -1, np.int64)
    index[on] = np.arange(on.sum())
    P = lattice[on].astype(np.float64)
    free = (P > 0) & (P < n)
    P += free * rng.uniform(-jitter, jitter, P.shape)
    tris, face_of = [], []
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    for axis in range(3):
        b, c = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, 1):
            if drop == (axis, side):
                continue

            def at(u, v):
                ijk = np.empty((len(u), 3), np.int64)
                ijk[:, axis], ijk[:, b], ijk[:, c] = side * n, u, v
                return index[ijk[:, 0], ijk[:, 1], ijk[:, 2]]

            q = np.stack([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)], 1)  # ccw about +axis
            if side == 0:
                q = q[:, ::-1]

            def upright(t):  # the triangle keeps the face's orientation (the moved points may make the quad concave)
                e1, e2 = P[t[:, 1]] - P[t[:, 0]], P[t[:, 2]] - P[t[:, 0]]
                return (e1[:, b] * e2[:, c] - e1[:, c] * e2[:, b]) * (1 if side else -1) > 0

            ok_a = upright(q[:, [0, 1, 2]]) & upright(q[:, [0, 2, 3]])
            ok_b = upright(q[:, [0, 1, 3]]) & upright(q[:, [1, 2, 3]])
            flip = np.where(ok_a & ok_b, rng.random(len(q)) < 0.5, ok_a)
            t1 = np.where(flip[:, None], q[:, [0, 1, 2]], q[:, [0, 1, 3]])
            t2 = np.where(flip[:, None], q[:, [0, 2, 3]], q[:, [1, 2, 3]])
            tris.append(np.concatenate([t1, t2]))
            face_of.append(np.full(2 * len(q), 2 * axis + side))
    F = np.concatenate(tris)
    used = np.unique(F)
    remap = np.full(len(P), -1, np.int64)
    remap[used] = np.arange(len(used))
    return P[used] * (2.0 / n) - 1.0, remap[F], np.concatenate(face_of)


def _sphere_directions(P: np.ndarray) -> np.ndarray:
    """Cube points to unit directions, equal-angle (tan) so the triangles are about even in size."""
    D = np.tan(P * (np.pi / 4))
    return D / np.linalg.norm(D, axis=1, keepdims=True)


def _crowd(D: np.ndarray, k: float) -> np.ndarray:
    """Move unit directions towards the south pole: a dilation by ``k`` in stereographic coordinates
    (a smooth, conformal map of the sphere onto itself), so that the vertex density grows smoothly
    from the north pole to the south pole, by k^4 in all, as it varies over a scan."""
    x, y, z = D.T
    s = k / np.maximum(1.0 - z, 1e-300)
    X, Y = x * s, y * s
    q = X * X + Y * Y
    return np.stack([2 * X, 2 * Y, q - 1], 1) / (q + 1)[:, None]


def _radial_field(D: np.ndarray, seed: int, n_bumps: int, amplitude: tuple, width: tuple) -> np.ndarray:
    """exp of a sum of smooth random bumps on the sphere (von Mises-Fisher kernels): a positive radius."""
    rng = np.random.default_rng(seed)
    C = rng.normal(size=(n_bumps, 3))
    C /= np.linalg.norm(C, axis=1, keepdims=True)
    a = rng.uniform(*amplitude, n_bumps)
    w = rng.uniform(*width, n_bumps)
    return np.exp((a * np.exp((D @ C.T - 1.0) / w)).sum(1))


def _fit_box(V: np.ndarray, extents) -> np.ndarray:
    """Scale each axis and centre the bounding box on the origin."""
    lo, hi = V.min(0), V.max(0)
    return (V - (lo + hi) / 2) * (np.asarray(extents) / (hi - lo))


@functools.cache
def _blob():
    P, F, _ = _cube_surface(22, seed=2762)
    D = _crowd(_sphere_directions(P), 2.0)
    body = _radial_field(D, seed=5520, n_bumps=120, amplitude=(-0.3, 0.5), width=(0.01, 0.08))
    limbs = _radial_field(D, seed=7, n_bumps=8, amplitude=(0.6, 1.0), width=(0.01, 0.03))
    return _decimal(_fit_box(D * (body * limbs)[:, None], [1.044, 0.64, 0.34]), 6), F


@functools.cache
def _open_cap():
    P, F, _ = _cube_surface(47, seed=11381, drop=(2, 1))
    D = _sphere_directions(P)
    r = _radial_field(D, seed=22704, n_bumps=30, amplitude=(-0.2, 0.35), width=(0.03, 0.25))
    return _decimal(_fit_box(D * r[:, None], [0.52, 0.53, 1.0]), 6), F


@functools.cache
def _cad_part():
    P, F, _ = _cube_surface(33, seed=6475)
    x, y, z = P.T
    # X depends on x, Y on (x, y), Z on (x, y, z), each increasing in its own coordinate: a one-to-one
    # map. The faces x = -1, x = +1 and z = -1 stay planar; y = +1 bulges out, y = -1 is hollowed
    # and z = +1 is tilted and arched.
    X = 1.6 * x
    Y = 0.9 * y + 0.45 * (1 - x**2) * (y + 1) / 2 - 0.2 * (1 - x**2) * (1 - y) / 2
    Z = 0.5 * z + 0.125 * x * (z + 1) + 0.3 * (1 - y**2) * (z + 1) / 2
    V = np.stack([X, Y, Z], 1) + [2.4, 15.2, -1.3]
    return _decimal(V, 10), F


@functools.cache
def _pinched_torus():
    rng = np.random.default_rng(2903)
    nu, nv = 97, 30  # rings around the torus (ring 0 is the pinch point), vertices per ring
    u = (np.arange(1, nu) + rng.uniform(-0.3, 0.3, nu - 1))[:, None] * (2 * np.pi / nu)
    v = (np.arange(nv) + rng.uniform(-0.3, 0.3, (nu - 1, nv))) * (2 * np.pi / nv)
    u = np.broadcast_to(u, v.shape)
    R = 1.0
    r = 0.45 * np.sin(u / 2) ** 0.8 * (1 + 0.1 * np.sin(3 * u) * np.cos(2 * v))
    ring = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1)
    V = np.vstack([[R, 0.0, 0.0], ring.reshape(-1, 3)]) * [3.0, 2.0, 1.7]
    idx = 1 + np.arange((nu - 1) * nv).reshape(nu - 1, nv)
    a, b = idx[:-1], idx[1:]
    a2, b2 = np.roll(a, -1, axis=1), np.roll(b, -1, axis=1)
    flip = (rng.random(a.shape) < 0.5)[..., None]
    q = np.stack([a, a2, b2, b], -1)
    t1 = np.where(flip, q[..., [0, 1, 2]], q[..., [0, 1, 3]]).reshape(-1, 3)
    t2 = np.where(flip, q[..., [0, 2, 3]], q[..., [1, 2, 3]]).reshape(-1, 3)
    first, last = idx[0], idx[-1]
    fan_in = np.stack([np.zeros(nv, np.int64), np.roll(first, -1), first], 1)
    fan_out = np.stack([np.zeros(nv, np.int64), last, np.roll(last, -1)], 1)
    F = np.concatenate([fan_in, t1, t2, fan_out])[:, ::-1]  # outward
    return _decimal(V, 6), F
