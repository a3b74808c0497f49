"""Mesh file input/output through trimesh.

Why this module exists: the watermark lives in vertex positions, so a file must come in and go out
without trimesh quietly merging, reordering or rounding vertices. Everything is loaded with
``process=False``; the canonical mesh the algorithms see is an exact-position weld of the file's
vertices (``weld``), and ``write_marked`` writes the file's *own* vertices (UV seams, order) back
with new positions. OBJ and OFF are written by this module (trimesh's writers round to a fixed
number of decimals); each coordinate is written with ``repr`` so float64 values read back bit-exactly.
PLY, STL and GLB store float32 positions (``SourceMesh.float32`` tells whether the input already fits).

Files are written through ``pmwm.atomic``.

trimesh is imported only when a file needs it: the plain files pmwm itself writes and most scanned
meshes (an OFF of triangles without comments, a binary little-endian PLY of float x, y, z and
triangles, nothing else) are read and written here directly, giving exactly the arrays and bytes
trimesh gives (``_read_plain``, ``_ply_bytes``); any other file goes through trimesh.
"""

from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .atomic import atomic_write_bytes
from .errors import MeshError, PmwmError
from .features import vertex_normals
from .validate import check_mesh, check_vertices

if TYPE_CHECKING:  # annotations only: trimesh is imported when a file needs it
    import trimesh

SUPPORTED_EXTENSIONS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")

__all__ = [
    "SUPPORTED_EXTENSIONS",
    "SourceMesh",
    "read_mesh",
    "write_mesh",
    "write_marked",
    "weld",
    "canonical_mesh",
]


@dataclass
class SourceMesh:
    """A mesh file as read: the welded canonical mesh plus the file's own geometry for write-back."""

    vertices: np.ndarray  # (n, 3) float64 canonical vertices (exact duplicates merged, first-appearance order)
    faces: np.ndarray  # (m, 3) int64 triangles over canonical vertices (degenerate ones dropped)
    source: "trimesh.Trimesh | PlainMesh"  # the mesh as loaded (process=False), vertex order of the file
    source_to_canonical: np.ndarray  # (len(source.vertices),) int64: file vertex -> canonical vertex
    float32: bool  # every coordinate is exactly representable as float32
    warnings: list[str] = field(default_factory=list)
    path: str = ""


@dataclass
class PlainMesh:
    """A file read without trimesh (``_read_plain``): its vertices (n, 3) float64 and triangles
    (m, 3) int64 in file order, and no visuals (what trimesh loads from such a file)."""

    vertices: np.ndarray
    faces: np.ndarray
    visual: None = None


# --------------------------------------------------------------------------------------------
# welding
# --------------------------------------------------------------------------------------------


_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser (wrapping uint64 arithmetic)."""
    x = x ^ (x >> np.uint64(30))
    x = x * _M1
    x = x ^ (x >> np.uint64(27))
    x = x * _M2
    return x ^ (x >> np.uint64(31))


def _row_hash(bits: np.ndarray) -> np.ndarray:
    """A 64-bit hash of each row of (n, 3) uint64 bit patterns; collisions are checked by the caller."""
    with np.errstate(over="ignore"):
        return _mix(bits[:, 0] ^ _mix(bits[:, 1] ^ _mix(bits[:, 2])))


def _same_as_previous(bits: np.ndarray) -> np.ndarray:
    """(n-1,) bool: row i+1 equals row i (column-wise compares beat .all(axis=1))."""
    return (bits[1:, 0] == bits[:-1, 0]) & (bits[1:, 1] == bits[:-1, 1]) & (bits[1:, 2] == bits[:-1, 2])


def _group_rows(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(order, starts_mask): an order putting equal rows next to each other, and where groups start.

    ``key`` is (n, 3) float64 without -0.0, so equal values have equal bits. Sorting one hashed
    uint64 column is about 3x faster than a 3-key lexsort; if two different rows ever share a
    hash, the exact lexsort is used instead.
    """
    bits = np.ascontiguousarray(key).view(np.uint64)
    h = _row_hash(bits)
    sh = np.sort(h)
    if not (sh[1:] == sh[:-1]).any():  # all hashes differ, so do all rows: nothing to group
        return np.arange(len(key)), np.ones(len(key), dtype=bool)
    order = np.argsort(h)
    sh = h[order]
    same_row = _same_as_previous(bits[order])
    if np.any((sh[1:] == sh[:-1]) & ~same_row):  # hash collision: fall back to the exact sort
        order = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))
        same_row = _same_as_previous(bits[order])
    starts_mask = np.ones(len(key), dtype=bool)
    starts_mask[1:] = ~same_row
    return order, starts_mask


