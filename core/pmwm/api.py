"""The public entry points: mark, read, and read keys, whatever the scheme.

``embed`` hands the mesh to the scheme named in the options, ``verify`` to the scheme named in the
key, or with a pass phrase to the scheme keyed by one; ``verify_keys`` reads one suspect with several
keys, one verdict each, corrected for the keys tried; ``read_key`` reads a key file and the
scheme's own data in it, so that a damaged key is refused before any suspect mesh is loaded. See
docs/api.md.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Optional, Sequence

from .base import KEY_FILE, EmbedOptions, EmbedResult, KeysVerdict, Progress, Verdict, no_progress
from .errors import KeyFileError, PayloadError
from .key import WatermarkKey, read_key_json
from .memory import reuse_freed_memory
from .metrics import union_bound
from .progressive import ProgressiveMesh
from .schemes import get_scheme, passphrase_scheme

__all__ = ["embed", "verify", "verify_keys", "verify_pm", "ber_per_level", "read_key", "load_key_data"]


def embed(vertices, faces, options: Optional[EmbedOptions] = None, progress: Progress = None) -> EmbedResult:
    """Watermark a triangle mesh, vertices : (n, 3) float64, faces : (m, 3) int64, with the scheme of
    ``options`` (default: robust). ``progress(fraction, message)`` is called as the work advances."""
    opts = options or EmbedOptions()
    reuse_freed_memory()
    return get_scheme(opts.scheme).embed(vertices, faces, opts, progress)


def load_key_data(key: WatermarkKey) -> WatermarkKey:
    """``key`` with its scheme's data read and checked (``key.data``); KeyFileError when damaged."""
    scheme = get_scheme(key.scheme, KeyFileError)
    key.data = scheme.load_key_data(key)
    return key


def read_key(path) -> WatermarkKey:
    """Read a key file and check it, its scheme's data included; KeyFileError on anything wrong."""
    return load_key_data(read_key_json(path))


def verify(
    vertices,
    faces,
    key: Optional[WatermarkKey] = None,
    p_threshold: float = 1e-6,
    *,
    passphrase: Optional[str] = None,
    progress: Progress = None,
) -> Verdict:
    """Read the mark from a suspect mesh (any order, possibly attacked) with the key's scheme, or,
    with ``passphrase`` instead of a key, with the scheme keyed by a pass phrase (the blind scheme:
    the payload is read, not known). ``progress(fraction, message)`` is called at the reader's stages,
    ending at 1.0."""
    if (key is None) == (passphrase is None):
        raise PayloadError(f"give a key or a pass phrase (the {passphrase_scheme().name} scheme), not both or neither")
    if key is None:
        scheme, secret = passphrase_scheme(), passphrase
    else:
        scheme, secret = get_scheme(key.scheme, KeyFileError), key
        if scheme.keying != KEY_FILE:
            raise KeyFileError(
                f"the {scheme.name} scheme reads with a pass phrase, not a key: give passphrase= instead"
            )
    reuse_freed_memory()
    return scheme.verify(vertices, faces, secret, p_threshold, progress=progress)


def verify_keys(
    vertices,
    faces,
    keys: Sequence[WatermarkKey],
    p_threshold: float = 1e-6,
    *,
    progress: Progress = None,
) -> KeysVerdict:
    """Read one suspect mesh, vertices : (n, 3), faces : (m, 3), with each of several key files' keys
    (a copy may carry the marks of several owners): one ``verify`` per key, each verdict's p-value
    multiplied by the number of keys (``KeysVerdict``), so that trying many keys does not make a chance
    "marked" likelier; marked and a payload shown only after that correction. One key: ``verify``'s
    verdict as it is. ``progress(fraction, message)`` as each key is read, ending at 1.0."""
    if not keys:
        raise PayloadError("give at least one key to read the suspect with")
    report = progress or no_progress
    n = len(keys)
    verdicts, singles = [], []
    for i, key in enumerate(keys):

        def part(f: float, msg: str, i: int = i) -> None:
            report(min((i + f) / n, 1.0), f"key {i + 1} of {n}: {msg}" if n > 1 else msg)

        v = verify(vertices, faces, key, p_threshold, progress=part)
        p = union_bound(v.p_value, n)
        marked = p < p_threshold
        confirmed = bool(marked and v.payload_confirmed)
        verdicts.append(
            replace(v, p_value=p, marked=marked, payload_confirmed=confirmed, payload=v.payload if confirmed else None)
        )
        singles.append(v.p_value)
    report(1.0, "read")
    return KeysVerdict(verdicts, singles)


def verify_pm(
    pm: ProgressiveMesh,
    key: Optional[WatermarkKey] = None,
    records: Optional[int] = None,
    p_threshold: float = 1e-6,
    *,
    passphrase: Optional[str] = None,
    progress: Progress = None,
) -> Verdict:
    """Read the mark from a progressive mesh at a level of detail (default: full)."""
    V, F = pm.decode(records=records)
    return verify(V, F, key, p_threshold, passphrase=passphrase, progress=progress)


def ber_per_level(pm: ProgressiveMesh, key: WatermarkKey) -> list[tuple[int, int, float]]:
    """(records, vertices, BER) at the base mesh and at the end of every level."""
    out = []
    for k in [0, *pm.level_records.tolist()]:
        v = verify_pm(pm, key, records=k)
        out.append((k, pm.n_base_vertices + k, v.bit_errors / v.carriers_total))
    return out
