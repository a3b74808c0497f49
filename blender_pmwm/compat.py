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


def notes(v) -> list[str]:
    """How a verdict was read when that departs from the suspect as given (``pmwm.wording.lines``'s middle
    lines), for a library whose verdicts still carry ``extra``."""
    mesh = getattr(v, "extra", {}).get("mesh")
    if not isinstance(mesh, str):
        return []
    from pmwm.schemes.blind import mesh_read

    note = mesh_read(mesh)
    return [note] if note else []