def weld(vertices, faces) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge vertices with exactly equal positions; number them in order of first appearance.

    Returns ``(welded_vertices, welded_faces, inverse)`` with ``welded_vertices[inverse] ==
    vertices`` (0.0 and -0.0 count as equal). Faces are remapped one to one (none dropped, so a
    face may now repeat a vertex). Why: trimesh splits vertices at UV seams and STL is a triangle
    soup, while the watermark needs the connected surface.
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = len(v)
    if n == 0:
        return v.copy(), f.copy(), np.zeros(0, dtype=np.int64)
    key = v + 0.0  # -0.0 -> +0.0 so both compare and hash as one position
    order, starts_mask = _group_rows(key)
    if starts_mask.all():  # no duplicates (the common case): nothing to renumber
        return v.copy(), f.copy(), np.arange(n, dtype=np.int64)
    group_of_sorted = np.cumsum(starts_mask) - 1
    first = np.minimum.reduceat(order, np.flatnonzero(starts_mask))  # earliest index per position
    is_first = np.zeros(n, dtype=bool)
    is_first[first] = True
    canonical_of_index = np.cumsum(is_first) - 1  # rank among first appearances
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = canonical_of_index[first][group_of_sorted]
    return v[is_first], inverse[f], inverse


# --------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------

_FORMAT_NAMES = {".obj": "OBJ", ".ply": "PLY", ".stl": "STL", ".off": "OFF", ".glb": "GLB", ".gltf": "glTF"}
_VT_LINE = re.compile(rb"(?m)^[ \t]*vt[ \t]")


def _extension(path: str) -> str:
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED_EXTENSIONS:
        shown = ext or "no extension"
        raise MeshError(f"{path}: unsupported mesh format ({shown}); use one of {', '.join(SUPPORTED_EXTENSIONS)}")
    return ext


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    msg = text[0] if text else ""
    if len(msg) > 160:
        msg = msg[:157] + "..."
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


def _describe_nonmesh(obj) -> str:
    import trimesh

    if isinstance(obj, trimesh.PointCloud):
        return f"a point cloud of {len(obj.vertices)} points, no faces"
    if type(obj).__name__ in ("Path2D", "Path3D"):
        return "lines or curves only, no faces"
    if isinstance(obj, trimesh.Trimesh):
        return f"{len(obj.vertices)} vertices, no faces"
    if isinstance(obj, trimesh.Scene):
        return "an empty scene" if len(obj.geometry) == 0 else "a scene without faces"
    return f"a {type(obj).__name__}, no faces"


def _load_trimesh(path: str, ext: str) -> tuple["trimesh.Trimesh", list[str]]:
    """Load without processing (trimesh, or ``_read_plain`` for plain OFF and PLY files) and reduce the
    result to one mesh."""
    if not os.path.lexists(path):
        raise MeshError(f"{path} does not exist; check the path")
    if os.path.isdir(path):
        raise MeshError(f"{path} is a directory, not a mesh file")
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise MeshError(f"cannot read {path}: {exc.strerror or exc}") from None
    if not data or data.isspace():
        raise MeshError(f"{path} holds no triangle mesh (the file is empty)")

    plain = _read_plain(data, ext)
    if plain is not None:
        return plain, []

    import trimesh

    kwargs = {}
    if ext == ".obj":
        # Keep the file's vertex order and its unreferenced vertices, unless UVs are present:
        # then trimesh must split vertices at UV seams (maintain_order would corrupt the UVs).
        kwargs["maintain_order"] = _VT_LINE.search(data) is None
    try:
        resolver = trimesh.resolvers.FilePathResolver(os.path.abspath(path))
        loaded = trimesh.load(io.BytesIO(data), file_type=ext[1:], resolver=resolver, process=False, **kwargs)
    except Exception as exc:  # trimesh raises anything on bad input; report it on one line
        raise MeshError(f"cannot read {path} as {_FORMAT_NAMES[ext]} ({_short(exc)})") from None

    warnings: list[str] = []
    if isinstance(loaded, trimesh.Scene):
        try:
            parts = loaded.dump()
        except Exception as exc:
            raise MeshError(f"cannot read {path}: scene could not be flattened ({_short(exc)})") from None
        meshes = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces) > 0]
        skipped = len(parts) - len(meshes)
        if not meshes:
            raise MeshError(f"{path} holds no triangle mesh ({_describe_nonmesh(loaded)})")
        if skipped:
            warnings.append(f"ignored {skipped} scene geometries without faces")
        if len(meshes) == 1:
            mesh = meshes[0]
        else:
            try:
                mesh = trimesh.util.concatenate(meshes)
            except Exception:  # visuals that cannot be merged: keep the geometry only
                offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
                mesh = trimesh.Trimesh(
                    np.concatenate([m.vertices for m in meshes]),
                    np.concatenate([m.faces + off for m, off in zip(meshes, offsets)]),
                    process=False,
                )
                warnings.append("scene materials could not be merged and were dropped")
            warnings.append(f"scene of {len(meshes)} meshes concatenated (pmwm.scene reads them as objects)")
        return mesh, warnings
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces) > 0:
        return loaded, warnings
    raise MeshError(f"{path} holds no triangle mesh ({_describe_nonmesh(loaded)})")


