"""OBJ files of several objects, marked line by line: only the ``v`` lines whose position moved (and
the ``vn`` lines of normals that turned with them) are rewritten; every other line (``o``, ``g``,
``mtllib``, ``usemtl``, ``vt``, ``s``, faces, comments) is kept byte for byte, but for the ``mtllib`` paths
of a file written to another folder (pointed back at the input's libraries).

An object is what follows an ``o`` line (or, in a file without ``o`` lines, a ``g`` line) up to the
next one; objects whose faces share vertices (groups that are material sections of one mesh) are one
object, named by their names joined with "+". Faces are polygons: the canonical mesh takes them as
triangle fans; the file keeps them as written.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshError
from ..meshio import _tokens_per_line
from .canonical import SceneObject, canonical_object, moved_normals

__all__ = ["ObjScene", "read_obj_scene"]

_CUT_LINE = re.compile(rb"(?m)^[ \t]*[og][ \t]")  # an o or g line


@dataclass
class ObjScene:
    """An OBJ file of several objects: the objects for the schemes and the lines to write back.
    ``rows[i]``: the 0-based ``v`` numbers of ``objects[i]``'s own vertices."""

    path: str
    lines: list[bytes]
    objects: list[SceneObject]
    rows: list[np.ndarray]
    v_line: np.ndarray  # (n_v,) int64 line number of each v line
    v_xyz: np.ndarray  # (n_v, 3) float64 positions as read
    vn_line: np.ndarray  # (n_vn,) int64 line number of each vn line
    vn_xyz: np.ndarray  # (n_vn, 3) float64 normals as read
    corner_v: np.ndarray  # (c,) int64 0-based v of each face corner
    corner_vn: np.ndarray  # (c,) int64 0-based vn of each corner (-1: none)
    warnings: list[str] = field(default_factory=list)

    def write(self, path: str, marked: list[np.ndarray], *, force: bool = False) -> list[str]:
        """Write the file with each object's vertices at ``marked[i]`` ((n_i, 3) float64 canonical
        positions of ``objects[i]``); returns [path]. Atomic."""
        from ..atomic import atomic_write_bytes

        V = self.v_xyz.copy()
        before = np.zeros_like(V)
        after = np.zeros_like(V)
        for obj, rows, new in zip(self.objects, self.rows, marked):
            new = np.asarray(new, np.float64)
            if new.shape != obj.vertices.shape:
                raise MeshError(f"object {obj.name!r}: {len(new)} marked vertices for {len(obj.vertices)}")
            V[rows] = new[obj.source_to_canonical]
            before[rows] = obj.normals_before()[obj.source_to_canonical]
            after[rows] = obj.normals_after(new)[obj.source_to_canonical]
        lines = list(self.lines)
        moved = np.flatnonzero((V != self.v_xyz).any(axis=1))
        for i in moved.tolist():
            lines[self.v_line[i]] = _replace_xyz(lines[self.v_line[i]], b"v", V[i], "%r")
        if len(self.vn_xyz):
            has = self.corner_vn >= 0
            cv, cn = self.corner_v[has], self.corner_vn[has]
            n = len(self.vn_xyz)
            count = np.bincount(cn, minlength=n)[:, None]
            mean = lambda a: np.stack([np.bincount(cn, a[cv, k], n) for k in range(3)], 1) / np.maximum(count, 1)  # noqa: E731
            new_n = moved_normals(self.vn_xyz, mean(before), mean(after))
            for i in np.flatnonzero((new_n != self.vn_xyz).any(axis=1)).tolist():
                lines[self.vn_line[i]] = _replace_xyz(lines[self.vn_line[i]], b"vn", new_n[i], "%.6f")
        _relocate_libraries(lines, self.path, path)
        atomic_write_bytes(path, b"".join(lines), force=force)
        return [path]


