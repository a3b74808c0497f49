"""Fingerprinting a scene: every object of an asset of several objects (``pmwm.scene``) analysed as an asset
of its own, one copy per recipient written as the scene file with every object marked with that
recipient's codewords (everything else in the file kept), and tracing over objects.

Key file (``"format": "pmwm-scene-fingerprint-key"``, mode 0600): the objects' names and their
fingerprinting keys (``FingerprintKey``), each object's secret drawn from one master secret. Registry
(``registry.json`` beside the copies, ``"format": "pmwm-scene-fingerprint-registry"``): one ``Registry`` per
object (the recipients' codewords for that object's sites), each recipient's files and their SHA-256 in
every one. Resumable as for one mesh: a recipient whose files are registered and on disk intact is skipped.

Tracing (``trace_objects``) reads every suspect object (the scene, or one object taken out alone) with the
object keys of the same connectivity (all of them when none matches; the choice looks at the suspect's
faces, never at a mark) and names the recipients whose corrected p-value (``codes.accuse``), times the
object/key pairs tried, is below the threshold.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np

from ..atomic import atomic_write_bytes, file_sha256
from ..errors import KeyFileError, PmwmError
from ..key import derive_seed, face_fingerprint, json_text, make_secret, mesh_sha256, scene_objects
from .asset import FingerprintRun, _on_disk, clean_temporaries
from .codes import Accusation, accuse, pack_codeword
from .copies import FingerprintOptions, analyse_asset
from .registry import KEY_FORMAT, FingerprintKey, Registry, RegistryEntry, RegistryError, _read_json
from .trace import TraceResult, site_readings

__all__ = [
    "SCENE_KEY_FORMAT",
    "SCENE_REGISTRY_FORMAT",
    "SceneFingerprintKey",
    "SceneRegistry",
    "SceneAnalysis",
    "read_any_fingerprint_key",
    "read_scene_registry",
    "prepare_scene",
    "open_scene_registry",
    "scene_pending",
    "add_copy",
    "fingerprint_scene",
    "trace_objects",
]

SCENE_KEY_FORMAT, SCENE_REGISTRY_FORMAT, VERSION = "pmwm-scene-fingerprint-key", "pmwm-scene-fingerprint-registry", 1
REGISTRY_NAME = "registry.json"


@dataclass
class SceneFingerprintKey:
    """The fingerprinting keys of a scene: ``keys[i]`` is the key of the object called ``names[i]``."""

    names: list
    keys: list

    def to_json(self) -> str:
        return json_text(
            {
                "format": SCENE_KEY_FORMAT,
                "version": VERSION,
                "objects": [{"name": n, "key": json.loads(k.to_json())} for n, k in zip(self.names, self.keys)],
            }
        )


def read_any_fingerprint_key(path) -> "FingerprintKey | SceneFingerprintKey":
    """The fingerprinting key of one mesh or of a scene in ``path`` (KeyFileError naming the problem)."""
    name = os.fspath(path)
    doc = _read_json(path, "fingerprinting key", KeyFileError)
    if not (isinstance(doc, dict) and doc.get("format") == SCENE_KEY_FORMAT):
        return FingerprintKey.from_json(doc, name)
    if doc.get("version") != VERSION:
        raise KeyFileError(
            f"{name} is scene fingerprinting key version {doc.get('version')!r}; this pmwm reads {VERSION}"
        )
    objects = scene_objects(doc, f"the scene fingerprinting key {name}")
    if any(key.get("format") != KEY_FORMAT for _, key in objects):
        raise KeyFileError(
            f"the scene fingerprinting key {name} is damaged (an object's key is not a fingerprinting key)"
        )
    return SceneFingerprintKey(
        [n for n, _ in objects],
        [FingerprintKey.from_json(key, f"{name} (object {n!r})") for n, key in objects],
    )


@dataclass
class SceneRegistry:
    """The registries of a fingerprinted scene, one per object (``registries[i]`` of ``names[i]``)."""

    names: list
    registries: list

    @classmethod
    def for_key(cls, sfk: SceneFingerprintKey) -> "SceneRegistry":
        return cls(list(sfk.names), [Registry.for_key(fk) for fk in sfk.keys])

    def check(self, sfk: SceneFingerprintKey, name: str = "the registry") -> None:
        """RegistryError unless this registry belongs to the scene key ``sfk``."""
        if self.names != sfk.names:
            raise RegistryError(
                f"{name} names the objects {self.names}, the key {sfk.names}; give the key and "
                "registry of the same scene"
            )
        for reg, fk, obj in zip(self.registries, sfk.keys, self.names):
            reg.check(fk, f"{name} (object {obj!r})")

    def to_json(self) -> str:
        return (
            json.dumps(
                {
                    "format": SCENE_REGISTRY_FORMAT,
                    "version": VERSION,
                    "objects": [
                        {"name": n, "registry": json.loads(r.to_json())} for n, r in zip(self.names, self.registries)
                    ],
                },
                indent=0,
            )
            + "\n"
        )


def read_scene_registry(path) -> SceneRegistry:
    """Read a scene's registry (RegistryError naming the problem; a registry of one mesh is refused)."""
    name = os.fspath(path)
    doc = _read_json(path, "fingerprinting registry", RegistryError)
    if not (isinstance(doc, dict) and doc.get("format") == SCENE_REGISTRY_FORMAT) or doc.get("version") != VERSION:
        raise RegistryError(
            f"{name} is not the registry of a fingerprinted scene (give the registry.json written "
            "with the scene's copies)"
        )
    try:
        return SceneRegistry(
            [str(o["name"]) for o in doc["objects"]],
            [Registry.from_json(o["registry"], f"{name} (object {o['name']!r})") for o in doc["objects"]],
        )
    except (KeyError, TypeError) as exc:
        raise RegistryError(f"{name} lacks or garbles a field ({exc}); it is damaged") from None