def canonical_mesh(
    v_src: np.ndarray, f_src: np.ndarray, where: str, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mesh the schemes see from a file's own vertices (n, 3) float64 and triangles (m, 3) int64:
    exact duplicates welded (``weld``), degenerate faces dropped. Returns (vertices, faces, inverse),
    inverse (n,) int64 file vertex -> canonical vertex; appends what it did to ``warnings``; MeshError
    (naming ``where``) when no face is left."""
    vertices, faces, inverse = weld(v_src, f_src)
    if len(vertices) < len(v_src):
        warnings.append(
            f"welded {len(v_src) - len(vertices)} duplicate vertices (UV seams, split normals or a triangle soup)"
        )
    degenerate = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    n_bad = int(degenerate.sum())
    if n_bad:
        faces = faces[~degenerate]
        warnings.append(f"dropped {n_bad} degenerate faces")
        if len(faces) == 0:
            raise MeshError(f"{where} holds no triangle mesh (all {n_bad} faces are degenerate)")
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    n_unused = int(len(vertices) - used.sum())
    if n_unused:
        warnings.append(f"{n_unused} vertices are not used by any face")
    return vertices, np.ascontiguousarray(faces, dtype=np.int64), inverse


def _is_float32(v: np.ndarray) -> bool:
    with np.errstate(over="ignore", invalid="ignore"):
        return bool(np.array_equal(v.astype(np.float32).astype(np.float64), v))


def read_mesh(path) -> SourceMesh:
    """Read a mesh file into a welded, triangulated canonical mesh (MeshError on any problem). A file of
    several objects is flattened into one mesh (a warning); ``pmwm.scene`` reads it as objects."""
    p = os.fspath(path)
    if os.path.isdir(p):
        raise MeshError(f"{p} is a directory; give a mesh file")
    ext = _extension(p)
    mesh, warnings = _load_trimesh(p, ext)

    v_src = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f_src = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    if not np.isfinite(v_src).all():
        bad = int((~np.isfinite(v_src).all(axis=1)).sum())
        raise MeshError(f"{p} has {bad} vertices with non-finite (NaN/inf) coordinates; repair the mesh")
    if len(f_src) and (f_src.min() < 0 or f_src.max() >= len(v_src)):
        raise MeshError(f"{p} has faces that reference missing vertices; repair the mesh")

    vertices, faces, inverse = canonical_mesh(v_src, f_src, p, warnings)
    return SourceMesh(
        vertices=vertices,
        faces=faces,
        source=mesh,
        source_to_canonical=inverse,
        float32=_is_float32(v_src),
        warnings=warnings,
        path=p,
    )


# --------------------------------------------------------------------------------------------
# plain files without trimesh
# --------------------------------------------------------------------------------------------

_PLY_FLOAT = {b"float": "<f4", b"float32": "<f4", b"double": "<f8", b"float64": "<f8"}
_PLY_HEADER = (
    b"ply\nformat binary_little_endian 1.0\ncomment %s\n"
    b"element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
    b"element face %d\nproperty list uchar int vertex_indices\nend_header\n"
)
_TRIMESH_COMMENT = b"https://github.com/mikedh/trimesh"
_PLY_FACE = np.dtype([("count", "<u1"), ("index", "<i4", (3,))])


def _read_plain(data: bytes, ext: str) -> "PlainMesh | None":
    """The mesh of a plain OFF or PLY file, read without trimesh, or None for any other file (trimesh
    reads it). The arrays are exactly trimesh's (``process=False``): the same text-to-number
    conversion, vertex order and faces. Plain: an ASCII OFF of triangles ("OFF" first line, no
    comments, three numbers per vertex line, nothing after the faces); a binary little-endian PLY
    whose vertices are float or double x, y, z and whose faces are uchar-counted int triangles,
    nothing else. Files with bad indices also go to trimesh (its error message)."""
    try:
        mesh = _read_plain_off(data) if ext == ".off" else _read_plain_ply(data) if ext == ".ply" else None
    except (ValueError, UnicodeDecodeError):
        return None
    if mesh is None or len(mesh.faces) == 0 or mesh.faces.min() < 0 or mesh.faces.max() >= len(mesh.vertices):
        return None
    return mesh


_OFF_BYTES = np.zeros(256, bool)
_OFF_BYTES[np.frombuffer(b"0123456789.-+eE \t\r\n", np.uint8)] = True


def _read_plain_off(data: bytes) -> "PlainMesh | None":
    body = data[3:]
    if not data.startswith(b"OFF") or body[:1] not in (b"\n", b"\r"):
        return None
    if not _OFF_BYTES[np.frombuffer(body, np.uint8)].all():
        return None  # digits, signs, exponents, points and blanks only: no comments, colours, names
    # trimesh's lines: str.splitlines (here only \n, \r\n and \r), stripped, empty ones dropped
    lines = [line for line in (raw.strip() for raw in body.replace(b"\r", b"\n").split(b"\n")) if line]
    head = lines[0].split() if lines else []
    if not 2 <= len(head) <= 3:
        return None
    nv, nf = int(head[0]), int(head[1])
    if nv <= 0 or nf <= 0 or len(lines) != 1 + nv + nf:
        return None
    vblock, fblock = b"\n".join(lines[1 : 1 + nv]), b"\n".join(lines[1 + nv :])
    if not (_tokens_per_line(vblock, nv) == 3).all() or not (_tokens_per_line(fblock, nf) == 4).all():
        return None
    ftok = fblock.decode("ascii").split()
    if ftok[0::4].count("3") != nf:  # triangles only
        return None
    # trimesh's own conversion of the same strings (np.array of str to float64 / int64)
    vertices = np.array(vblock.decode("ascii").split(), dtype=np.float64).reshape(nv, 3)
    faces = np.array(ftok, dtype=np.int64).reshape(nf, 4)[:, 1:]
    return PlainMesh(vertices, np.ascontiguousarray(faces))


def _tokens_per_line(block: bytes, n: int) -> np.ndarray:
    """(n,) int64: the number of blank-separated tokens on each of the n lines of ``block`` (lines
    joined by \\n, none empty, none with leading or trailing blanks)."""
    b = np.frombuffer(block, np.uint8)
    newline = b == 10
    sep = newline | (b == 32) | (b == 9)
    start = ~sep
    start[1:] &= sep[:-1]
    return np.bincount(np.cumsum(newline)[start], minlength=n)


def _read_plain_ply(data: bytes) -> "PlainMesh | None":
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        return None
    header = data[:end].split(b"\n")[1:]  # the last is the empty rest before end_header
    body = [h for h in header[:-1] if not h.startswith(b"comment ") and h != b"comment"]
    if len(body) != 7 or body[0] != b"format binary_little_endian 1.0":
        return None
    ev, px, py, pz, ef, pf = (line.split() for line in body[1:])
    if len(ev) != 3 or ev[:2] != [b"element", b"vertex"] or len(ef) != 3 or ef[:2] != [b"element", b"face"]:
        return None
    types = set()
    for prop, name in ((px, b"x"), (py, b"y"), (pz, b"z")):
        if len(prop) != 3 or prop[0] != b"property" or prop[2] != name or prop[1] not in _PLY_FLOAT:
            return None
        types.add(_PLY_FLOAT[prop[1]])
    if (
        len(types) != 1
        or pf[:4] != [b"property", b"list", b"uchar", b"int"]
        or len(pf) != 5
        or pf[4] not in (b"vertex_indices", b"vertex_index")
    ):
        return None
    nv, nf = int(ev[2]), int(ef[2])
    vtype = np.dtype(types.pop())
    start = end + len(b"end_header\n")
    if nv <= 0 or nf <= 0 or len(data) != start + nv * 3 * vtype.itemsize + nf * _PLY_FACE.itemsize:
        return None
    vertices = np.frombuffer(data, vtype, 3 * nv, start).astype(np.float64).reshape(nv, 3)
    faces = np.frombuffer(data, _PLY_FACE, nf, start + nv * 3 * vtype.itemsize)
    if not (faces["count"] == 3).all():
        return None
    return PlainMesh(vertices, faces["index"].astype(np.int64))


def ply_parts(n_vertices: int, faces: np.ndarray, comment: bytes = _TRIMESH_COMMENT) -> tuple[bytes, bytes]:
    """The two fixed parts of a binary little-endian PLY of ``n_vertices`` float32 vertices and
    triangles ``faces`` (m, 3): its header and its face block. The file is header + the vertices as
    ``<f4`` bytes + the face block (copies that differ only in positions share both parts)."""
    face = np.zeros(len(faces), _PLY_FACE)
    face["count"] = 3
    face["index"] = faces
    return _PLY_HEADER % (comment, n_vertices, len(faces)), face.tobytes()


def _ply_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary PLY of vertices (n, 3) as float32 and triangles (m, 3), byte for byte what
    trimesh's ``export_ply(mesh, encoding="binary", vertex_normal=False)`` writes for a mesh
    without visuals or attributes."""
    head, body = ply_parts(len(vertices), faces)
    return b"".join([head, np.ascontiguousarray(vertices, "<f4").tobytes(), body])


# --------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------


def _float_lines(prefix: str, values: np.ndarray) -> str:
    """Rows of floats as text, each with repr (shortest string that reads back bit-exactly)."""
    rows, cols = values.shape
    if rows == 0:
        return ""
    line = prefix + " ".join(["%r"] * cols) + "\n"
    return (line * rows) % tuple(values.ravel().tolist())


def _int_lines(line: str, values: np.ndarray) -> str:
    if len(values) == 0:
        return ""
    return (line * len(values)) % tuple(values.ravel().tolist())


def _obj_text(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None, header: str = "") -> str:
    parts = ["# written by pmwm\n", header, _float_lines("v ", vertices)]
    f1 = faces + 1
    if uv is not None:
        parts.append(_float_lines("vt ", uv))
        pairs = np.repeat(f1, 2, axis=1)  # v/vt with vt index == v index
        parts.append(_int_lines("f %d/%d %d/%d %d/%d\n", pairs))
    else:
        parts.append(_int_lines("f %d %d %d\n", f1))
    return "".join(parts)


def _off_text(vertices: np.ndarray, faces: np.ndarray) -> str:
    return f"OFF\n{len(vertices)} {len(faces)} 0\n" + _float_lines("", vertices) + _int_lines("3 %d %d %d\n", faces)


def _obj_material_header(src: SourceMesh, out_path: str) -> str:
    """Point the written OBJ at the source OBJ's material library, if it had one."""
    if not src.path.lower().endswith(".obj") or not os.path.isfile(src.path):
        return ""
    material = getattr(src.source.visual, "material", None)
    name = getattr(material, "name", None)
    try:
        with open(src.path, "rb") as fh:
            text = fh.read()
    except OSError:
        return ""
    found = re.search(rb"(?m)^[ \t]*mtllib[ \t]+(.+?)[ \t]*\r?$", text)
    if not found:
        return ""
    lib = found.group(1).decode("utf-8", "replace")
    lib_abs = os.path.join(os.path.dirname(os.path.abspath(src.path)), lib)
    rel = os.path.relpath(lib_abs, os.path.dirname(os.path.abspath(out_path))).replace(os.sep, "/")
    return f"mtllib {rel}\n" + (f"usemtl {name}\n" if name else "")


def _export_trimesh(mesh: "trimesh.Trimesh", ext: str) -> bytes:
    """Bytes of a binary/float32 format written by trimesh (vertex order and faces kept)."""
    import trimesh

    if ext == ".ply":
        return trimesh.exchange.ply.export_ply(mesh, encoding="binary", vertex_normal=False)
    if ext == ".stl":
        return trimesh.exchange.stl.export_stl(mesh)
    # glTF viewers shade flat without normals, so give them fresh ones for the new positions
    normals = vertex_normals(np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64))
    normals[~normals.any(axis=1)] = (0.0, 0.0, 1.0)  # viewers want a unit normal everywhere
    mesh.vertex_normals = normals
    scene = trimesh.Scene(mesh)
    if ext == ".glb":
        return trimesh.exchange.gltf.export_glb(scene, include_normals=True)
    files = trimesh.exchange.gltf.export_gltf(scene, include_normals=True, embed_buffers=True)
    return files["model.gltf"]


