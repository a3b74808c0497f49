"""The fingerprinting key file and the registry of recipients, and the recipients' list.

Key file (JSON, ``"format": "pmwm-fingerprint-key"``, mode 0600: a secret): the options of the
analysis, the SHA-256 of the asset it was made for, and the tracing key (a robust pmwm key, one site
per "bit"). It is written by the first run and reused by every later one, which checks it against
the asset. It is not a payload key: ``pmwm verify`` refuses it, ``pmwm trace`` reads it.

Registry (JSON, ``"format": "pmwm-fingerprint-registry"``), beside the copies: the key's public id
(``codes.key_id``) and the asset's SHA-256 (a registry and a key that do not belong together are a
clear error), the number of sites, and per recipient its codeword (hex) and the SHA-256 of every
file written for it. Written atomically; a recipient once registered is never dropped.
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass, field

import numpy as np

from ..atomic import atomic_write_bytes
from ..errors import KeyFileError, PayloadError
from ..key import WatermarkKey, json_text
from ..schemes.robust.keydata import RobustKeyData
from .codes import check_recipient_id, key_id, unpack_codewords
from .copies import FingerprintOptions

__all__ = [
    "FingerprintKey",
    "Registry",
    "RegistryEntry",
    "read_fingerprint_key",
    "write_fingerprint_key",
    "read_registry",
    "write_registry",
    "read_recipients",
    "RegistryError",
]

KEY_FORMAT, REGISTRY_FORMAT, VERSION = "pmwm-fingerprint-key", "pmwm-fingerprint-registry", 1


class RegistryError(KeyFileError):
    """A registry is unreadable, damaged, or does not belong to the key or asset given."""


def _read_json(path, what: str, error) -> dict:
    path = os.fspath(path)
    if os.path.isdir(path):
        raise error(f"{path} is a directory, not a {what}")
    try:
        with open(path, "rb") as fh:
            return json.loads(fh.read().decode("utf-8"))
    except FileNotFoundError:
        raise error(f"{what} {path} does not exist") from None
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        raise error(f"{path} is not a {what} (not JSON)") from None


@dataclass
class FingerprintKey:
    """A fingerprinting key: the tracing key (robust, one site per bit), the analysis options and
    the asset's SHA-256 (``copies.asset_sha256``)."""

    key: WatermarkKey
    options: FingerprintOptions
    asset_sha256: str

    @property
    def key_id(self) -> str:
        return key_id(self.key.secret)

    @property
    def n_sites(self) -> int:
        return self.key.n_bits

    def to_json(self) -> str:
        doc = {
            "format": KEY_FORMAT,
            "version": VERSION,
            "key_id": self.key_id,
            "options": self.options.to_dict(),
            "asset_sha256": self.asset_sha256,
            "key": json.loads(self.key.to_json()),
        }
        return json_text(doc)

    @classmethod
    def from_json(cls, doc: dict, name: str = "the key") -> "FingerprintKey":
        if not isinstance(doc, dict) or doc.get("format") != KEY_FORMAT:
            raise KeyFileError(
                f'{name} is not a fingerprinting key (no "format": "{KEY_FORMAT}"); '
                "give the --key written by pmwm fingerprint"
            )
        if doc.get("version") != VERSION:
            raise KeyFileError(
                f"{name} is fingerprinting key version {doc.get('version')!r}; this pmwm reads {VERSION}"
            )
        try:
            key = WatermarkKey.from_json(json.dumps(doc["key"]), name)
            key.data = RobustKeyData.from_extra(key.extra, key.n_bits, key.n_vertices)
            o = doc["options"]
            opts = FingerprintOptions(
                strength=float(o["strength"]), n_sites=int(o["n_sites"]), base_ratio=float(o["base_ratio"])
            )
            return cls(key, opts, str(doc["asset_sha256"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise KeyFileError(f"{name} lacks or garbles a field ({exc}); it is damaged") from None


def write_fingerprint_key(path, fk: FingerprintKey, *, overwrite: bool = False) -> None:
    """Write the key atomically, readable by its owner only (0600)."""
    atomic_write_bytes(path, fk.to_json().encode(), force=overwrite, mode=0o600)


def read_fingerprint_key(path) -> FingerprintKey:
    """Read and check a fingerprinting key file (KeyFileError naming the problem)."""
    return FingerprintKey.from_json(_read_json(path, "fingerprinting key", KeyFileError), os.fspath(path))


@dataclass
class RegistryEntry:
    """One recipient: codeword (hex, ``codes.pack_codeword``) and {file name: SHA-256}."""

    codeword: str
    files: dict = field(default_factory=dict)


@dataclass
class Registry:
    """The recipients of one fingerprinted asset (see the module docstring)."""

    key_id: str
    asset_sha256: str
    n_sites: int
    entries: dict = field(default_factory=dict)  # recipient id -> RegistryEntry (written sorted by id)

    @classmethod
    def for_key(cls, fk: FingerprintKey) -> "Registry":
        return cls(fk.key_id, fk.asset_sha256, fk.n_sites)

    def check(self, fk: FingerprintKey, name: str = "the registry") -> None:
        """RegistryError unless this registry belongs to the key ``fk``."""
        if self.key_id != fk.key_id:
            raise RegistryError(
                f"{name} belongs to another fingerprinting key (key id {self.key_id}, "
                f"the key's is {fk.key_id}); give the key and registry of the same asset"
            )
        if self.asset_sha256 != fk.asset_sha256 or self.n_sites != fk.n_sites:
            raise RegistryError(f"{name} was written for another asset than the key's; it is damaged")

    def codewords(self) -> tuple[list, np.ndarray]:
        """The recipients in order and their codewords (N, S) int8 +-1."""
        ids = list(self.entries)
        try:
            return ids, unpack_codewords([self.entries[r].codeword for r in ids], self.n_sites)
        except ValueError as exc:
            raise RegistryError(f"the registry's codewords are damaged ({exc})") from None

    def to_json(self) -> str:
        doc = {
            "format": REGISTRY_FORMAT,
            "version": VERSION,
            "key_id": self.key_id,
            "asset_sha256": self.asset_sha256,
            "n_sites": self.n_sites,
            "recipients": [
                {"id": r, "codeword": self.entries[r].codeword, "files": dict(sorted(self.entries[r].files.items()))}
                for r in sorted(self.entries)
            ],
        }  # sorted: the same file whatever order copies came in
        return json.dumps(doc, indent=0) + "\n"

    @classmethod
    def from_json(cls, doc: dict, name: str = "the registry") -> "Registry":
        if not isinstance(doc, dict) or doc.get("format") != REGISTRY_FORMAT:
            raise RegistryError(f'{name} is not a fingerprinting registry (no "format": "{REGISTRY_FORMAT}")')
        if doc.get("version") != VERSION:
            raise RegistryError(f"{name} is registry version {doc.get('version')!r}; this pmwm reads {VERSION}")
        try:
            reg = cls(str(doc["key_id"]), str(doc["asset_sha256"]), int(doc["n_sites"]))
            for r in doc["recipients"]:
                reg.entries[check_recipient_id(r["id"])] = RegistryEntry(
                    str(r["codeword"]), {str(k): str(v) for k, v in dict(r["files"]).items()}
                )
        except (KeyError, TypeError, ValueError, PayloadError) as exc:
            raise RegistryError(f"{name} lacks or garbles a field ({exc}); it is damaged") from None
        return reg


def write_registry(path, reg: Registry) -> None:
    """Write the registry atomically (replacing the previous one)."""
    atomic_write_bytes(path, reg.to_json().encode(), force=True)


def read_registry(path) -> Registry:
    """Read and check a registry file (RegistryError naming the problem)."""
    return Registry.from_json(_read_json(path, "fingerprinting registry", RegistryError), os.fspath(path))


def read_recipients(path) -> list:
    """Recipient ids from a CSV file: the column "id" (or "recipient") when the first row names one,
    else the first column; blank lines skipped. PayloadError on an invalid or repeated id."""
    try:
        with open(os.fspath(path), newline="", encoding="utf-8-sig") as fh:
            rows = [row for row in csv.reader(fh) if row and any(c.strip() for c in row)]
    except FileNotFoundError:
        raise PayloadError(f"recipients file {path} does not exist") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise PayloadError(f"cannot read recipients file {path}: {exc}") from None
    col = 0
    if rows:
        head = [c.strip().lower() for c in rows[0]]
        for name in ("id", "recipient", "recipient_id"):
            if name in head:
                col, rows = head.index(name), rows[1:]
                break
    ids = [check_recipient_id(row[col].strip() if col < len(row) else "") for row in rows]
    seen = set()
    for rid in ids:
        if rid in seen:
            raise PayloadError(f"recipient {rid!r} is listed twice in {path}")
        seen.add(rid)
    if not ids:
        raise PayloadError(f"{path} lists no recipient")
    return ids
