"""The near-symmetric shapes the pose search was tuned on (``bench_pose.py --shapes tuning``); its results are
reported on ``pmwm_bench.corpus``'s, never tuned on.

Every shape is an icosphere (10,242 vertices) pushed onto a surface, with a seeded low-frequency wobble
small enough that the shape stays close to its symmetric ideal:
- ``ellipsoid``: an ellipsoid of random axes (three mirror planes, 2-fold axes);
- ``cad2``: a rounded box (superellipsoid) of three different sides (2-fold symmetry);
- ``cad4``: a rounded box of square section (4-fold symmetry about its long axis);
- ``bilateral``: an egg-like body with one mirror plane (a character's left and right).
"""

from __future__ import annotations

import numpy as np

FAMILIES = ("ellipsoid", "cad2", "cad4", "bilateral")


def _sphere() -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    m = trimesh.creation.icosphere(5)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def generate(family: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A shape of ``family`` (vertices (n, 3) float64, faces (m, 3) int64), drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    U, F = _sphere()
    if family == "ellipsoid":
        radii = np.sort(rng.uniform(0.45, 1.0, 3))[::-1]
        radii[0] = 1.0
        V = U * radii
    elif family in ("cad2", "cad4"):
        p = rng.uniform(4.0, 8.0)
        radii = np.array([1.0, rng.uniform(0.5, 0.8), rng.uniform(0.3, 0.45)])
        if family == "cad4":
            radii[2] = radii[1]
        g = (np.abs(U) ** p).sum(axis=1) ** (1.0 / p)
        V = U / g[:, None] * radii
    elif family == "bilateral":
        a, b = rng.uniform(0.55, 0.8), rng.uniform(0.4, 0.6)
        taper = rng.uniform(0.15, 0.35)
        V = U * np.array([1.0, a, b])
        V[:, 1] *= 1.0 + taper * U[:, 0]  # wider at one end: only the x-z plane is a mirror
        V[:, 2] += 0.2 * b * U[:, 0] ** 2
    else:
        raise ValueError(f"unknown family {family!r}; one of {FAMILIES}")
    # a seeded low-frequency wobble of 0.5-2 % of the size along the normal direction
    amp = rng.uniform(0.005, 0.02)
    k = rng.normal(size=(3, 3))
    phase = rng.uniform(0, 2 * np.pi, 3)
    wob = sum(np.sin(U @ k[i] + phase[i]) for i in range(3)) / 3.0
    V = V + amp * wob[:, None] * U
    return V, F
