"""The blind scheme's carrier: keyed directions among the solid's low spatial frequencies.

In the solid's frame (``solid``, unit = its RMS radius) the pass phrase draws ``N_WAVES`` plane waves
psi_j(x) = cos(2 pi f_j u_j . x + phi_j), frequencies uniform in the ball shell ``BAND`` (cycles per RMS
radius). Each wave's integral over the solid, y_j, is a surface integral by the divergence theorem:
y_j = integral of G_j . n dA with G_j = u_j sin(2 pi f_j u_j . x + phi_j) / (2 pi f_j), computed with a
3-point rule per face. It belongs to the solid, not to its sampling: remeshing, simplification, subdivision
and re-export move it far less than the mark, and moving the surface by delta along its normals moves it by
the surface integral of psi_j delta.

Word bit k reads z_k = s_k . y, s_k a keyed unit spread vector of its word length (``Spread``), quantised
with a public step Delta (``STEPS``) and a keyed dither d_k: bit 0 where z_k / Delta - d_k is an integer,
bit 1 a half-integer (dither modulation). ``mark`` moves the vertices along their normals by the
least-energy field in the span of the spread waves that puts every z_k on its bit's lattice, reading
everything again (frame, normals) for a few rounds. The reading is ``waveread``; the choices and their
measurements: docs/schemes/blind.md and docs/decisions/141-keyed-waves-prototype.md.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from .solid import Frame, solid_frame

__all__ = [
    "BAND",
    "N_WAVES",
    "STEPS",
    "Waves",
    "Spread",
    "waves_of",
    "spread_of",
    "integrals",
    "solid_integrals",
    "projections",
    "mark",
]

BAND = (0.3, 4.5)  # cycles per RMS radius of the solid
N_WAVES = 768
STEPS = tuple(1e-3 * 2 ** (i / 2) for i in range(10))  # the public quantisation steps (frame units^3)
ROUNDS = 3  # the marking reads the mesh again this many times
QUADRATURE = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


def _generator(secret: str, label: str) -> np.random.Generator:
    digest = hashlib.sha256(f"{secret}:{label}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


@dataclass(frozen=True)
class Waves:
    """The keyed waves of a secret: directions u (P, 3) unit, frequencies f (P,), phases (P,)."""

    u: np.ndarray
    f: np.ndarray
    phase: np.ndarray

    @property
    def omega(self) -> np.ndarray:
        """(3, P): the waves' angular wave vectors, for ``X @ omega``."""
        return (2 * np.pi * self.f[:, None] * self.u).T


@dataclass(frozen=True)
class Spread:
    """The keyed reading of a word of K bits: spread vectors (K, P) unit rows, dithers (K,) in [0, 1),
    scramble (K,) uint8 (XOR of the word before it is written)."""

    vectors: np.ndarray
    dither: np.ndarray
    scramble: np.ndarray


def waves_of(secret: str, n_waves: int = N_WAVES, band: tuple[float, float] = BAND) -> Waves:
    """The ``Waves`` of a secret (``word.derive_secret``)."""
    r = _generator(secret, "blind-waves")
    u = r.normal(size=(n_waves, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    f = r.uniform(band[0] ** 3, band[1] ** 3, n_waves) ** (1 / 3)
    return Waves(u, f, r.uniform(0, 2 * np.pi, n_waves))


def spread_of(secret: str, n_word: int, n_waves: int = N_WAVES) -> Spread:
    """The ``Spread`` of a secret's words of ``n_word`` bits (each length its own)."""
    r = _generator(secret, f"blind-waves-spread:{n_word}")
    S = r.normal(size=(n_word, n_waves))
    S /= np.linalg.norm(S, axis=1)[:, None]
    return Spread(S, r.uniform(0, 1, n_word), r.integers(0, 2, n_word).astype(np.uint8))


def integrals(Y: np.ndarray, faces: np.ndarray, waves: Waves, block: int = 4096) -> np.ndarray:
    """y (P,) float64: each wave's integral over the solid bounded by the surface Y (n, 3) (frame
    coordinates), faces (m, 3). The waves are evaluated in float32 (an error near 1e-4 of the smallest
    step), ``block`` faces at a time (memory: a few (block, P) arrays), and summed in float64."""
    W = waves.omega.astype(np.float32)
    u = waves.u.T.astype(np.float32)
    phase = waves.phase.astype(np.float32)
    y = np.zeros(len(waves.f))
    for start in range(0, len(faces), block):
        T = Y[faces[start : start + block]]
        un = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]).astype(np.float32) @ u  # 2 area (n . u)
        for q in QUADRATURE:
            arg = (q[0] * T[:, 0] + q[1] * T[:, 1] + q[2] * T[:, 2]).astype(np.float32) @ W
            arg += phase
            np.sin(arg, out=arg)
            arg *= un
            y += arg.sum(0, dtype=np.float64)
    return y / (2 * np.pi * waves.f) / 6