def _visual_copy(visual):
    """A copy of the loaded visuals (UVs, colours) that trimesh can export.

    Without Pillow, trimesh gives an OBJ without a texture image a material whose image is a
    deferred ImportError; copying or hashing it raises. Such a material is replaced by a plain
    one of the same name, so UVs survive without needing Pillow.
    """
    import trimesh

    if isinstance(visual, trimesh.visual.TextureVisuals):
        material = visual.material
        try:
            hash(material)
            material = material.copy()
        except Exception:
            try:
                name = material.name
            except Exception:
                name = None
            material = trimesh.visual.material.SimpleMaterial(name=name)
        uv = None if visual.uv is None else np.array(visual.uv, dtype=np.float64)
        return trimesh.visual.TextureVisuals(uv=uv, material=material)
    try:
        return visual.copy()
    except Exception:
        return None


def _trimesh(vertices: np.ndarray, faces: np.ndarray, visual=None):
    """A trimesh.Trimesh of the arrays as they are (no processing)."""
    import trimesh

    return trimesh.Trimesh(vertices, faces, visual=visual, process=False)


def write_mesh(path, vertices, faces, *, force: bool = False) -> None:
    """Write a triangle mesh; the format comes from the extension. Atomic.

    PLY (binary), OFF and OBJ keep the vertex order and faces exactly; OBJ/OFF coordinates
    are exact float64, PLY/STL/GLB store float32. STL is a triangle soup (re-welded on read).
    """
    p = os.fspath(path)
    ext = _extension(p)
    v, f = check_mesh(vertices, faces, need_faces=False)
    if ext == ".obj":
        data = _obj_text(v, f).encode("ascii")
    elif ext == ".off":
        data = _off_text(v, f).encode("ascii")
    else:
        # a mesh without visuals: trimesh's PLY bytes are written here, without loading trimesh
        data = _encode(lambda: _ply_bytes(v, f) if ext == ".ply" else _export_trimesh(_trimesh(v, f), ext), p)
    atomic_write_bytes(p, data, force=force)


