"""A catalogue: many assets times many recipients on a Dask cluster (``dask.distributed``).

Each asset is analysed once, as a task (``asset.prepare_asset``: its key is written by the first run
and checked on later ones); a second task lists the recipients still to deliver (``asset.pending``:
not in the registry, or a file missing or not matching its registered SHA-256); then the copies
are tasks of ``batch`` recipients each, run where the analysis is. The client keeps each asset's
registry and writes it atomically every few seconds and at the end, so an interrupted run resumes
where it stopped (files are written atomically by the workers: whole or absent) and writes the
same bytes an uninterrupted run would. An asset that fails (unreadable, a key of another asset)
is reported with its error; the others complete.

Layout under ``out``: ``<name>/`` (the copies and ``registry.json``) and ``<name>.key.json`` (the
asset's key, a secret: not in the folder delivered), ``<name>`` the asset file's stem. A scene of several
objects (``pmwm.fingerprint.scene``) gets copies in its own format and a key and a registry of its objects.

The cluster: a ``LocalCluster`` of ``n_workers`` single-threaded worker processes (BLAS threads
limited to one) on this machine by default, or an existing scheduler's address (its workers must
see the same file system). Imported on its own: ``import pmwm`` never imports dask.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Optional

from ..errors import PayloadError, PmwmError
from .asset import REGISTRY_NAME, clean_temporaries, open_registry, pending, prepare_asset
from .codes import pack_codeword
from .copies import AssetAnalysis, FingerprintOptions
from .registry import RegistryEntry, write_registry
from .scene import SceneAnalysis, SceneRegistry, add_copy, open_scene_registry, prepare_scene, scene_pending

__all__ = ["CatalogueResult", "run_catalogue", "asset_names", "connect"]

REGISTRY_EVERY = 2.0  # seconds between registry writes of an asset while its copies arrive
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass
class CatalogueResult:
    """What ``run_catalogue`` did: copies written and skipped (already delivered intact), the assets
    that failed {name: one-line error}, each finished asset's registry path, and the wall time (s)."""

    written: int = 0
    skipped: int = 0
    failed: dict = field(default_factory=dict)
    registries: dict = field(default_factory=dict)
    seconds: float = 0.0


def asset_names(assets) -> list:
    """Each asset's name (its file's stem); PayloadError when two assets share one."""
    names = [os.path.splitext(os.path.basename(os.fspath(a)))[0] for a in assets]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise PayloadError(f"assets share a file name ({', '.join(dup)}); their folders would clash, rename them")
    return names


# --------------------------------------------------------------------------- the tasks (run on workers)


def _analyse(asset_path: str, key_path: str, options: FingerprintOptions, pm: bool) -> "AssetAnalysis | SceneAnalysis":
    scene = prepare_scene(asset_path, key_path, options)  # a scene of several objects: copies in its format
    if scene is not None:
        if pm:
            raise PayloadError(f"{asset_path} is a scene: its copies have no progressive mesh (omit --pm)")
        return scene
    return prepare_asset(asset_path, key_path, options, progressive=pm)[0]


def _todo(an: "AssetAnalysis | SceneAnalysis", key_path: str, out_dir: str, recipients: list, pm: bool):
    from .registry import read_fingerprint_key

    os.makedirs(out_dir, exist_ok=True)
    if isinstance(an, SceneAnalysis):
        reg = open_scene_registry(out_dir, an.key)
        todo = scene_pending(reg, out_dir, recipients, an.ext)
    else:
        reg = open_registry(out_dir, read_fingerprint_key(key_path))
        todo = pending(reg, out_dir, recipients, pm)
    clean_temporaries(out_dir)
    return reg, todo


def _copies(an: "AssetAnalysis | SceneAnalysis", out_dir: str, rids: list, pm: bool) -> list:
    if isinstance(an, SceneAnalysis):
        return [(rid, an.codewords(rid), an.write_copy(out_dir, rid)) for rid in rids]
    return [(rid, pack_codeword(an.codeword(rid)), an.write_copy(out_dir, rid, pm)) for rid in rids]


# --------------------------------------------------------------------------- the client


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, PmwmError):
        return str(exc)
    return f"{type(exc).__name__}: {exc}".splitlines()[0]


