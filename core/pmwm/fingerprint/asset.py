"""Fingerprinting one asset file: the key (written by the first run, checked on later ones), one
analysis, a copy per recipient not yet delivered intact, and the registry beside the copies.

Resumable: a recipient whose files are in the registry and on disk with the registered SHA-256 is
skipped; any other is (re)written, byte-identical to what an uninterrupted run writes (every choice
derives from the key). Every file is written atomically, so an interruption leaves whole files or
none (and stale temporary files of an earlier kill are removed on the next run)."""

from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ..atomic import file_sha256
from ..errors import KeyFileError, PmwmError
from ..key import mesh_sha256
from ..meshio import read_mesh
from .codes import pack_codeword
from .copies import AssetAnalysis, FingerprintOptions, analyse_asset
from .registry import (
    FingerprintKey,
    Registry,
    RegistryEntry,
    read_fingerprint_key,
    read_registry,
    write_fingerprint_key,
    write_registry,
)

__all__ = ["REGISTRY_NAME", "FingerprintRun", "prepare_asset", "pending", "fingerprint_asset", "clean_temporaries"]

REGISTRY_NAME = "registry.json"
REGISTRY_EVERY = 2.0  # seconds between registry writes while copies are written (and at the end)


_TEMPORARY = re.compile(r"\..+\.tmp-[^.]+\.(ply|pmwm|json|glb|gltf|bin|obj)")  # pmwm.atomic's temporary names


def clean_temporaries(folder) -> None:
    """Remove the temporary files an interrupted (killed) run left in ``folder``."""
    for name in os.listdir(folder):
        if _TEMPORARY.fullmatch(name):
            try:
                os.unlink(os.path.join(folder, name))
            except OSError:
                pass


def prepare_asset(
    asset_path, key_path, options: Optional[FingerprintOptions] = None, progress=None, progressive: bool = True
) -> tuple[AssetAnalysis, FingerprintKey]:
    """Read the asset and analyse it with the key at ``key_path``: the existing key (its options;
    KeyFileError when it was made for another asset), or a new one from ``options`` written there.
    ``progressive``: build the progressive mesh the copies share (only .pmwm copies need it)."""
    src = read_mesh(asset_path)
    V, F = src.vertices, src.faces
    if os.path.exists(key_path):
        fk = read_fingerprint_key(key_path)
        if fk.asset_sha256 != mesh_sha256(V, F, "<f8"):
            raise KeyFileError(
                f"{key_path} is the fingerprinting key of another asset than {asset_path}; "
                "give that asset's key, or a new --key path"
            )
        opts = FingerprintOptions(fk.options.strength, fk.options.n_sites, fk.options.base_ratio)
        an = analyse_asset(V, F, opts, secret=fk.key.secret, progress=progress, progressive=progressive)
        if not np.array_equal(an.key.data.origin, fk.key.data.origin):
            raise KeyFileError(
                f"this pmwm analyses {asset_path} differently from the one that wrote {key_path}; "
                "use the same pmwm version"
            )
        return an, fk
    an = analyse_asset(V, F, options, progress=progress, progressive=progressive)
    fk = FingerprintKey(an.key, an.options, an.asset_sha256)
    write_fingerprint_key(key_path, fk)
    return an, fk


def _expected(rid: str, pm: bool) -> list:
    return [rid + ".ply"] + ([rid + ".pmwm"] if pm else [])


def _on_disk(path: str, sha256: str) -> bool:
    """The file exists with this SHA-256."""
    try:
        return file_sha256(path) == sha256
    except FileNotFoundError:
        return False


def pending(reg: Registry, out_dir, recipients, pm: bool) -> list:
    """The recipients whose files are not all in the registry and on disk with its SHA-256."""
    todo = []
    for rid in recipients:
        e = reg.entries.get(rid)
        ok = e is not None and all(
            name in e.files and _on_disk(os.path.join(out_dir, name), e.files[name]) for name in _expected(rid, pm)
        )
        if not ok:
            todo.append(rid)
    return todo


def open_registry(out_dir, fk: FingerprintKey) -> Registry:
    """The registry in ``out_dir`` (checked against the key), or a new one."""
    path = os.path.join(out_dir, REGISTRY_NAME)
    if os.path.exists(path):
        reg = read_registry(path)
        reg.check(fk, path)
        return reg
    return Registry.for_key(fk)


def register(reg: Registry, an: AssetAnalysis, rid: str, files: dict) -> None:
    """Record a recipient's codeword and the SHA-256 of its files."""
    entry = reg.entries.get(rid) or RegistryEntry(pack_codeword(an.codeword(rid)))
    entry.files.update(files)
    reg.entries[rid] = entry


@dataclass
class FingerprintRun:
    """What ``fingerprint_asset`` did: recipients written and skipped, the registry and its path,
    and the time of the analysis and of the copies (seconds)."""

    written: list
    skipped: list
    registry: Registry
    registry_path: str
    analysis_seconds: float = 0.0
    copies_seconds: float = 0.0
    extra: dict = field(default_factory=dict)


def fingerprint_asset(
    asset_path,
    key_path,
    recipients,
    out_dir,
    pm: bool = False,
    options: Optional[FingerprintOptions] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> FingerprintRun:
    """Fingerprint ``asset_path`` for ``recipients`` (ids) into ``out_dir`` (created): see the module
    docstring. ``progress(done, total)`` after each copy."""
    if not os.path.isdir(out_dir):
        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as exc:
            raise PmwmError(f"cannot create {out_dir}: {exc.strerror or exc}") from None
    t0 = time.perf_counter()
    an, fk = prepare_asset(asset_path, key_path, options, progressive=pm)
    reg = open_registry(out_dir, fk)
    t1 = time.perf_counter()
    todo = pending(reg, out_dir, recipients, pm)
    clean_temporaries(out_dir)
    path = os.path.join(out_dir, REGISTRY_NAME)
    last = time.perf_counter()
    for i, rid in enumerate(todo):
        register(reg, an, rid, an.write_copy(out_dir, rid, pm))
        if time.perf_counter() - last > REGISTRY_EVERY:
            write_registry(path, reg)
            last = time.perf_counter()
        if progress:
            progress(i + 1, len(todo))
    write_registry(path, reg)
    again = set(todo)
    return FingerprintRun(todo, [r for r in recipients if r not in again], reg, path, t1 - t0, time.perf_counter() - t1)
