"""The watermarking schemes, each behind the same interface (``pmwm.base.Scheme``).

- ``robust`` (the default): bumps and swirls spread over sites, registered, matched-filter reading.
- ``paper``: the paper's Algorithms 1-2 (one carrier vertex per bit, read against its 1-ring).
- ``cho1``, ``cho2``: Cho et al. 2007, methods I and II (the distribution of vertex norms; blind).
- ``blind``: read with a pass phrase alone, no key file (keyed waves in the solid's shape, keyed check);
  ``blind-histogram``, its baseline carrier (vertex norms over a quantile range), read by the same reader.

Each scheme says what its reader needs (``Scheme.keying``: a key file, or a pass phrase alone); front
ends look schemes up here (``SCHEMES``, ``get_scheme``, ``keyed_by``, ``passphrase_scheme``) and never
import a scheme's own modules. Each scheme module imports the shared layers below it (``base``, ``key``,
geometry), never another scheme and never ``pmwm.api``.
"""

from __future__ import annotations

from ..base import Scheme
from ..errors import PayloadError
from .blind import HISTOGRAM_SCHEME as BLIND_HISTOGRAM
from .blind import SCHEME as BLIND
from .cho import CHO1, CHO2
from .paper import SCHEME as PAPER
from .robust import SCHEME as ROBUST

SCHEMES: dict[str, Scheme] = {s.name: s for s in (ROBUST, PAPER, CHO1, CHO2, BLIND, BLIND_HISTOGRAM)}
DEFAULT_SCHEME = "robust"

__all__ = ["SCHEMES", "DEFAULT_SCHEME", "get_scheme", "keyed_by", "passphrase_scheme"]


def get_scheme(name: str, error=PayloadError) -> Scheme:
    """The scheme called ``name``, or ``error`` (a PmwmError class) naming the ones there are."""
    try:
        return SCHEMES[name]
    except (KeyError, TypeError):
        raise error(f"unknown scheme {name!r}; use one of {', '.join(SCHEMES)}") from None


def keyed_by(keying: str) -> list[str]:
    """The names of the schemes whose ``keying`` is ``keying`` ("key file" or "pass phrase")."""
    return [s.name for s in SCHEMES.values() if s.keying == keying]


def passphrase_scheme() -> Scheme:
    """The scheme that reads a mark with a pass phrase alone (``pmwm.verify(..., passphrase=...)``): the
    blind scheme, whose reader reads both its carriers (``blind`` and ``blind-histogram``)."""
    return SCHEMES[BLIND.name]