def _analyses(asset, asset_path: str, key_path: str, options: Optional[FingerprintOptions]):
    """(analyses, key): with the key at ``key_path`` when it exists (checked against the scene's objects),
    else with a new one from ``options`` (each object's secret drawn from one master secret), written there."""
    objects = asset.objects
    if os.path.exists(key_path):
        sfk = read_any_fingerprint_key(key_path)
        if (
            not isinstance(sfk, SceneFingerprintKey)
            or sfk.names != [o.name for o in objects]
            or any(fk.asset_sha256 != mesh_sha256(o.vertices, o.faces, "<f8") for fk, o in zip(sfk.keys, objects))
        ):
            raise KeyFileError(
                f"{key_path} is not the fingerprinting key of the scene {asset_path}; give that "
                "scene's key, or a new --key path"
            )
        ans = []
        for fk, o in zip(sfk.keys, objects):
            opts = FingerprintOptions(fk.options.strength, fk.options.n_sites, fk.options.base_ratio)
            an = analyse_asset(o.vertices, o.faces, opts, secret=fk.key.secret, progressive=False)
            if not np.array_equal(an.key.data.origin, fk.key.data.origin):
                raise KeyFileError(
                    f"this pmwm analyses {asset_path} differently from the one that wrote {key_path}; "
                    "use the same pmwm version"
                )
            ans.append(an)
        return ans, sfk
    opts = options or FingerprintOptions()
    master = make_secret(opts.seed)
    ans = []
    for i, o in enumerate(objects):
        try:
            ans.append(
                analyse_asset(
                    o.vertices,
                    o.faces,
                    replace(opts, seed=None),
                    progressive=False,
                    secret=make_secret(derive_seed(master, f"scene-object:{i}")),
                )
            )
        except PmwmError as exc:
            raise type(exc)(f"object {o.name!r}: {exc}") from None
    sfk = SceneFingerprintKey(
        [o.name for o in objects], [FingerprintKey(an.key, an.options, an.asset_sha256) for an in ans]
    )
    atomic_write_bytes(key_path, sfk.to_json().encode(), mode=0o600)
    return ans, sfk


@dataclass
class SceneAnalysis:
    """A scene analysed for fingerprinting: the scene (``pmwm.scene`` asset) to write copies of, its
    extension, each object's analysis and the scene's key."""

    asset: object
    ext: str
    analyses: list
    key: SceneFingerprintKey

    def codewords(self, recipient: str) -> list:
        """The recipient's codeword of each object, packed (``codes.pack_codeword``)."""
        return [pack_codeword(an.codeword(recipient)) for an in self.analyses]

    def write_copy(self, folder, recipient: str) -> dict:
        """Write the recipient's copy of the scene to ``folder``/<recipient><ext> (and, for a .gltf whose
        buffers are files, its .bin), each atomically; {file name: SHA-256} of what was written."""
        marked = [an.marked(an.codeword(recipient)) for an in self.analyses]
        written = self.asset.write(os.path.join(os.fspath(folder), recipient + self.ext), marked, force=True)
        return {os.path.basename(p): file_sha256(p) for p in written}


def prepare_scene(
    asset_path, key_path, options: Optional[FingerprintOptions] = None, asset=None
) -> Optional[SceneAnalysis]:
    """The scene at ``asset_path`` (``asset``: as read already by ``pmwm.scene.read_asset``) analysed with
    the key at ``key_path`` (written when new), or None when the file holds one mesh
    (``asset.prepare_asset`` fingerprints it)."""
    from ..scene import read_asset

    asset = read_asset(asset_path) if asset is None else asset
    if asset is None or len(asset.objects) < 2:
        return None
    ans, sfk = _analyses(asset, os.fspath(asset_path), os.fspath(key_path), options)
    return SceneAnalysis(asset, os.path.splitext(os.fspath(asset_path))[1].lower(), ans, sfk)


