"""The solid's frame: the key-free coordinates in which the blind scheme's keyed waves are laid.

A surface bounds a solid; its centroid, second-moment axes and RMS radius are integrals over the volume
(exact, by tetrahedra from a point of the surface's own, so that a surface with small holes still has
them), which noise, remeshing, simplification and subdivision barely move, unlike the vertices' or the
area's moments. The axes are signed by the surface's third moments along them; where a third moment is
too small to trust (a nearly symmetric solid), the reader tries both signs of that axis
(``sign_choices``), a choice it makes without the pass phrase and pays for in the p-value (the
reading's hypotheses, ``waveread``). Mirrored copies need no search: a mirrored solid's third moments
mirror with it, and so does the frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

__all__ = ["Frame", "solid_frame", "sign_choices", "SKEW_TRUSTED"]

SKEW_TRUSTED = 0.05  # |third moment| / (area * sigma^3) below this: both signs of that axis are read


@dataclass(frozen=True)
class Frame:
    """centre (3,), axes (3, 3) (columns, the largest spread first, signed), scale (the solid's RMS radius,
    > 0), skew (3,): each axis's normalised third moment (its sign is the axis's), and orientation (+-1): the
    sign of the solid's volume in frame coordinates (-1 when the faces turn inwards there: a mirrored copy
    whose faces were turned to face out again, or a mesh whose faces face in), by which integrals over the
    solid are multiplied so that they do not depend on it."""

    centre: np.ndarray
    axes: np.ndarray
    scale: float
    skew: np.ndarray
    orientation: float = 1.0

    def local(self, vertices: np.ndarray) -> np.ndarray:
        """vertices (n, 3) in the frame: centred, turned to the axes, divided by the scale."""
        return (np.asarray(vertices, np.float64) - self.centre) @ self.axes / self.scale

    def world(self, vectors: np.ndarray) -> np.ndarray:
        """Directions (n, 3) of the frame in world coordinates, lengths times the scale."""
        return np.asarray(vectors, np.float64) @ self.axes.T * self.scale

    def flipped(self, signs: np.ndarray) -> "Frame":
        """The same frame with axis k multiplied by signs[k] (+-1)."""
        s = np.asarray(signs, np.float64)
        return Frame(self.centre, self.axes * s, self.scale, self.skew * s, self.orientation * float(np.prod(s)))

    def aligned(self, like: "Frame") -> "Frame":
        """This frame with each axis signed as ``like``'s (a slightly moved copy read in the same choice)."""
        return self.flipped(np.where(np.diag(self.axes.T @ like.axes) < 0, -1.0, 1.0))


def solid_frame(vertices: np.ndarray, faces: np.ndarray) -> Frame:
    """The ``Frame`` of the solid bounded by a surface, vertices (n, 3) float64, faces (m, 3) int64
    (consistently oriented; either orientation). Raises ValueError when the surface bounds no volume."""
    V = np.asarray(vertices, np.float64)
    T = V[np.asarray(faces, np.int64)]
    n2 = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    area = 0.5 * np.sqrt(np.einsum("ij,ij->i", n2, n2))
    total = area.sum()
    if not total > 0:
        raise ValueError("the surface has no area")
    o = (area[:, None] * T.mean(1)).sum(0) / total
    a, b, c = T[:, 0] - o, T[:, 1] - o, T[:, 2] - o
    det = np.einsum("ij,ij->i", a, np.cross(b, c))  # 6 x each tetrahedron's signed volume
    vol = det.sum() / 6
    size = np.ptp(V, axis=0).max()
    if not abs(vol) > 1e-9 * total * size:
        raise ValueError("the surface bounds no volume (an open sheet)")
    s = a + b + c
    cen = (s * det[:, None]).sum(0) / 24 / vol
    second = (
        np.einsum("n,ni,nj->ij", det, a, a)
        + np.einsum("n,ni,nj->ij", det, b, b)
        + np.einsum("n,ni,nj->ij", det, c, c)
        + np.einsum("n,ni,nj->ij", det, s, s)
    )
    C = second / 120 / vol - np.outer(cen, cen)
    w, R = np.linalg.eigh((C + C.T) / 2)
    w, R = np.maximum(w[::-1], 0.0), R[:, ::-1]
    cen = cen + o
    X = (T.mean(1) - cen) @ R
    sigma = np.sqrt((area[:, None] * X**2).sum(0) / total)
    skew = (area[:, None] * X**3).sum(0) / total / np.maximum(sigma, 1e-300) ** 3
    signs = np.where(skew < 0, -1.0, 1.0)
    scale = float(np.sqrt(w.sum()))
    if not scale > 0:
        raise ValueError("the solid has no extent")
    axes = R * signs
    return Frame(cen, axes, scale, skew * signs, float(np.sign(vol) * np.sign(np.linalg.det(axes))))


def sign_choices(frame: Frame) -> list[np.ndarray]:
    """The sign choices (each (3,) of +-1) the reader tries in ``frame``: the frame as it is first, then
    every flip of the axes whose skew is below SKEW_TRUSTED (at most 8 choices)."""
    loose = np.abs(frame.skew) < SKEW_TRUSTED
    options = [(1.0, -1.0) if k else (1.0,) for k in loose]
    return [np.array(c) for c in product(*options)]
