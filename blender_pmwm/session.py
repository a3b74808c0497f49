"""Session-only state: the last watermark of each object and the progressive meshes read from disk.

Nothing here is saved in the .blend: key material (carriers, the PM of a marked object) lives in
memory for this Blender session only, so sharing a .blend never reveals it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np


@dataclass
class Marked:
    """What the last watermark of one object left behind (memory only)."""

    name: str
    pm: object  # pmwm.ProgressiveMesh of the marked mesh (None: watermarked without one)
    carriers: np.ndarray  # carrier vertex indices into the mesh
    positions: np.ndarray  # (n, 3) float32 positions written back, to detect later edits or undo
    n_bits: int
    vsnr_db: float


@dataclass
class Verified:
    """The last verification of one object (memory only): the panel's verdict box and its report."""

    name: str
    verdict: object  # pmwm.Verdict
    key: object  # pmwm.WatermarkKey; None when read with a pass phrase (nothing for a report to cite)
    key_path: str
    key_sha256: str
    positions: np.ndarray  # (n, 3) float32 positions read, to detect later edits
    faces: np.ndarray  # (m, 3) int64 triangles read

    @property
    def reportable(self) -> bool:
        """True when Save Report can write this verification (a key file to cite)."""
        return self.key is not None


_MARKED: dict[int, Marked] = {}
_VERIFIED: dict[int, Verified] = {}
_BUSY: dict[int, str] = {}  # object pointer -> what runs on it in the background
_PROGRESS: dict[int, str] = {}  # object pointer -> how far it is ("35%, building the progressive mesh, 4 s")
_PM_FILES: dict[tuple[str, int], object] = {}


def remember(ob, marked: Marked) -> None:
    """Record the watermark of ``ob``, keyed by the object's pointer."""
    _MARKED[ob.as_pointer()] = marked


def lookup(ob) -> Marked | None:
    """The last watermark of ``ob`` in this session, or None."""
    return _MARKED.get(ob.as_pointer())


def remember_verified(ob, verified: Verified) -> None:
    """Record the last verification of ``ob``."""
    _VERIFIED[ob.as_pointer()] = verified


def lookup_verified(ob) -> Verified | None:
    """The last verification of ``ob`` in this session, or None."""
    return _VERIFIED.get(ob.as_pointer())


def busy(ob) -> str | None:
    """What runs on ``ob`` in the background ("watermarking", "verifying"), or None."""
    return _BUSY.get(ob.as_pointer())


def set_busy(pointer: int, what: str | None) -> None:
    if what is None:
        _BUSY.pop(pointer, None)
        _PROGRESS.pop(pointer, None)
    else:
        _BUSY[pointer] = what


def set_progress(pointer: int, text: str) -> None:
    _PROGRESS[pointer] = text


def progress(ob) -> str:
    """How far the background run on ``ob`` is ("" when none runs or it has not reported yet)."""
    return _PROGRESS.get(ob.as_pointer(), "")


def same_positions(stored: np.ndarray, positions32: np.ndarray) -> bool:
    """True when two float32 position arrays are exactly equal."""
    return stored.shape == positions32.shape and np.array_equal(stored, positions32)


WHOLE = 50_000  # meshes up to this many vertices are compared whole by ``looks_unchanged``
SAMPLES = 64  # vertices compared in a larger mesh


def looks_unchanged(mesh, stored: np.ndarray) -> bool:
    """A check cheap enough for every redraw (a few milliseconds): every vertex of a mesh of up to WHOLE
    vertices, else the vertex count and SAMPLES evenly spread vertices, equal ``stored`` (n, 3) float32.
    The operators compare every vertex before they write anything."""
    n = len(mesh.vertices)
    if n != len(stored):
        return False
    if n <= WHOLE:
        co = np.empty(n * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        return np.array_equal(co.reshape(-1, 3), stored)
    for i in np.unique(np.linspace(0, n - 1, SAMPLES).astype(np.int64)).tolist():
        if tuple(mesh.vertices[i].co) != tuple(stored[i].tolist()):
            return False
    return True


def load_pm(path: str):
    """Read a .pmwm file through a cache keyed by path and modification time."""
    import pmwm

    path = os.path.abspath(path)
    mtime = os.stat(path).st_mtime_ns
    pm = _PM_FILES.get((path, mtime))
    if pm is None:
        pm = pmwm.read_pm(path)
        for stale in [k for k in _PM_FILES if k[0] == path]:
            del _PM_FILES[stale]
        _PM_FILES[(path, mtime)] = pm
    return pm


def clear() -> None:
    """Forget everything (on file load and when the add-on is disabled)."""
    _MARKED.clear()
    _VERIFIED.clear()
    _BUSY.clear()
    _PROGRESS.clear()
    _PM_FILES.clear()