def solid_integrals(vertices: np.ndarray, faces: np.ndarray, waves: Waves, frame: Frame) -> np.ndarray:
    """y (P,): the waves' integrals over the solid in ``frame``, whichever way its faces turn
    (``Frame.orientation``)."""
    return frame.orientation * integrals(frame.local(vertices), faces, waves)


def projections(vertices: np.ndarray, faces: np.ndarray, waves: Waves, spread: Spread, frame: Frame) -> np.ndarray:
    """z (K,): the word's projections of the surface in ``frame``."""
    return spread.vectors @ solid_integrals(vertices, faces, waves, frame)


def vertex_normals_areas(Y: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals (n, 3), areas (n,)): each vertex's third of its faces' vector areas, and its length."""
    T = Y[faces]
    third = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]) / 6
    vector = np.zeros_like(Y)
    for i in range(3):
        np.add.at(vector, faces[:, i], third)
    area = np.linalg.norm(vector, axis=1)
    return vector / np.maximum(area, 1e-300)[:, None], area


def _moments(Y: np.ndarray) -> np.ndarray:
    """(n, 10): 1, x, y, z, x^2, y^2, z^2, xy, yz, zx at the vertices Y (n, 3): a normal move delta changes
    the solid's volume, centroid and second moments (its frame) by the surface integrals of delta times these."""
    x, y, z = Y.T
    return np.stack([np.ones(len(Y)), x, y, z, x * x, y * y, z * z, x * y, y * z, z * x], axis=1)


def field(Y: np.ndarray, faces: np.ndarray, waves: Waves, spread: Spread, target: np.ndarray):
    """(moves (n,), normals (n, 3)): the least-energy normal displacement in the span of the spread waves
    and the moment functions that changes the projections by ``target`` (K,) and leaves the solid's volume,
    centroid and second moments (so its frame) as they are, to first order (frame units). Without the
    moments the frame drifts with each move and the marking converges slowly on detailed shapes."""
    N, area = vertex_normals_areas(Y, faces)
    SP = np.cos(Y @ waves.omega + waves.phase) @ spread.vectors.T  # (n, K): the spread waves on the surface
    A = np.concatenate([SP, _moments(Y)], axis=1)
    G = A.T @ (area[:, None] * A)
    G[np.diag_indices_from(G)] += 1e-12 * np.trace(G) / len(G)
    return A @ np.linalg.solve(G, np.concatenate([target, np.zeros(10)])), N


def mark(vertices, faces, waves: Waves, spread: Spread, bits: np.ndarray, step: float, rounds: int = ROUNDS):
    """The vertices (n, 3) float64 moved along their normals so that each projection z_k lies on the
    lattice of bit k (``bits`` (K,) uint8, already scrambled) at ``step``."""
    V = np.array(vertices, np.float64)
    F = np.asarray(faces, np.int64)
    for _ in range(rounds):
        frame = solid_frame(V, F)
        Y = frame.local(V)
        e = frame.orientation * (spread.vectors @ integrals(Y, F, waves)) / step - spread.dither - bits / 2
        move, N = field(Y, F, waves, spread, -frame.orientation * (e - np.round(e)) * step)
        V = V + frame.world(move[:, None] * N)
    return V
