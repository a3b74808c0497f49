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
    pm: object  # pmwm.ProgressiveMesh of the marked mesh
    carriers: np.ndarray  # carrier vertex indices into the mesh
    positions: np.ndarray  # (n, 3) float32 positions written back, to detect later edits or undo
    n_bits: int
    vsnr_db: float


_MARKED: dict[int, Marked] = {}
_PM_FILES: dict[tuple[str, int], object] = {}


def remember(ob, marked: Marked) -> None:
    """Record the watermark of ``ob``, keyed by the object's pointer."""
    _MARKED[ob.as_pointer()] = marked


def lookup(ob) -> Marked | None:
    """The last watermark of ``ob`` in this session, or None."""
    return _MARKED.get(ob.as_pointer())


def is_current(marked: Marked, positions32: np.ndarray) -> bool:
    """True when the mesh still holds exactly the positions the watermark wrote."""
    return marked.positions.shape == positions32.shape and np.array_equal(marked.positions, positions32)


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
    _PM_FILES.clear()