def connect(n_workers: Optional[int] = None, scheduler: Optional[str] = None):
    """(Client, LocalCluster or None): a client of the scheduler at ``scheduler``, or of a new
    LocalCluster of ``n_workers`` single-threaded worker processes (default: the cores)."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError) as exc:
            raise PmwmError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
    import dask

    for var in _THREAD_VARS:  # single-threaded workers: one process per core is the parallelism
        os.environ.setdefault(var, "1")
    # distributed starts workers with MALLOC_TRIM_THRESHOLD_=65536, which makes the numpy-heavy analysis
    # about 1.5x slower (its many large temporaries are mapped and unmapped each time): left out
    environ = {
        k: v
        for k, v in dask.config.get("distributed.nanny.pre-spawn-environ", {}).items()
        if k != "MALLOC_TRIM_THRESHOLD_"
    }
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
        cluster = LocalCluster(
            n_workers=n_workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=logging.CRITICAL,
            env={v: "1" for v in _THREAD_VARS},
        )
    return Client(cluster), cluster


def _terminate_as_interrupt() -> Callable[[], None]:
    """Make SIGTERM (a plain ``kill``) stop the run like Ctrl-C, so that the registry of what was
    written is saved and the cluster closed; returns the function that restores the old handler."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "SIGTERM"):
        return lambda: None

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, interrupt)
    return lambda: signal.signal(signal.SIGTERM, old)


def run_catalogue(
    assets,
    recipients: list,
    out,
    *,
    pm: bool = False,
    options: Optional[FingerprintOptions] = None,
    n_workers: Optional[int] = None,
    scheduler: Optional[str] = None,
    batch: int = 8,
    progress: Optional[Callable[[int, int], None]] = None,
) -> CatalogueResult:
    """Fingerprint every asset (mesh paths) for every recipient (ids) under ``out``; see the module
    docstring. ``progress(done, total)`` as copies are written or found intact."""
    from dask.distributed import as_completed

    t0 = time.perf_counter()
    names = asset_names(assets)
    out = os.fspath(out)
    os.makedirs(out, exist_ok=True)
    res = CatalogueResult()
    total, done = len(assets) * len(recipients), 0
    client, cluster = connect(n_workers, scheduler)
    regs, last, left, tags = {}, {}, {}, {}
    restore = _terminate_as_interrupt()
    try:
        ac = as_completed()
        for path, name in zip(assets, names):
            folder, key_path = os.path.join(out, name), os.path.join(out, name + ".key.json")
            an = client.submit(
                _analyse,
                os.path.abspath(os.fspath(path)),
                os.path.abspath(key_path),
                options or FingerprintOptions(),
                pm,
                pure=False,
                key=f"analyse-{name}",
            )
            todo = client.submit(
                _todo,
                an,
                os.path.abspath(key_path),
                os.path.abspath(folder),
                list(recipients),
                pm,
                pure=False,
                key=f"pending-{name}",
            )
            tags[todo.key] = ("todo", name, an)
            ac.add(todo)
        for fut in ac:
            kind, name, an = tags.pop(fut.key)
            if name in res.failed:
                continue
            try:
                value = fut.result()
            except Exception as exc:  # one asset fails, the others go on
                res.failed[name] = _one_line(exc)
                total -= len(recipients)
                continue
            folder = os.path.join(out, name)
            if kind == "todo":
                reg, todo = value
                regs[name], last[name], left[name] = reg, time.perf_counter(), len(todo)
                res.skipped += len(recipients) - len(todo)
                done += len(recipients) - len(todo)
                for i in range(0, len(todo), batch):
                    f = client.submit(
                        _copies,
                        an,
                        os.path.abspath(folder),
                        todo[i : i + batch],
                        pm,
                        pure=False,
                        key=f"copies-{name}-{i}",
                    )
                    tags[f.key] = ("copies", name, an)
                    ac.add(f)
            else:
                reg = regs[name]
                for rid, code, files in value:
                    if isinstance(reg, SceneRegistry):  # (a scene: a codeword per object)
                        add_copy(reg, rid, code, files)
                        continue
                    entry = reg.entries.get(rid) or RegistryEntry(code)
                    entry.files.update(files)
                    reg.entries[rid] = entry
                left[name] -= len(value)
                res.written += len(value)
                done += len(value)
            if progress and total:
                progress(done, total)
            if left[name] == 0 or time.perf_counter() - last[name] > REGISTRY_EVERY:
                write_registry(os.path.join(folder, REGISTRY_NAME), regs[name])
                last[name] = time.perf_counter()
                if left[name] == 0:
                    res.registries[name] = os.path.join(folder, REGISTRY_NAME)
    finally:
        for name, reg in regs.items():  # what was written so far is registered
            if name not in res.registries:
                write_registry(os.path.join(out, name, REGISTRY_NAME), reg)
        client.close()
        if cluster is not None:
            cluster.close()
        restore()
    res.seconds = time.perf_counter() - t0
    return res
