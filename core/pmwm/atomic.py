"""Atomic file writing: an output appears whole or not at all, and an existing one is kept unless
forced. Used by every writer (meshes, keys, progressive meshes, reports); imports nothing heavier
than the standard library, so the key and .pmwm writers do not pull in trimesh. Also the SHA-256 of
a file, which reports and registries record of what was written."""

from __future__ import annotations

import hashlib
import os
import secrets
from contextlib import contextmanager
from typing import Iterator

from .errors import OutputExistsError, PmwmError

__all__ = ["atomic_output", "atomic_write_bytes", "file_sha256"]


def file_sha256(path) -> str:
    """Hex SHA-256 of a file's bytes (read in blocks); FileNotFoundError when it does not exist."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _fsync_path(path: str) -> None:
    fd = os.open(path, os.O_RDWR)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(folder: str) -> None:
    """Make the rename durable where the OS allows it (a no-op on Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _remove_quietly(path: str) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


@contextmanager
def atomic_output(path, *, force: bool = False, mode: int | None = None) -> Iterator[str]:
    """Yield a temporary path next to ``path``; on success move it onto ``path`` atomically.

    Refuses an existing target unless ``force`` (OutputExistsError) and a missing folder
    (PmwmError). The temporary file already exists (empty) and keeps the target's extension, so
    writers that sniff the extension work. After the body it is fsynced and renamed; when the
    body raises it is removed and the target is untouched. ``mode`` (e.g. 0o600) is applied to
    the temporary file from its creation, so a secret is never readable by others.
    """
    target = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(target))
    if not os.path.isdir(folder):
        raise PmwmError(f"folder {folder} does not exist; create it first or choose another output path")
    if os.path.isdir(target):
        raise PmwmError(f"{target} is a directory; give a file name to write")
    if not force and os.path.lexists(target):
        raise OutputExistsError(f"{target} exists; pass --force to overwrite")

    stem, ext = os.path.splitext(os.path.basename(target))
    create_mode = 0o666 if mode is None else mode
    while True:
        tmp = os.path.join(folder, f".{stem}.tmp-{secrets.token_hex(4)}{ext}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, create_mode)
        except FileExistsError:
            continue
        except OSError as exc:
            raise PmwmError(f"cannot write {target}: {exc.strerror or exc}") from None
        os.close(fd)
        break

    try:
        yield tmp
        if mode is not None:
            os.chmod(tmp, mode)
        _fsync_path(tmp)
        if force:
            os.replace(tmp, target)
        else:
            try:  # no-clobber: fails if the target appeared while we were writing
                os.link(tmp, target)
            except FileExistsError:
                raise OutputExistsError(f"{target} exists; pass --force to overwrite") from None
            except OSError:  # the filesystem has no hard links
                if os.path.lexists(target):
                    raise OutputExistsError(f"{target} exists; pass --force to overwrite") from None
                os.replace(tmp, target)
            else:
                _remove_quietly(tmp)
    except BaseException as exc:
        _remove_quietly(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, PmwmError):
            raise PmwmError(f"cannot write {target}: {exc.strerror or exc}") from exc
        raise
    _fsync_dir(folder)


def atomic_write_bytes(path, data: bytes, *, force: bool = False, mode: int | None = None) -> None:
    """Write ``data`` to ``path`` atomically (see ``atomic_output``); ``mode`` e.g. 0o600 for secrets."""
    with atomic_output(path, force=force, mode=mode) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