def open_scene_registry(out_dir, sfk: SceneFingerprintKey) -> SceneRegistry:
    """The scene registry in ``out_dir`` (checked against the key), or a new one."""
    path = os.path.join(out_dir, REGISTRY_NAME)
    sreg = read_scene_registry(path) if os.path.exists(path) else SceneRegistry.for_key(sfk)
    sreg.check(sfk, path)
    return sreg


def scene_pending(sreg: SceneRegistry, out_dir, recipients, ext: str) -> list:
    """The recipients whose copy is not registered with its files on disk intact."""
    first = sreg.registries[0]
    return [
        r
        for r in recipients
        if not (
            r in first.entries
            and r + ext in first.entries[r].files
            and all(_on_disk(os.path.join(out_dir, f), sha) for f, sha in first.entries[r].files.items())
        )
    ]


def add_copy(sreg: SceneRegistry, recipient: str, codes: list, files: dict) -> None:
    """Record a recipient's codewords (one per object, packed) and files in every object's registry."""
    for reg, code in zip(sreg.registries, codes):
        entry = reg.entries.get(recipient) or RegistryEntry(code)
        entry.files.update(files)
        reg.entries[recipient] = entry


def fingerprint_scene(
    scene: SceneAnalysis, recipients, out_dir, progress: Optional[Callable[[int, int], None]] = None
) -> FingerprintRun:
    """Write the analysed scene's copies for ``recipients`` into ``out_dir`` (created): ``<recipient><ext>``
    each (the scene's own format) and registry.json (see the module docstring). ``progress(done, total)``
    after each copy."""
    if not os.path.isdir(out_dir):
        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as exc:
            raise PmwmError(f"cannot create {out_dir}: {exc.strerror or exc}") from None
    t1 = time.perf_counter()
    sreg = open_scene_registry(out_dir, scene.key)
    path = os.path.join(out_dir, REGISTRY_NAME)
    todo = scene_pending(sreg, out_dir, recipients, scene.ext)
    clean_temporaries(out_dir)
    last = time.perf_counter()
    for i, rid in enumerate(todo):
        add_copy(sreg, rid, scene.codewords(rid), scene.write_copy(out_dir, rid))
        if time.perf_counter() - last > 2.0:
            atomic_write_bytes(path, sreg.to_json().encode(), force=True)
            last = time.perf_counter()
        if progress:
            progress(i + 1, len(todo))
    atomic_write_bytes(path, sreg.to_json().encode(), force=True)
    again = set(todo)
    return FingerprintRun(todo, [r for r in recipients if r not in again], sreg, path, 0.0, time.perf_counter() - t1)


def trace_objects(objects, sfk: SceneFingerprintKey, sreg: SceneRegistry, p_threshold: float = 1e-6) -> TraceResult:
    """Trace suspect objects ([(name, vertices (n, 3), faces (m, 3))]: a scene's, or one object alone) to the
    scene's recipients: every object with the object keys of its connectivity (all when none matches), each
    recipient's best p-value times the pairs tried. ``mode`` names the pairs read."""
    sreg.check(sfk)
    plan = []
    for name, V, F in objects:
        fp = face_fingerprint(F)
        same = [i for i, fk in enumerate(sfk.keys) if fk.key.faces_fingerprint == fp]
        plan += [(name, V, F, i) for i in (same or range(len(sfk.keys)))]
    tried = len(plan)
    best: dict = {}
    read, total, modes = 0, 0, []
    ids, p_best, T_best = [], None, None
    for name, V, F, i in plan:
        ids_i, C = sreg.registries[i].codewords()
        x, mode, detail = site_readings(V, F, sfk.keys[i])
        _, T, p = accuse(x, ids_i, C, p_threshold)
        p = np.minimum(1.0, p * tried)
        read, total = read + detail.sites_read, total + detail.sites_total
        modes.append(f"{name} with the key of {sfk.names[i]} ({mode})")
        for rid, t, q in zip(ids_i, T.tolist(), p.tolist()):
            if q < p_threshold and (rid not in best or q < best[rid].p_value):
                best[rid] = Accusation(rid, float(t), float(q))
        if p_best is None or (len(p) and p.min() < p_best.min()):
            ids, p_best, T_best = ids_i, p, T
    accused = sorted(best.values(), key=lambda a: (a.p_value, -a.score))
    return TraceResult(accused, p_threshold, len(ids), "; ".join(modes), read, total, ids, T_best, p_best)