def _encode(fn, path: str) -> bytes:
    try:
        return fn()
    except PmwmError:
        raise
    except Exception as exc:
        raise MeshError(f"cannot write {path} ({_short(exc)})") from None


def write_marked(path, src: SourceMesh, canonical_vertices, *, force: bool = False) -> None:
    """Write the loaded file's own mesh (vertex order, UVs, faces) with new positions. Atomic.

    ``canonical_vertices`` are positions of ``src.vertices``; each file vertex takes the position
    of its canonical vertex, so UV-seam copies move together. Normals are not carried over (they
    would be stale); GLB/glTF get fresh ones. An OBJ written from an OBJ keeps its ``mtllib``.
    """
    p = os.fspath(path)
    ext = _extension(p)
    v = check_vertices(canonical_vertices, "marked vertices", rows=len(src.vertices))
    positions = v[src.source_to_canonical]
    faces = np.asarray(src.source.faces, dtype=np.int64)
    if ext == ".off":
        data = _off_text(positions, faces).encode("ascii")
    elif ext == ".obj":
        uv = getattr(src.source.visual, "uv", None)
        if uv is not None:
            uv = np.asarray(uv, dtype=np.float64)
            if uv.ndim != 2 or uv.shape[0] != len(positions) or uv.shape[1] < 2 or not np.isfinite(uv).all():
                uv = None
            else:
                uv = uv[:, :2]
        header = _obj_material_header(src, p) if uv is not None else ""
        data = _obj_text(positions, faces, uv=uv, header=header).encode("utf-8")
    else:

        def export() -> bytes:
            if isinstance(src.source, PlainMesh) and ext == ".ply":
                return _ply_bytes(positions, faces)  # no visuals: trimesh's bytes without trimesh
            mesh = _trimesh(positions, faces, visual=_visual_copy(src.source.visual))
            return _export_trimesh(mesh, ext)

        data = _encode(export, p)
    atomic_write_bytes(p, data, force=force)
