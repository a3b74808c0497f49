"""Validation of what users hand to pmwm: mesh arrays (the one check every entry point uses: schemes,
attacks, metrics, writers) and payload bits, so the same bad input gets the same one-line error
everywhere."""

from __future__ import annotations

from typing import Optional, Sequence, Union

import numpy as np

from .errors import MeshError, PayloadError

__all__ = ["MAX_COORDINATE", "check_vertices", "check_mesh", "parse_bits"]

MAX_COORDINATE = 1e30  # marked meshes are float32 (max 3.4e38); quadrics square coordinates


def check_vertices(vertices, what: str = "vertices", rows: Optional[int] = None, copy: bool = False) -> np.ndarray:
    """``vertices`` as float64 (n, 3), or a MeshError naming ``what``: wrong shape, another row count
    than ``rows``, NaN or infinite coordinates. ``copy`` returns a copy even of a float64 input."""
    V = np.array(vertices, dtype=np.float64, copy=True) if copy else np.asarray(vertices, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"{what} must be an (n, 3) array of xyz positions, got shape {V.shape}")
    if rows is not None and len(V) != rows:
        raise MeshError(f"{what} has {len(V)} rows but the mesh has {rows} vertices")
    if not np.all(np.isfinite(V)):
        raise MeshError(f"{what} hold NaN or infinite coordinates; repair the mesh first")
    return V


def check_mesh(
    vertices, faces, *, need_faces: bool = True, copy: bool = False, max_coordinate: Optional[float] = None
) -> tuple[np.ndarray, np.ndarray]:
    """Validated (n, 3) float64 vertices and (m, 3) int64 triangles, or a MeshError.

    need_faces: an empty mesh (no vertex or no face) is an error ("nothing to watermark"); without
    it an empty face array is accepted as (0, 3). max_coordinate: the largest coordinate allowed
    (schemes pass MAX_COORDINATE: a marked mesh is float32). copy: fresh arrays, for callers that
    modify them in place.
    """
    F = np.array(faces, copy=True) if copy else np.asarray(faces)
    if need_faces and (F.size == 0 or np.size(vertices) == 0):
        raise MeshError("the mesh is empty (no vertices or no faces); nothing to watermark")
    V = check_vertices(vertices, copy=copy)
    if F.size == 0:
        F = F.reshape(0, 3)
    if F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(f"faces must be an (m, 3) array of triangles, got shape {F.shape}; triangulate first")
    if F.size and not np.issubdtype(F.dtype, np.integer):
        if not np.all(np.isfinite(F)) or np.any(F != np.round(F)):
            raise MeshError("face indices must be whole numbers; fix the face array")
    F = F.astype(np.int64)
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise MeshError("a face refers to a vertex index outside the vertex array; fix the face indices")
    if max_coordinate is not None and len(V) and np.abs(V).max() > max_coordinate:
        raise MeshError(
            f"coordinates reach {np.abs(V).max():.3g}, beyond float32 range for a marked mesh "
            f"(limit {max_coordinate:g}); rescale the mesh first"
        )
    return V, F


def parse_bits(raw: Union[str, Sequence[int], np.ndarray], erasures: bool = False) -> np.ndarray:
    """Bits from a '0'/'1' string or a sequence of 0/1: (N,) uint8, or a PayloadError.

    With ``erasures`` (reading extracted bits), anything else is an erasure and the result is
    float64 with NaN there; an empty input is then allowed.
    """
    if isinstance(raw, str):
        codes = np.frombuffer(raw.encode("ascii", "replace"), np.uint8)
        arr = np.where(codes == ord("0"), 0.0, np.where(codes == ord("1"), 1.0, np.nan))
    else:
        try:
            arr = np.asarray(raw, dtype=np.float64).ravel()
        except (TypeError, ValueError):
            raise PayloadError("bits must be a sequence of 0 and 1") from None
        arr = np.where((arr == 0) | (arr == 1), arr, np.nan)
    if erasures:
        return arr
    if len(arr) == 0 or np.isnan(arr).any():
        raise PayloadError("bits must be a non-empty string or sequence of 0 and 1, e.g. --bits 01101001")
    return arr.astype(np.uint8)