def _relocate_libraries(lines: list[bytes], source: str, target: str) -> None:
    """Point the ``mtllib`` lines from ``target``'s folder to the source's material libraries, so that
    an OBJ written elsewhere still finds them (nothing changes when both are in one folder)."""
    src_dir, dst_dir = (os.path.dirname(os.path.abspath(p)) for p in (source, target))
    if src_dir == dst_dir:
        return
    for i, line in enumerate(lines):
        parts = line.split()
        if parts[:1] == [b"mtllib"] and len(parts) > 1:
            names = [
                os.path.relpath(os.path.join(src_dir, n.decode("utf-8", "replace")), dst_dir).replace(os.sep, "/")
                for n in parts[1:]
            ]
            lines[i] = ("mtllib " + " ".join(names)).encode("utf-8") + line[len(line.rstrip(b"\r\n")) :]


def _replace_xyz(line: bytes, head: bytes, xyz: np.ndarray, fmt: str) -> bytes:
    """The line ``head x y z [rest]`` with x, y, z replaced, its other numbers and ending kept."""
    body = line.rstrip(b"\r\n")
    rest = body.split()[4:]
    text = head + b" " + (" ".join([fmt] * 3) % tuple(xyz.tolist())).encode("ascii")
    return b" ".join([text, *rest]) + line[len(body) :]


def _numbers(lines: list[bytes], rows: list[int], first: int, take: int, what: str, path: str) -> np.ndarray:
    """(len(rows), take) float64: the numbers ``first .. first+take`` of each listed line."""
    if not rows:
        return np.zeros((0, take))
    parts = [lines[r].split(None, 1) for r in rows]
    block = b"\n".join(p[1].strip() if len(p) > 1 else b"" for p in parts)
    count = _tokens_per_line(block, len(rows)) if block.strip() else np.zeros(len(rows), np.int64)
    if (count < first + take).any():
        bad = rows[int(np.argmax(count < first + take))] + 1
        raise MeshError(f"{path}: line {bad} has fewer than {take} numbers in a {what} line; repair the file")
    tok = np.array(block.split())
    at = (np.cumsum(count) - count)[:, None] + first + np.arange(take)
    try:
        out = tok[at].astype(np.float64)
    except ValueError:
        raise MeshError(f"{path}: a {what} line holds something that is not a number; repair the file") from None
    if not np.isfinite(out).all():
        raise MeshError(f"{path} has non-finite (NaN/inf) numbers in {what} lines; repair the mesh")
    return out


