"""COMPAT: the library's newer interface where this pmwm predates it; the whole module goes once
``pmwm.wording`` and ``Scheme.keying`` are in the bundled library (then import them directly)."""

from __future__ import annotations

try:
    from pmwm import wording
except ImportError:
    wording = None


def keying(scheme: str) -> str:
    """What reads a scheme's mark: "key file" or "pass phrase" (``pmwm`` scheme's ``keying``)."""
    from pmwm.schemes import get_scheme

    found = getattr(get_scheme(scheme), "keying", None)
    if found is not None:
        return found
    return "pass phrase" if scheme == "blind" else "key file"
