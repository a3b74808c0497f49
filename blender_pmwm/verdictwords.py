"""The verdict in the panel's words: the rows of the verdict box, its numbers, the one-line report.

Everything comes from ``pmwm.wording`` (the words every front end shares); the add-on only picks
which rows its box shows. A payload is shown only when the verdict confirms it.
"""

from __future__ import annotations

from . import compat
from .compat import wording  # COMPAT: the branches for ``wording is None`` go with compat.py

# Rows of wording.rows left out of the sidebar's box (too long for it; the report has them).
LEFT_OUT = {"Payload bits"}


def _confirmed(v) -> bool:
    confirmed = getattr(v, "payload_confirmed", None)
    return bool(v.marked and v.bit_errors == 0) if confirmed is None else bool(confirmed)


def headline(v) -> str:
    """"MARKED: ..." / "not marked: ..."."""
    if wording is not None:
        return wording.headline(v)
    state = "MARKED" if v.marked else "not marked"
    return f"{state}: {v.matches}/{v.carriers_total} bits match, p = {v.p_value:.3g} (threshold {v.p_threshold:g})"


def payload_line(v) -> str:
    """"payload: 'OWNR'", "payload unconfirmed (...)" or "no payload read"; never unconfirmed text."""
    if wording is not None:
        return wording.payload_line(v)
    if _confirmed(v):
        return f"payload: {v.payload!r}" if v.payload is not None else f"payload bits: {v.bits}"
    if v.marked:
        return f"payload unconfirmed ({v.bit_errors} of {v.carriers_total} bits differ)"
    return "no payload read"


def box_rows(v) -> list[tuple[str, str]]:
    """(label, value) rows of the verdict box in plain words."""
    if wording is not None:
        return [(k, val) for k, val in wording.rows(v) if k not in LEFT_OUT]
    if _confirmed(v):
        payload = repr(v.payload) if v.payload is not None else "not text"
    else:
        payload = f"unconfirmed ({v.bit_errors} of {v.carriers_total} bits differ)" if v.marked else "none read"
    return [("Verdict", "MARKED" if v.marked else "NOT MARKED"),
            ("p-value", f"{v.p_value:.3g} (threshold {v.p_threshold:g})"),
            ("Matching bits", f"{v.matches} of {v.carriers_total} ({v.bit_errors} wrong)"),
            ("Payload read", payload)] + [("Read", note) for note in compat.notes(v)]


def numbers(v) -> list[tuple[str, str]]:
    """(name, value) rows of the verdict's figures, for the box's closed Numbers section."""
    if wording is not None:
        return wording.technical_rows(v)
    return [("mode", v.mode), ("p-value", f"{v.p_value:.6g}"), ("correlation", f"{v.correlation:.4f}"),
            ("bits read (not erased)", f"{v.carriers_found}/{v.carriers_total}")]


def report_line(v) -> str:
    """The verdict in one line for Blender's report: headline, how it was read, payload line."""
    if wording is not None:
        return "; ".join(wording.lines(v))
    return "; ".join([headline(v), *compat.notes(v), payload_line(v)])


def confirmed_payload(v) -> str:
    """The payload text when the verdict confirms it, else "" (what scripts read)."""
    return v.payload if _confirmed(v) and v.payload is not None else ""