def read_obj_scene(path: str) -> ObjScene | None:
    """The OBJ file's objects, or None when it holds one object (``pmwm.read_mesh`` reads it as one mesh).
    MeshError naming the line on anything malformed."""
    with open(path, "rb") as fh:
        data = fh.read()
    if len(_CUT_LINE.findall(data)) < 2:  # one object at most: no need to read it line by line
        return None
    lines = data.splitlines(keepends=True)
    heads = np.array([ln.split(None, 1)[0] if ln.strip() else b"" for ln in lines] or [b""])
    cut = b"o" if (heads == b"o").any() else b"g"
    cuts = np.flatnonzero(heads == cut)
    if len(cuts) < 2:
        return None
    v_line, vn_line, f_line = (np.flatnonzero(heads == h) for h in (b"v", b"vn", b"f"))
    if not len(f_line):
        return None
    v_xyz = _numbers(lines, v_line.tolist(), 0, 3, "v", path)
    vn_xyz = _numbers(lines, vn_line.tolist(), 0, 3, "vn", path)

    # the corners: v and vn numbers of each token "v", "v/vt", "v//vn", "v/vt/vn"
    block = b"\n".join(
        lines[r].split(None, 1)[1].strip() if len(lines[r].split(None, 1)) > 1 else b"-" for r in f_line.tolist()
    )
    count = _tokens_per_line(block, len(f_line))
    tok = np.array(block.split())
    first = np.char.partition(tok, b"/")
    third = np.char.partition(first[:, 2], b"/")[:, 2]
    try:
        cv = first[:, 0].astype(np.int64)
        cn = np.where(third == b"", b"0", third).astype(np.int64)
    except ValueError:
        raise MeshError(f"{path}: a face line holds something that is not a vertex number; repair the file") from None
    line_of_corner = np.repeat(f_line, count)
    cv = np.where(cv < 0, np.searchsorted(v_line, line_of_corner) + cv, cv - 1)  # negative: relative
    cn = np.where(cn < 0, np.searchsorted(vn_line, line_of_corner) + cn, cn - 1)
    if (count < 3).any():
        bad = int(f_line[np.argmax(count < 3)]) + 1
        raise MeshError(f"{path}: line {bad} is a face of fewer than 3 vertices; repair the file")
    if len(cv) and (cv.min() < 0 or cv.max() >= len(v_xyz)):
        raise MeshError(f"{path} has faces that reference missing vertices; repair the mesh")
    if (cn >= len(vn_xyz)).any() or (cn < -1).any():
        raise MeshError(f"{path} has faces that reference missing normals; repair the file")

    # triangle fans over the corners, and each face's object
    start = np.cumsum(count) - count
    ntri = count - 2
    tri_face = np.repeat(np.arange(len(count)), ntri)
    j = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    s = start[tri_face]
    tris = cv[np.stack([s, s + j, s + j + 1], axis=1)]
    group = np.searchsorted(cuts, f_line, side="right") - 1  # -1: faces before the first o/g line
    names = [
        lines[c].split(None, 1)[1].strip().decode("utf-8", "replace")
        if len(lines[c].split(None, 1)) > 1
        else f"{cut.decode()} {k}"
        for k, c in enumerate(cuts.tolist())
    ]
    objects, rows = _objects(path, v_xyz, tris, group[tri_face], np.repeat(group, count), cv, names, cut == b"o")
    if len(objects) < 2:
        return None
    return ObjScene(
        path, lines, objects, rows, v_line, v_xyz, vn_line, vn_xyz, cv, cn, [w for o in objects for w in o.warnings]
    )


def _objects(
    path, v_xyz, tris, tri_group, corner_group, cv, names, explicit: bool
) -> tuple[list[SceneObject], list[np.ndarray]]:
    """The objects: groups (index into ``names``, -1 for faces before any) joined where they share
    vertices; each with its own vertices (sorted v numbers) and fan triangles. ``explicit``: the groups
    are ``o`` objects, each of which must have faces (``g`` groups without faces are common and kept)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = corner_group + 1  # 0: before the first o/g line
    if explicit:
        empty = sorted(set(range(1, len(names) + 1)) - set(np.unique(g).tolist()))
        if empty:
            raise MeshError(
                f"{path}: object {names[empty[0] - 1]!r} has no face (an empty object); delete it or give it faces"
            )
    n_groups = len(names) + 1
    owner = np.full(len(v_xyz), n_groups, np.int64)
    np.minimum.at(owner, cv, g)
    graph = coo_matrix((np.ones(len(g)), (g, owner[cv])), shape=(n_groups, n_groups + 1)).tocsr()[:, :n_groups]
    _, label = connected_components(graph, directed=False)
    used = np.unique(g)
    objects, rows, seen = [], [], set()
    all_names = ["(before any object)", *names]
    for lab in np.unique(label[used]).tolist():
        members = [k for k in used.tolist() if label[k] == lab]
        name = "+".join(all_names[k] for k in members)
        if name in seen:
            name = f"{name} #{len(objects)}"
        seen.add(name)
        mine = np.isin(tri_group + 1, members)
        local = np.unique(tris[mine])
        faces = np.searchsorted(local, tris[mine])
        objects.append(canonical_object(name, v_xyz[local], faces, f"{path}: object {name!r}"))
        rows.append(local)
    return objects, rows
