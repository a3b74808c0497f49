"""The .pmwm file: a progressive mesh as a versioned, checked binary file.

Layout (little endian)::

    header   magic "\\x89PMWM\\r\\n\\x1a", version u16, flags u16 (bit 0: float64 positions),
             n_base_vertices u32, n_base_faces u32, n_records u32, n_levels u32, reserved u32
    base vertices   n_base_vertices x 3 float32 (float64 with flag bit 0)
    base faces      n_base_faces x 3 u32
    levels          n_levels u32: records at the end of each level
    records         n_records x (position 3 x float32|float64, v u32 whose top two bits are the
                    split flags, face mask u64): 24 bytes each with float32 positions
    checksum        SHA-256 of everything before it

Version 2 differs from version 1 only in the masks' top 12 bits, which name the two faces that end
each record's arc (``records.ENDS_SHIFT``), so that the decoder reads p and q from two faces instead
of summing over the arc. A version-1 file reads as before (without them), and a progressive mesh
without them (``end_ranks`` False: one read from a version-1 file) is written as version 1.

The size implied by the header is checked against the file size before anything is
allocated, so a header that claims a billion records is rejected at once. Nothing of
the watermark key is stored here.
"""

from __future__ import annotations

import hashlib
import os
import struct

import numpy as np

from ..atomic import atomic_write_bytes
from ..errors import PMFormatError
from .mesh import ProgressiveMesh
from .records import FLAG_SECOND, FLAG_SINGLE

MAGIC = b"\x89PMWM\r\n\x1a"
VERSION = 2  # the newest this module reads and writes (it reads every version from 1)
HEADER = struct.Struct("<8sHHIIIII")
_DIGEST = 32
_FLAG_F64 = 1
_V_BITS = 30  # v is stored in the low 30 bits, split flags in the top 2
MAX_VERTICES = (1 << _V_BITS) - 1


def _record_dtype(f64: bool) -> np.dtype:
    return np.dtype([("pos", "<f8" if f64 else "<f4", (3,)), ("v", "<u4"), ("mask", "<u8")])


def record_size(f64: bool = False) -> int:
    """Bytes per vertex-split record."""
    return _record_dtype(f64).itemsize


def to_bytes(pm: ProgressiveMesh) -> bytes:
    """Serialise a progressive mesh (float32 positions when they are exactly float32)."""
    if pm.n_vertices > MAX_VERTICES:
        raise PMFormatError(f"a .pmwm file holds at most {MAX_VERTICES} vertices; this mesh has {pm.n_vertices}")
    f64 = not pm.float32
    ftype = "<f8" if f64 else "<f4"
    header = HEADER.pack(
        MAGIC,
        VERSION if pm.end_ranks else 1,
        _FLAG_F64 if f64 else 0,
        pm.n_base_vertices,
        len(pm.base_faces),
        pm.n_records,
        len(pm.level_records),
        0,
    )
    rec = np.zeros(pm.n_records, dtype=_record_dtype(f64))
    rec["pos"] = pm.pos
    rec["v"] = pm.v.astype(np.uint32) | (pm.flags.astype(np.uint32) << np.uint32(_V_BITS))
    rec["mask"] = pm.mask
    body = b"".join(
        [
            header,
            np.ascontiguousarray(pm.base_vertices, dtype=ftype).tobytes(),
            np.ascontiguousarray(pm.base_faces, dtype="<u4").tobytes(),
            np.ascontiguousarray(pm.level_records, dtype="<u4").tobytes(),
            rec.tobytes(),
        ]
    )
    return body + hashlib.sha256(body).digest()


