"""One mark for a whole asset: every object of a scene marked with one key file (or pass phrase), and
read from the scene or from any object taken out of it.

The key of a scene of several objects (``SceneKey``, a "pmwm-scene-key" file) holds one key of the
chosen key-file scheme per object, named by the object; every object's secret is drawn from one master
secret (the seed's, or fresh) and every object carries the same payload. A key of one mesh (a
"pmwm-key" file) reads as a scene key of one object, so old keys read as before.

Reading (``verify_objects``) with a key file tries every suspect object against every object key (only
the keys of objects of the same connectivity when some match: a wrong key costs seconds of
registration search) and keeps the best pair; its p-value pays the union bound over the pairs tried
(``union_bound``), so that a scene of many objects is no easier to call marked by chance than one
mesh. With a pass phrase (one payload in every object) the scene is marked when every object is: the
p-value is the largest object's, exact whatever the dependence between objects, with no union bound
to pay (a pass-phrase scheme's p-value has a floor close to the threshold, which a union bound
would lift above it). The verdict names the
objects where the mark was read (``SceneDetail``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np

from ..api import embed, load_key_data, verify
from ..base import EmbedOptions, EmbedResult, Progress, Verdict, VerdictDetail, no_progress
from ..errors import KeyFileError, MeshError, PayloadError, PmwmError
from ..metrics import union_bound
from ..key import (
    scene_objects,
    WatermarkKey,
    derive_seed,
    face_fingerprint,
    json_text,
    keyed_bits,
    make_secret,
    read_key_text,
    write_key,
)

__all__ = [
    "SCENE_KEY_FORMAT",
    "SceneKey",
    "SceneDetail",
    "AssetMarking",
    "embed_objects",
    "verify_objects",
    "union_bound",
    "read_keys",
    "write_keys",
]

SCENE_KEY_FORMAT = "pmwm-scene-key"
SCENE_KEY_VERSION = 1

Named = tuple[str, np.ndarray, np.ndarray]  # (object name, vertices (n, 3) float64, faces (m, 3) int64)


@dataclass
class SceneKey:
    """The keys of a marked scene: ``keys[i]`` reads the object called ``names[i]``."""

    names: list[str]
    keys: list[WatermarkKey]

    def to_json(self) -> str:
        return json_text(
            {
                "format": SCENE_KEY_FORMAT,
                "version": SCENE_KEY_VERSION,
                "scheme": self.keys[0].scheme,
                "objects": [{"name": n, "key": json.loads(k.to_json())} for n, k in zip(self.names, self.keys)],
            }
        )


@dataclass
class AssetMarking:
    """What ``embed_objects`` gives: results[i] the embed of object i (its ``vertices`` the marked
    canonical positions); key: a WatermarkKey for one object, a SceneKey for several, None for a
    pass-phrase scheme."""

    names: list[str]
    results: list[EmbedResult]
    key: "WatermarkKey | SceneKey | None"

    @property
    def marked(self) -> list[np.ndarray]:
        return [r.vertices for r in self.results]


def embed_objects(
    objects: Sequence[Named], options: Optional[EmbedOptions] = None, progress: Progress = None
) -> AssetMarking:
    """Mark every object with the scheme of ``options``: one master secret (from ``options.seed`` or
    fresh) gives each object's seed; one payload (the options', or random bits drawn from the master
    secret) goes into every object. A PmwmError names the object that could not be marked."""
    if not objects:
        raise MeshError("no object to mark: give at least one mesh")
    opts = options or EmbedOptions()
    report = progress or no_progress
    master = make_secret(opts.seed)
    if opts.payload is None and opts.bits is None and len(objects) > 1:
        opts = replace(opts, bits="".join(map(str, keyed_bits(master, "scene-payload", opts.n_bits).tolist())))
    results = []
    for i, (name, V, F) in enumerate(objects):
        o = replace(opts, seed=derive_seed(master, f"scene-object:{i}") if len(objects) > 1 else opts.seed)

        def part(f: float, msg: str, i=i, name=name) -> None:
            report((i + f) / len(objects), f"{name}: {msg}")

        try:
            res = embed(V, F, o, progress=part if len(objects) > 1 else progress)
        except PmwmError as exc:
            if len(objects) == 1:
                raise
            raise type(exc)(f"object {name!r}: {exc}") from None
        if len(objects) > 1:
            _check_reads_back(name, res, F, opts)
        results.append(res)
    names = [n for n, _, _ in objects]
    keys = [r.key for r in results]
    if keys[0] is None:
        key = None
    elif len(keys) == 1:
        key = keys[0]
    else:
        key = SceneKey(names, keys)
    return AssetMarking(names, results, key)


def _check_reads_back(name: str, res: EmbedResult, faces: np.ndarray, opts: EmbedOptions) -> None:
    """PayloadError unless the object's mark reads back, as float32 (what a glTF stores): a scene's
    key must not name an object that carries nothing."""
    stored = res.vertices.astype(np.float32).astype(np.float64)
    v = verify(stored, faces, res.key, passphrase=None if res.key is not None else opts.passphrase)
    if not v.marked:
        raise PayloadError(
            f"object {name!r} does not read back as marked (p = {v.p_value:.3g}); it may be too "
            "small for the payload: give a stronger --strength, fewer bits, or another scheme"
        )


@dataclass(frozen=True)
class SceneDetail(VerdictDetail):
    """How a verdict over objects was read: the deciding pair's own detail (``inner``), the pairs tried
    (suspect objects x object keys; 0 for a pass phrase: then every object must read marked and the
    weakest decides), the deciding pair's names and p-value before any correction, and the (suspect
    object, key object, p) of every pair read as marked."""

    inner: VerdictDetail
    tried: int
    n_objects: int
    n_keys: int
    best: tuple[str, str]
    p_single: float
    found: tuple[tuple[str, str, float], ...]

    @property
    def counted(self) -> str:  # type: ignore[override]  (the inner scheme's word)
        return self.inner.counted

    def headline_note(self, verdict: Verdict) -> str:
        return self.inner.headline_note(verdict)

    def _where(self) -> str:
        shown = [s if (not k or s == k) else f"{s} (key of {k})" for s, k, _ in self.found]
        return ", ".join(shown)

    def notes(self) -> list[str]:
        read = (
            f"mark read in {len(self.found)} of {self.n_objects} objects: {self._where()}"
            if self.found
            else f"mark read in none of {self.n_objects} objects"
        )
        how = (
            f"p-value x {self.tried}, the object/key pairs tried"
            if self.tried
            else "the p-value is the weakest object's: a pass phrase marks every object"
        )
        return [*self.inner.notes(), f"{read} ({how})"]

    def in_words(self) -> list[tuple[str, str]]:
        where = (
            f"{self._where()} ({len(self.found)} of {self.n_objects})"
            if self.found
            else f"none of the {self.n_objects} objects"
        )
        how = (
            f"the p-value is the best object's times {self.tried}, the object/key pairs tried, so that "
            "many objects do not make a chance match likelier"
            if self.tried
            else "the p-value is the weakest object's: with a pass phrase every object must carry the mark"
        )
        return [("Objects marked", where), ("Correction", how), *self.inner.in_words()]

    def to_dict(self) -> dict:
        """The objects' part of ``pmwm verify --json``: the objects read (suspect object, key object,
        p-value), the pairs tried, the deciding pair and its p-value before any correction."""
        return {
            "read": [{"object": s, "key": k, "p_value": p} for s, k, p in self.found],
            "n_objects": self.n_objects,
            "pairs_tried": self.tried,
            "deciding": {"object": self.best[0], "key": self.best[1], "p_value": self.p_single},
        }

    def numbers(self) -> list[tuple[str, str]]:
        return [
            ("object/key pairs tried", str(self.tried)),
            ("deciding pair", " / ".join(self.best)),
            ("its p before correction", f"{self.p_single:.6g}"),
            *self.inner.numbers(),
        ]


def verify_objects(
    objects: Sequence[Named],
    keys: Optional[Sequence[tuple[str, WatermarkKey]]] = None,
    p_threshold: float = 1e-6,
    *,
    passphrase: Optional[str] = None,
) -> Verdict:
    """Read the mark from suspect objects with the object keys (``read_keys``) or a pass phrase: every
    object against every key, the best pair's verdict with its p-value times the pairs tried. One
    object and one key: ``pmwm.verify`` as it is."""
    secrets = [("", None)] if keys is None else list(keys)
    if len(objects) == 1 and len(secrets) == 1:
        return verify(objects[0][1], objects[0][2], secrets[0][1], p_threshold, passphrase=passphrase)
    plan = [(name, V, F, key_name, key) for name, V, F in objects for key_name, key in _keys_for(F, secrets)]
    tried = len(plan)
    pairs = [
        (name, key_name, verify(V, F, key, p_threshold, passphrase=passphrase)) for name, V, F, key_name, key in plan
    ]
    if keys is None:  # one pass phrase, one payload in every object: the weakest object decides
        found = tuple((s, k, v.p_value) for s, k, v in pairs if v.p_value < p_threshold)
        s, k, best = max(pairs, key=lambda t: t[2].p_value)
        p, tried = best.p_value, 0
    else:
        found = tuple(
            (s, k, union_bound(v.p_value, tried)) for s, k, v in pairs if union_bound(v.p_value, tried) < p_threshold
        )
        s, k, best = min(pairs, key=lambda t: t[2].p_value)
        p = union_bound(best.p_value, tried)
    marked = p < p_threshold
    confirmed = bool(marked and best.payload_confirmed)
    detail = SceneDetail(
        inner=best.detail,
        tried=tried,
        n_objects=len(objects),
        n_keys=len(secrets),
        best=(s, k),
        p_single=best.p_value,
        found=found,
    )
    return replace(
        best,
        p_value=p,
        marked=marked,
        payload_confirmed=confirmed,
        payload=best.payload if confirmed else None,
        detail=detail,
    )


def _keys_for(faces: np.ndarray, secrets: list) -> list:
    """The object keys to try on a suspect object of these faces: those of an object of the same
    connectivity (the key's faces fingerprint) when there are any, else all. The choice looks at the
    suspect's faces only, never at a mark, so the union bound over the pairs tried holds."""
    if len(secrets) == 1 or secrets[0][1] is None:
        return secrets
    fp = face_fingerprint(faces)
    same = [(n, k) for n, k in secrets if k.faces_fingerprint == fp]
    return same or secrets


def read_keys(path) -> list[tuple[str, WatermarkKey]]:
    """The (object name, key) pairs of a scene key file, or [("", key)] for the key file of one mesh;
    every key checked with its scheme's data (KeyFileError on anything wrong)."""
    text = read_key_text(path)
    try:
        doc = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        doc = None
    if not (isinstance(doc, dict) and doc.get("format") == SCENE_KEY_FORMAT):
        return [("", load_key_data(WatermarkKey.from_json(text, str(path))))]
    version = doc.get("version")
    if not isinstance(version, int) or not 1 <= version <= SCENE_KEY_VERSION:
        raise KeyFileError(
            f"{path} is scene key version {version}; this pmwm reads version {SCENE_KEY_VERSION}: upgrade pmwm"
        )
    return [
        (name, load_key_data(WatermarkKey.from_json(json.dumps(key), f"{path} (object {name!r})")))
        for name, key in scene_objects(doc, f"the scene key {path}")
    ]


def write_keys(path, key: "WatermarkKey | SceneKey", *, overwrite: bool = False) -> None:
    """Write the key of one mesh or of a scene atomically, readable by its owner only."""
    if isinstance(key, WatermarkKey):
        write_key(path, key, overwrite=overwrite)
        return
    from ..atomic import atomic_write_bytes

    atomic_write_bytes(path, key.to_json().encode(), force=overwrite, mode=0o600)
