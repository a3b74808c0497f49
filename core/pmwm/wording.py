"""The verdict in words, written once for every front end: the command line prints ``lines``, the
add-on shows ``headline`` and ``payload_line`` (and ``payload_value`` in its panel), the HTML report
tables ``rows`` and, in a collapsible section, ``technical_rows``.

A payload is shown only when the verdict confirms it (``Verdict.payload_confirmed``): a marked
verdict whose payload is not confirmed says how many bits differ, never the text it read. What is
particular to a scheme comes from its ``Verdict.detail`` (``pmwm.base.VerdictDetail``).
"""

from __future__ import annotations

from .base import Verdict

__all__ = ["headline", "payload_line", "payload_value", "lines", "rows", "technical_rows"]


def _state(v: Verdict) -> str:
    return "MARKED" if v.marked else "not marked"


def headline(v: Verdict) -> str:
    """The verdict's first line: "MARKED: ..." or "not marked: ...", with the bits that match, the
    p-value and its threshold, and how much of the mark was read."""
    return (
        f"{_state(v)}: {v.matches}/{v.carriers_total} {v.detail.counted} match, p = {v.p_value:.3g} "
        f"(threshold {v.p_threshold:g}), {v.detail.headline_note(v)}"
    )


def _differ(v: Verdict) -> str:
    return f"{v.bit_errors} of {v.carriers_total} bits differ"


def payload_line(v: Verdict) -> str:
    """ "payload: 'OWNR'" (or "payload bits: 0110..." for a payload that is not text) when confirmed;
    "payload unconfirmed (N of M bits differ)" when marked but not confirmed; "no payload read" when
    not marked."""
    if v.payload_confirmed:
        return f"payload: {v.payload!r}" if v.payload is not None else f"payload bits: {v.bits}"
    if v.marked:
        return f"payload unconfirmed ({_differ(v)})"
    return "no payload read"


def payload_value(v: Verdict) -> str:
    """The payload as a short value (a panel's field): its text or bits when confirmed, else
    "unconfirmed (N of M bits differ)" or "none read"."""
    if v.payload_confirmed:
        return v.payload if v.payload is not None else v.bits
    return f"unconfirmed ({_differ(v)})" if v.marked else "none read"


def lines(v: Verdict) -> list[str]:
    """Everything the command line prints for a verdict: the headline, the scheme's notes (how the
    suspect was read when that departs from the suspect as given), the payload line."""
    return [headline(v), *v.detail.notes(), payload_line(v)]


def rows(v: Verdict) -> list[tuple[str, str]]:
    """(label, value) pairs in plain words: the verdict, its p-value, the bits that match, the payload,
    and how the scheme read the mark."""
    if v.payload_confirmed:
        payload = repr(v.payload) if v.payload is not None else "not text (see its bits)"
    else:
        payload = payload_value(v)
    out = [
        ("Verdict", "MARKED" if v.marked else "NOT MARKED"),
        ("p-value", f"{v.p_value:.3g} (threshold {v.p_threshold:g})"),
        (f"Matching {v.detail.counted}", f"{v.matches} of {v.carriers_total} ({v.bit_errors} wrong)"),
        ("Payload read", payload),
    ]
    if v.payload_confirmed:
        out.append(("Payload bits", v.bits))
    return out + v.detail.in_words()


def technical_rows(v: Verdict) -> list[tuple[str, str]]:
    """(name, value) pairs of the verdict's numbers: the reading's mode, the exact p-value, correlation,
    bits read, and the scheme's own figures."""
    return [
        ("mode", v.mode),
        ("p-value", f"{v.p_value:.6g}"),
        ("correlation", f"{v.correlation:.4f}"),
        (f"{v.detail.counted} read (not erased)", f"{v.carriers_found}/{v.carriers_total}"),
        ("payload confirmed", "yes" if v.payload_confirmed else "no"),
        *v.detail.numbers(),
    ]
