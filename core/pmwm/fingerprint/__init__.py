"""Fingerprinting: a marked copy per recipient, tracing a leaked copy to its source, a catalogue.

- ``codes``: keyed +-1 codewords over the sites, the correlation score, the corrected p-value and the
  decision rule (read its docstring for the rule and why).
- ``copies``: ``analyse_asset`` (one analysis of an asset) and ``AssetAnalysis.copy`` (a cheap marked
  copy and its files per codeword).
- ``registry``: the fingerprinting key file, the registry of recipients, the recipients' CSV.
- ``asset``: ``fingerprint_asset`` (the files of one asset, resumable).
- ``trace``: ``trace`` (who a suspect copy came from).
- ``scene``: a scene of several objects (``pmwm.scene``): a key and a registry per object, copies in the
  scene's own format, ``trace_objects`` over a scene or one object alone (imported by ``cli`` when needed).
- ``catalogue``: many assets times many recipients on Dask (imported on its own: ``pmwm`` never
  imports dask; ``pip install 'pmwm[catalogue]'``).
"""

from .asset import FingerprintRun, fingerprint_asset
from .codes import Accusation, codeword, key_id
from .copies import AssetAnalysis, FingerprintOptions, analyse_asset
from .registry import (
    FingerprintKey,
    Registry,
    RegistryError,
    read_fingerprint_key,
    read_recipients,
    read_registry,
    write_fingerprint_key,
    write_registry,
)
from .trace import TraceResult, trace

__all__ = [
    "FingerprintOptions",
    "AssetAnalysis",
    "analyse_asset",
    "FingerprintRun",
    "fingerprint_asset",
    "FingerprintKey",
    "Registry",
    "RegistryError",
    "read_fingerprint_key",
    "write_fingerprint_key",
    "read_registry",
    "write_registry",
    "read_recipients",
    "TraceResult",
    "trace",
    "Accusation",
    "codeword",
    "key_id",
]
