"""glTF 2.0 and GLB scenes, marked in place: the mesh data (POSITION, NORMAL) edited in the file's own
buffers, every other byte kept.

Why in place: a glTF asset holds far more than triangles (nodes and their hierarchy, transforms,
materials, textures and images, UVs, vertex colours, skins, morph targets, extras); a re-export
through a mesh library keeps what that library understands. Here pygltflib reads the document, the
buffers are patched where the positions and normals lie (interleaved or not), and the JSON is written
back with only the POSITION accessors' ``min``/``max`` changed (and, for a .gltf, the URI of a buffer
that moved). The GLB container is rebuilt around the same chunks.

Each glTF mesh is one object (its triangle primitives together, shared positions welded); a mesh
used by several nodes is one object, marked once, in its own frame (the node transforms are
unchanged). Skinned and morphed meshes are marked at rest: joints, weights and morph-target deltas
are kept as they are. Refused with one line (``MeshError``): Draco or meshopt compression, quantized
or sparse positions, a buffer that is missing, a mesh with no primitive or no triangle, a scene
without a mesh.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshError
from .canonical import SceneObject, canonical_object, moved_normals

__all__ = ["GltfScene", "read_gltf"]

_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = b"glTF", 0x4E4F534A, 0x004E4942
_COMPONENT = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_COMPRESSION = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression")
_TRIANGLES = 4


@dataclass
class _Buffer:
    """One glTF buffer: its bytes (patched in place) and where they live: "glb" (the BIN chunk),
    "data" (a data: URI in the JSON) or "file" (an external file, ``path``)."""

    data: bytearray
    kind: str
    path: str = ""
    changed: bool = False


@dataclass
class GltfScene:
    """A glTF or GLB file as read: its objects (one per mesh with triangles) for the schemes, and what
    writing it back needs. ``objects[i]`` is ``doc["meshes"][i]`` (every mesh is an object)."""

    path: str
    doc: dict  # the JSON document as read (written back with min/max and moved URIs changed)
    buffers: list
    objects: list[SceneObject]
    glb_tail: bytes = b""  # chunks after BIN in a GLB, kept verbatim
    warnings: list[str] = field(default_factory=list)
    # per object: [(POSITION accessor, its NORMAL accessor or None, the object's file vertices it holds)]
    _parts: list = field(default_factory=list, repr=False)

    def write(self, path: str, marked: list[np.ndarray], *, force: bool = False) -> list[str]:
        """Write the scene with each object's positions replaced by ``marked[i]`` ((n_i, 3) float64
        canonical positions of ``objects[i]``) and its normals moved with them; returns the files
        written (a .gltf with external buffers: the .gltf and a ``<name>.bin`` per changed buffer).
        Atomic per file; on failure nothing written is left."""
        from ..atomic import atomic_write_bytes

        doc = json.loads(json.dumps(self.doc))
        buffers = [_Buffer(bytearray(b.data), b.kind, b.path) for b in self.buffers]
        for obj, parts, new in zip(self.objects, self._parts, marked):
            self._patch(doc, buffers, obj, parts, np.asarray(new, np.float64))
        out_ext = os.path.splitext(path)[1].lower()
        written: list[str] = []
        try:
            _relocate_uris(doc, self.path, path)
            if out_ext == ".glb":
                data = self._glb_bytes(doc, buffers)
            else:
                stem = os.path.splitext(os.path.basename(path))[0]
                for i, b in enumerate(buffers):
                    if b.kind == "data":
                        doc["buffers"][i]["uri"] = _data_uri(doc["buffers"][i]["uri"], b.data)
                    elif b.kind == "file" and b.changed:
                        name = (
                            f"{stem}.bin"
                            if sum(x.changed and x.kind == "file" for x in buffers) == 1
                            else f"{stem}_{i}.bin"
                        )
                        target = os.path.join(os.path.dirname(os.path.abspath(path)), name)
                        if any(x.path and os.path.realpath(x.path) == os.path.realpath(target) for x in buffers):
                            raise MeshError(
                                f"{target} is a buffer of {self.path}; pmwm never overwrites its "
                                "input: give the marked scene another name"
                            )
                        atomic_write_bytes(target, bytes(b.data), force=force)
                        written.append(target)
                        doc["buffers"][i]["uri"] = name
                    elif b.kind == "glb":
                        raise MeshError(f"{self.path} is a GLB; write the marked scene as .glb")
                data = (json.dumps(doc, indent=2, ensure_ascii=False) + "\n").encode("utf-8")
            atomic_write_bytes(path, data, force=force)
            written.append(path)
        except BaseException:
            for p in written:
                try:
                    os.remove(p)
                except OSError:
                    pass
            raise
        return written

    def _patch(self, doc: dict, buffers: list, obj: SceneObject, parts: list, new: np.ndarray) -> None:
        if new.shape != obj.vertices.shape:
            raise MeshError(f"object {obj.name!r}: {len(new)} marked vertices for {len(obj.vertices)}")
        src_new = new[obj.source_to_canonical].astype("<f4")
        if any(nrm is not None for _, nrm, _ in parts):
            old_n, new_n = obj.normals_before(), obj.normals_after(new)
        for pos_acc, nrm_acc, rows in parts:
            view = _view(doc, buffers, pos_acc, writable=True)
            view[...] = src_new[rows]
            acc = doc["accessors"][pos_acc]
            acc["min"], acc["max"] = src_new[rows].min(0).tolist(), src_new[rows].max(0).tolist()
            buffers[doc["bufferViews"][acc["bufferView"]]["buffer"]].changed = True
            if nrm_acc is not None:
                nview = _view(doc, buffers, nrm_acc, writable=True)
                canon = obj.source_to_canonical[rows]
                nview[...] = moved_normals(np.asarray(nview, np.float64), old_n[canon], new_n[canon]).astype("<f4")

    def _glb_bytes(self, doc: dict, buffers: list) -> bytes:
        if any(b.kind == "file" and b.changed for b in buffers):
            raise MeshError(f"{self.path} keeps its buffers in separate files; write the marked scene as .gltf")
        for i, b in enumerate(buffers):
            if b.kind == "data":
                doc["buffers"][i]["uri"] = _data_uri(doc["buffers"][i]["uri"], b.data)
        text = json.dumps(doc, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
        text += b" " * (-len(text) % 4)
        chunks = [struct.pack("<II", len(text), _JSON_CHUNK), text]
        glb = [b for b in buffers if b.kind == "glb"]
        if glb:
            body = bytes(glb[0].data) + b"\0" * (-len(glb[0].data) % 4)
            chunks += [struct.pack("<II", len(body), _BIN_CHUNK), body]
        chunks.append(self.glb_tail)
        size = 12 + sum(len(c) for c in chunks)
        return b"".join([_GLB_MAGIC, struct.pack("<II", 2, size), *chunks])


# --------------------------------------------------------------------------- reading


def read_gltf(path: str) -> GltfScene:
    """Read a .glb or .gltf file into its objects (MeshError naming the problem on anything refused)."""
    try:
        import pygltflib
    except ImportError:
        raise MeshError(f"reading the scene {path} needs pygltflib: pip install pygltflib") from None

    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise MeshError(f"cannot read {path}: {exc.strerror or exc}") from None
    text, bin_chunk, tail = _split_glb(raw, path) if raw[:4] == _GLB_MAGIC else (raw, None, b"")
    try:
        doc = json.loads(text.decode("utf-8"))
        gltf = pygltflib.GLTF2.from_json(json.dumps(doc))
    except Exception as exc:  # not JSON, or not a glTF document pygltflib understands
        raise MeshError(f"cannot read {path} as glTF ({type(exc).__name__}: {str(exc)[:120]})") from None
    required = set(doc.get("extensionsRequired") or []) | set(doc.get("extensionsUsed") or [])
    for name in _COMPRESSION:
        if name in required:
            raise MeshError(
                f"{path} is compressed with {name}; pmwm marks uncompressed glTF only: "
                "export it without mesh compression and mark that"
            )
    buffers = [_load_buffer(b, i, path, bin_chunk) for i, b in enumerate(gltf.buffers or [])]
    scene = GltfScene(path=path, doc=doc, buffers=buffers, objects=[], glb_tail=tail)
    names = _mesh_names(gltf)
    skinned = {node.mesh for node in gltf.nodes or [] if node.skin is not None}
    for m, mesh in enumerate(gltf.meshes or []):
        obj, parts = _read_mesh(doc, gltf, buffers, m, mesh, names[m], path)
        if m in skinned:
            obj.warnings.append(f"{obj.name}: skinned; marked in its bind pose, joints and weights kept")
        for other, their in zip(scene.objects, scene._parts):
            if {pos for pos, _, _ in parts} & {pos for pos, _, _ in their}:
                raise MeshError(
                    f"{path}: meshes {other.name!r} and {obj.name!r} share their positions; pmwm "
                    "cannot mark them apart: make them one mesh, or give each its own data"
                )
        scene.objects.append(obj)
        scene._parts.append(parts)
    if not scene.objects:
        raise MeshError(f"{path} holds no mesh (its nodes carry no geometry); nothing to mark")
    scene.warnings = [w for obj in scene.objects for w in obj.warnings]
    return scene


def _split_glb(raw: bytes, path: str) -> tuple[bytes, bytes | None, bytes]:
    """(JSON text, BIN chunk or None, the chunks after them verbatim) of a GLB file."""
    if len(raw) < 20:
        raise MeshError(f"{path} is a truncated GLB file")
    version, length = struct.unpack_from("<II", raw, 4)
    if version != 2 or length > len(raw):
        raise MeshError(f"{path} is not a GLB 2.0 file (version {version}, {length} of {len(raw)} bytes)")
    n, kind = struct.unpack_from("<II", raw, 12)
    if kind != _JSON_CHUNK or 20 + n > length:
        raise MeshError(f"{path} is a damaged GLB file (no JSON chunk first)")
    text, at, bin_chunk = raw[20 : 20 + n], 20 + n, None
    if at + 8 <= length:
        n, kind = struct.unpack_from("<II", raw, at)
        if kind == _BIN_CHUNK:
            if at + 8 + n > length:
                raise MeshError(f"{path} is a truncated GLB file (its binary chunk is cut)")
            bin_chunk, at = raw[at + 8 : at + 8 + n], at + 8 + n
    return text, bin_chunk, raw[at:length]


def _load_buffer(buffer, index: int, path: str, bin_chunk: bytes | None) -> _Buffer:
    uri = buffer.uri
    if uri is None:
        if bin_chunk is None:
            raise MeshError(f"{path}: buffer {index} has no data (no GLB binary chunk, no URI)")
        if len(bin_chunk) < buffer.byteLength:
            raise MeshError(f"{path} is a truncated GLB file (its binary chunk is shorter than its buffer)")
        return _Buffer(bytearray(bin_chunk), "glb")  # (whole: its padding written back as it was)
    if uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1], validate=True)
        except (ValueError, IndexError):
            raise MeshError(f"{path}: buffer {index} has a damaged data URI") from None
        return _Buffer(bytearray(data), "data")
    from urllib.parse import unquote

    file = os.path.join(os.path.dirname(os.path.abspath(path)), unquote(uri))
    if not os.path.isfile(file):
        raise MeshError(f"{path}: its buffer file {uri} is missing; put it next to the .gltf (or export a .glb)")
    with open(file, "rb") as fh:
        data = fh.read()
    if len(data) < buffer.byteLength:
        raise MeshError(
            f"{path}: its buffer file {uri} is shorter ({len(data)} bytes) than the "
            f"{buffer.byteLength} bytes it should hold"
        )
    return _Buffer(bytearray(data), "file", file)


def _mesh_names(gltf) -> list[str]:
    """A unique name per mesh: the name of the one node using it (what an editor calls the object),
    else the mesh's own, else the first node's using it, else "mesh <i>"."""
    by_node: dict[int, list[str]] = {}
    for node in gltf.nodes or []:
        if node.mesh is not None:
            by_node.setdefault(node.mesh, []).append(node.name or "")
    out, seen = [], set()
    for m, mesh in enumerate(gltf.meshes or []):
        nodes = by_node.get(m, [])
        name = (
            nodes[0] if len(nodes) == 1 and nodes[0] else mesh.name or next((n for n in nodes if n), "") or f"mesh {m}"
        )
        if name in seen:
            name = f"{name} #{m}"
        seen.add(name)
        out.append(name)
    return out


def _read_mesh(doc, gltf, buffers, m: int, mesh, name: str, path: str):
    """The object of one glTF mesh and its parts: (POSITION accessor, NORMAL accessor or None, rows of
    the object's source vertices that accessor holds)."""
    where = f"{path}: mesh {name!r}"
    if not mesh.primitives:
        raise MeshError(f"{where} has no primitive (an empty mesh node); delete it or give it geometry")
    offsets: dict[int, int] = {}
    blocks, faces, normals = [], [], {}
    for prim in mesh.primitives:
        if any(k in (prim.extensions or {}) for k in _COMPRESSION):
            raise MeshError(f"{where} is Draco/meshopt-compressed; export the scene without mesh compression")
        pos = prim.attributes.POSITION
        if pos is None:
            raise MeshError(f"{where} has a primitive without positions (an empty node); repair or delete it")
        mode = _TRIANGLES if prim.mode is None else prim.mode
        if pos not in offsets:
            v = np.asarray(_view(doc, buffers, pos, where=where, position=True), np.float64)
            offsets[pos] = sum(len(b) for b in blocks)
            blocks.append(v)
        if prim.attributes.NORMAL is not None:
            if normals.setdefault(pos, prim.attributes.NORMAL) != prim.attributes.NORMAL:
                raise MeshError(f"{where} pairs one position array with two normal arrays; pmwm cannot move both")
            _view(doc, buffers, prim.attributes.NORMAL, where=where)
        if mode != _TRIANGLES:
            continue  # points and lines: their positions move with the triangles sharing them, if any
        count = len(blocks[list(offsets).index(pos)])
        if prim.indices is None:
            idx = np.arange(count, dtype=np.int64)
        else:
            idx = np.asarray(_view(doc, buffers, prim.indices, where=where), np.int64).ravel()
        if len(idx) % 3 or (len(idx) and (idx.min() < 0 or idx.max() >= count)):
            raise MeshError(f"{where} has triangle indices outside its {count} vertices; repair the file")
        faces.append(idx.reshape(-1, 3) + offsets[pos])
    if not faces or not sum(len(f) for f in faces):
        raise MeshError(f"{where} has no triangle (points or lines only); delete it or triangulate it")
    V = np.concatenate(blocks)
    obj = canonical_object(name, V, np.concatenate(faces), where)
    parts = []
    for pos, start in offsets.items():
        rows = np.arange(start, start + len(blocks[list(offsets).index(pos)]))
        parts.append((pos, normals.get(pos), rows))
    if mesh.weights or any(p.targets for p in mesh.primitives):
        obj.warnings.append(f"{name}: morph targets kept as they are; marked at rest")  # (deltas from rest)
    return obj, parts


def _view(
    doc: dict, buffers: list, index: int, *, where: str = "", position: bool = False, writable: bool = False
) -> np.ndarray:
    """The accessor's elements as an (count, width) array viewing its buffer (strided; writes go to the
    buffer). MeshError on a sparse, quantized (POSITION) or out-of-range accessor."""
    try:
        acc = doc["accessors"][index]
        if acc.get("sparse") is not None:
            raise MeshError(f"{where} has sparse accessor {index}; export it without sparse storage")
        if position and (acc.get("componentType") != 5126 or acc.get("type") != "VEC3"):
            raise MeshError(
                f"{where} stores quantized positions (KHR_mesh_quantization); export float positions and mark that"
            )
        if "bufferView" not in acc:
            raise MeshError(f"{where}: accessor {index} has no data (no buffer view)")
        bv = doc["bufferViews"][acc["bufferView"]]
        buf = buffers[bv["buffer"]]
        dtype = np.dtype(_COMPONENT[acc["componentType"]])
        width, count = _WIDTH[acc["type"]], int(acc["count"])
    except (KeyError, IndexError, TypeError):
        raise MeshError(f"{where}: accessor {index} is damaged; repair the file") from None
    item = dtype.itemsize * width
    stride = bv.get("byteStride") or item
    start = bv.get("byteOffset", 0) + acc.get("byteOffset", 0)
    end = start + (count - 1) * stride + item if count else start
    if end > bv.get("byteOffset", 0) + bv["byteLength"] or end > len(buf.data):
        raise MeshError(f"{where}: accessor {index} reaches past its buffer; the file is truncated")
    arr = np.ndarray((count, width), dtype, buffer=buf.data, offset=start, strides=(stride, dtype.itemsize))
    if position and not np.isfinite(arr).all():
        raise MeshError(f"{where} has non-finite (NaN/inf) positions; repair the mesh")
    return arr if writable else arr.copy()


def _data_uri(old: str, data: bytearray) -> str:
    return old.split(",", 1)[0] + "," + base64.b64encode(bytes(data)).decode("ascii")


def _relocate_uris(doc: dict, source: str, target: str) -> None:
    """Point the relative URIs of external files (images, buffers) from ``target``'s folder to the
    source's files, so that a scene written elsewhere still finds them."""
    from urllib.parse import quote, unquote

    src_dir = os.path.dirname(os.path.abspath(source))
    dst_dir = os.path.dirname(os.path.abspath(target))
    if src_dir == dst_dir:
        return
    for kind in ("images", "buffers"):
        for item in doc.get(kind, []):
            uri = item.get("uri")
            if uri and not uri.startswith("data:") and "://" not in uri:
                rel = os.path.relpath(os.path.join(src_dir, unquote(uri)), dst_dir).replace(os.sep, "/")
                item["uri"] = quote(rel)