def from_bytes(data: bytes, name: str = "the file") -> ProgressiveMesh:
    """Parse and check a .pmwm file; PMFormatError on any inconsistency."""
    if len(data) < HEADER.size + _DIGEST:
        raise PMFormatError(f"{name} is too short to be a .pmwm progressive mesh ({len(data)} bytes)")
    magic, version, flags, nb, fb, nr, nl, _ = HEADER.unpack_from(data, 0)
    if magic != MAGIC:
        raise PMFormatError(f"{name} is not a .pmwm progressive mesh (wrong magic bytes)")
    if version > VERSION:
        raise PMFormatError(f"{name} is .pmwm version {version}; this pmwm reads versions 1 to {VERSION}: upgrade pmwm")
    if version < 1:
        raise PMFormatError(f"{name} has an invalid .pmwm version {version}")
    if flags & ~_FLAG_F64:
        raise PMFormatError(f"{name} uses unknown .pmwm flags {flags:#x}; upgrade pmwm")
    f64 = bool(flags & _FLAG_F64)
    fsize = 8 if f64 else 4
    rdt = _record_dtype(f64)
    expected = HEADER.size + nb * 3 * fsize + fb * 12 + nl * 4 + nr * rdt.itemsize + _DIGEST
    if len(data) != expected:
        raise PMFormatError(f"{name} is truncated or padded: its header promises {expected} bytes, it has {len(data)}")
    if hashlib.sha256(memoryview(data)[:-_DIGEST]).digest() != bytes(data[-_DIGEST:]):
        raise PMFormatError(f"{name} is corrupted (checksum mismatch); get a fresh copy")
    off = HEADER.size
    ftype = "<f8" if f64 else "<f4"
    base_v = np.frombuffer(data, ftype, nb * 3, off).reshape(nb, 3).astype(np.float64)
    off += nb * 3 * fsize
    base_f = np.frombuffer(data, "<u4", fb * 3, off).reshape(fb, 3).astype(np.int64)
    off += fb * 12
    levels = np.frombuffer(data, "<u4", nl, off).astype(np.int64)
    off += nl * 4
    rec = np.frombuffer(data, rdt, nr, off)
    vfield = rec["v"].astype(np.int64)
    v = vfield & MAX_VERTICES
    rflags = (vfield >> _V_BITS).astype(np.uint8)
    pm = ProgressiveMesh(
        base_vertices=base_v,
        base_faces=base_f,
        pos=rec["pos"].astype(np.float64),
        v=v,
        mask=rec["mask"].astype(np.uint64),
        flags=rflags,
        level_records=levels,
        float32=not f64,
        end_ranks=version >= 2,
    )
    _check(pm, name)
    return pm


def _check(pm: ProgressiveMesh, name: str) -> None:
    """Structural consistency, so that decoding can never index out of range."""
    nb, nr = pm.n_base_vertices, pm.n_records
    bad = None
    if len(pm.base_faces) and (pm.base_faces.max() >= nb):
        bad = "a base face refers to a missing vertex"
    elif np.any((pm.flags & ~np.uint8(FLAG_SINGLE | FLAG_SECOND)) != 0):
        bad = "unknown record flags"
    elif len(pm.level_records) == 0 and nr:
        bad = "records without levels"
    elif len(pm.level_records) and (
        np.any(np.diff(pm.level_records) <= 0) or pm.level_records[0] <= 0 or pm.level_records[-1] != nr
    ):
        bad = "level table out of order"
    elif nr and np.any(pm.v >= nb + _level_start(pm.level_records)):
        bad = "a record splits a vertex that its level has not got yet"
    elif not (np.all(np.isfinite(pm.base_vertices)) and np.all(np.isfinite(pm.pos))):
        bad = "non-finite coordinates"
    if bad:
        raise PMFormatError(f"{name} is inconsistent ({bad}); it was not written by pmwm or is damaged")


def _level_start(level_records: np.ndarray) -> np.ndarray:
    """For every record, the number of records before its level (they are applied together)."""
    starts = np.r_[0, level_records[:-1]]
    return np.repeat(starts, np.diff(np.r_[0, level_records]))


def write_pm(path, pm: ProgressiveMesh, *, force: bool = False) -> None:
    """Write a .pmwm file atomically (refuses an existing file unless force)."""
    atomic_write_bytes(path, to_bytes(pm), force=force)


def read_pm(path) -> ProgressiveMesh:
    """Read and check a .pmwm file."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise PMFormatError(f"{path} is a directory, not a .pmwm file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(HEADER.size)
            fh.seek(0, os.SEEK_END)
            size = fh.tell()
            if len(head) < 8 or head[:8] != MAGIC:
                raise PMFormatError(f"{path} is not a .pmwm progressive mesh (wrong magic bytes)")
            if len(head) == HEADER.size:
                _, _, flags, nb, fb, nr, nl, _ = HEADER.unpack(head)
                fsize = 8 if flags & _FLAG_F64 else 4
                rsize = _record_dtype(bool(flags & _FLAG_F64)).itemsize
                expected = HEADER.size + nb * 3 * fsize + fb * 12 + nl * 4 + nr * rsize + _DIGEST
                if expected != size:
                    raise PMFormatError(
                        f"{path} is truncated or padded: its header promises {expected} bytes, it has {size}"
                    )
            fh.seek(0)
            data = fh.read()
    except FileNotFoundError:
        raise PMFormatError(f"{path} does not exist") from None
    except OSError as exc:
        raise PMFormatError(f"cannot read {path}: {exc.strerror or exc}") from None
    return from_bytes(data, path)
