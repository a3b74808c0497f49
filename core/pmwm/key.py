"""The watermark key: everything extraction needs, as a versioned JSON file.

The key is a secret. It holds the secret from which every random choice derives
(carrier choice, the keyed bit scrambling), the payload bits, and the carriers:
their index in the marked mesh, their index in the progressive mesh and their
marked position (for re-synchronising a re-ordered or cropped copy), and a fingerprint of the
marked mesh's connectivity (a copy with the same faces keeps the vertex order, whatever the noise).
A scheme keeps its own data under ``extra``, read into a typed object (``data``) by that scheme
(``pmwm.schemes``) when the key file is read. Whoever
holds it can read the mark, and could locate and erase it; it does not let anyone
mark another mesh in your name without your mesh, and it is never stored in the
marked mesh, the .pmwm file or the .blend.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .errors import KeyFileError
from .atomic import atomic_write_bytes

KEY_FORMAT = "pmwm-key"
KEY_VERSION = 1


@dataclass
class WatermarkKey:
    """What verification needs; see the module docstring for what it reveals."""

    secret: str  # 64 hex digits
    bits: np.ndarray  # (k,) uint8 payload bits
    payload_kind: str  # "text" | "bits" | "random"
    strength: float
    carrier_index: np.ndarray  # (k,) int64 index in the marked mesh (input order)
    carrier_pm_index: np.ndarray  # (k,) int64 index in the progressive mesh order
    carrier_position: np.ndarray  # (k, 3) float64 marked position
    n_vertices: int
    n_faces: int
    mean_edge: float  # mean edge length of the marked mesh (position tolerance scale)
    bbox_diagonal: float
    scheme: str = "paper"
    extra: dict = field(default_factory=dict)  # the scheme's data as read from JSON (written from ``data``)
    faces_fingerprint: str = ""  # face_fingerprint of the marked mesh's faces ("" in older keys)
    pm_faces_fingerprint: str = ""  # the same in the progressive mesh's vertex order
    data: object = field(default=None, repr=False, compare=False)  # the scheme's typed data

    @property
    def n_bits(self) -> int:
        return len(self.bits)

    def stream(self, label: str, n: int) -> np.ndarray:
        """A keyed pseudo-random bit sequence (n,) uint8 for one purpose (``keyed_bits``)."""
        return keyed_bits(self.secret, label, n)

    def to_json(self) -> str:
        doc = {
            "format": KEY_FORMAT,
            "version": KEY_VERSION,
            "scheme": self.scheme,
            "secret": self.secret,
            "payload_kind": self.payload_kind,
            "bits": "".join(map(str, self.bits.tolist())),
            "strength": self.strength,
            "mesh": {
                "n_vertices": self.n_vertices,
                "n_faces": self.n_faces,
                "mean_edge": self.mean_edge,
                "bbox_diagonal": self.bbox_diagonal,
                "faces_sha256": self.faces_fingerprint,
                "pm_faces_sha256": self.pm_faces_fingerprint,
            },
            "carriers": [
                [int(i), int(j), *map(float, p)]
                for i, j, p in zip(self.carrier_index, self.carrier_pm_index, self.carrier_position)
            ],
            "extra": self.data.to_extra() if hasattr(self.data, "to_extra") else self.extra,
        }
        return json_text(doc)

    @classmethod
    def from_json(cls, text: str, name: str = "the key") -> "WatermarkKey":
        try:
            doc = json.loads(text)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise KeyFileError(
                f"{name} is not a pmwm key (not JSON: {exc.msg if hasattr(exc, 'msg') else exc})"
            ) from None
        except RecursionError:
            raise KeyFileError(f"{name} is not a pmwm key (JSON nested too deeply)") from None
        if not isinstance(doc, dict) or doc.get("format") != KEY_FORMAT:
            raise KeyFileError(f'{name} is not a pmwm key file (no "format": "{KEY_FORMAT}")')
        version = doc.get("version")
        if not isinstance(version, int) or version > KEY_VERSION or version < 1:
            raise KeyFileError(f"{name} is key version {version}; this pmwm reads version {KEY_VERSION}: upgrade pmwm")
        try:
            mesh = doc["mesh"]
            bits = np.array([int(c) for c in doc["bits"]], dtype=np.uint8)
            car = np.asarray(doc["carriers"], dtype=np.float64).reshape(-1, 5)
            idx = car[:, :2]
            if not (np.all(np.isfinite(idx)) and np.all(idx == np.round(idx)) and np.all(np.abs(idx) < 2**53)):
                raise ValueError("carrier indices are not integers")
            key = cls(
                secret=str(doc["secret"]),
                bits=bits,
                payload_kind=str(doc["payload_kind"]),
                strength=float(doc["strength"]),
                carrier_index=car[:, 0].astype(np.int64),
                carrier_pm_index=car[:, 1].astype(np.int64),
                carrier_position=car[:, 2:5].copy(),
                n_vertices=int(mesh["n_vertices"]),
                n_faces=int(mesh["n_faces"]),
                mean_edge=float(mesh["mean_edge"]),
                bbox_diagonal=float(mesh["bbox_diagonal"]),
                scheme=str(doc.get("scheme", "paper")),
                extra=dict(doc.get("extra", {})),
                faces_fingerprint=str(mesh.get("faces_sha256", "")),
                pm_faces_fingerprint=str(mesh.get("pm_faces_sha256", "")),
            )
        except KeyError as exc:
            raise KeyFileError(f"{name} lacks the field {exc.args[0]!r}; it is damaged or not a pmwm key") from None
        except (TypeError, ValueError, OverflowError) as exc:
            raise KeyFileError(f"{name} has a malformed field ({exc}); it is damaged or not a pmwm key") from None
        key.validate(name)
        return key

    def validate(self, name: str = "the key") -> None:
        problems = []
        if len(self.secret) != 64 or any(c not in "0123456789abcdef" for c in self.secret):
            problems.append("secret is not 64 hex digits")
        if (
            self.n_bits == 0
            or len(self.carrier_index) not in (0, self.n_bits)
            or not (len(self.carrier_index) == len(self.carrier_pm_index) == len(self.carrier_position))
        ):
            problems.append("bit count and carrier count differ")
        if np.any(self.bits > 1):
            problems.append("bits are not 0/1")
        if not np.all(np.isfinite(self.carrier_position)) or np.any(np.abs(self.carrier_position) > 1e30):
            problems.append("carrier positions are not finite numbers below 1e30")
        for what, idx in (("index", self.carrier_index), ("progressive-mesh index", self.carrier_pm_index)):
            if len(idx) and (idx.min() < 0 or idx.max() >= self.n_vertices):
                problems.append(f"a carrier {what} is outside the mesh's {self.n_vertices} vertices")
        if self.n_vertices < 1 or self.n_faces < 1:
            problems.append("mesh counts are not positive")
        if self.payload_kind not in ("text", "bits", "random"):
            problems.append(f"unknown payload kind {self.payload_kind!r}")
        if not (0 < self.mean_edge < 1e30 and np.isfinite(self.bbox_diagonal)):
            problems.append("mean edge length is not positive")
        if problems:
            raise KeyFileError(f"{name} is inconsistent: {'; '.join(problems)}")


def json_text(doc: dict) -> str:
    """A key file's text: JSON, one top-level field per line (readable), each value compact. Why not
    ``indent``: json writes indented text in pure Python, about three times slower than compact text on a
    large key, and that time is the end of every ``pmwm embed`` (docs/decisions/012-numpy-hot-paths.md)."""
    fields = (f"{json.dumps(k)}:{json.dumps(v, separators=(',', ':'))}" for k, v in doc.items())
    return "{\n" + ",\n".join(fields) + "\n}\n"


def derive_seed(secret: str, label: str) -> int:
    """A 64-bit seed for one purpose, derived from the key secret."""
    return int.from_bytes(hashlib.sha256(f"{secret}:{label}".encode()).digest()[:8], "little")


def keyed_bits(secret: str, label: str, n: int) -> np.ndarray:
    """A pseudo-random bit sequence (n,) uint8 drawn from the secret for one purpose (``label``)."""
    return np.random.default_rng(derive_seed(secret, label)).integers(0, 2, n).astype(np.uint8)


def make_secret(seed: Optional[int]) -> str:
    """The key secret: derived from ``seed`` when given (reproducible), else fresh randomness."""
    if seed is None:
        return os.urandom(32).hex()
    return hashlib.sha256(f"pmwm-seed:{int(seed)}".encode()).hexdigest()


def write_key(path, key: WatermarkKey, *, overwrite: bool = False) -> None:
    """Write the key atomically, readable by its owner only (mode 0600)."""
    atomic_write_bytes(path, key.to_json().encode(), force=overwrite, mode=0o600)


def face_fingerprint(faces: np.ndarray) -> str:
    """SHA-256 (hex) of a face array, faces : (m, 3) int, independent of the order of the faces and
    of where each triangle's vertex list starts (its orientation counts): equal for two meshes with
    the same connectivity over the same vertex numbering."""
    F = np.asarray(faces, np.int64).reshape(-1, 3)
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    # each row rotated to start at its first smallest entry (argmin's): a, b or c
    at_a = (a <= b) & (a <= c)
    at_b = ~at_a & (b <= c)
    G = np.stack(
        [
            np.where(at_a, a, np.where(at_b, b, c)),
            np.where(at_a, b, np.where(at_b, c, a)),
            np.where(at_a, c, np.where(at_b, a, b)),
        ],
        axis=1,
    )
    if len(G) and F.min() >= 0 and F.max() < 1 << 21:  # rows packed in one int64: the same order, one sort
        packed = np.sort((G[:, 0] << 42) | (G[:, 1] << 21) | G[:, 2])  # equal keys are equal rows
        G = np.empty((len(packed), 3), "<i8")
        G[:, 0] = packed >> 42
        G[:, 1] = (packed >> 21) & ((1 << 21) - 1)
        G[:, 2] = packed & ((1 << 21) - 1)
    else:
        G = np.ascontiguousarray(G[np.lexsort(G.T[::-1])], dtype="<i8")
    return hashlib.sha256(G).hexdigest()  # (the rows' bytes, little-endian int64)


def mesh_sha256(vertices, faces, float_type: str = "<f4") -> str:
    """Hex SHA-256 of mesh data: the vertex positions (n, 3) as little-endian ``float_type`` ("<f4",
    what a suspect such as a Blender object holds; "<f8" for canonical float64 arrays), then the
    triangles (m, 3) as little-endian int64."""
    h = hashlib.sha256(np.ascontiguousarray(vertices, float_type).tobytes())
    h.update(np.ascontiguousarray(faces, "<i8").tobytes())
    return h.hexdigest()


def read_key_json(path) -> WatermarkKey:
    """Read a key file and check its generic part (``pmwm.read_key`` also reads the scheme's data);
    KeyFileError on anything wrong."""
    return WatermarkKey.from_json(read_key_text(path), os.fspath(path))


def read_key_text(path) -> str:
    """The text of a key file (any pmwm key format), KeyFileError when it is missing, unreadable,
    too large or not UTF-8."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise KeyFileError(f"{path} is a directory, not a key file")
    try:
        with open(path, "rb") as fh:
            data = fh.read(16 * 1024 * 1024 + 1)
    except FileNotFoundError:
        raise KeyFileError(f"key file {path} does not exist") from None
    except OSError as exc:
        raise KeyFileError(f"cannot read key file {path}: {exc.strerror or exc}") from None
    if len(data) > 16 * 1024 * 1024:
        raise KeyFileError(f"{path} is too large to be a pmwm key")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise KeyFileError(f"{path} is not a pmwm key (not UTF-8 text)") from None


def scene_objects(doc: dict, what: str) -> list[tuple[str, dict]]:
    """The (object name, key document) pairs of a scene key file's ``objects`` list, each checked to be a
    named JSON object; a KeyFileError naming ``what`` (the file, and its kind) when the list is missing,
    empty or malformed."""
    objects = doc.get("objects")
    if not (
        isinstance(objects, list)
        and objects
        and all(
            isinstance(o, dict) and isinstance(o.get("name"), str) and isinstance(o.get("key"), dict) for o in objects
        )
    ):
        raise KeyFileError(f"{what} is damaged (its objects are missing or malformed)")
    return [(o["name"], o["key"]) for o in objects]
