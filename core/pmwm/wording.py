"""The verdict in words, written once for every front end: the command line prints ``lines``, the
add-on shows ``headline`` and ``payload_line`` (and ``payload_value`` in its panel), the HTML report
tables ``rows`` and, in a collapsible section, ``technical_rows``. A suspect read with several keys
(``KeysVerdict``) is said by ``keys_lines``, each key's verdict in the same words under the key's name,
then the correction for the keys tried and ``keys_summary`` when several keys' marks are on the copy.

A payload is shown only when the verdict confirms it (``Verdict.payload_confirmed``): a marked
verdict whose payload is not confirmed says how many bits differ, never the text it read. What is
particular to a scheme comes from its ``Verdict.detail`` (``pmwm.base.VerdictDetail``).
"""

from __future__ import annotations

from typing import Optional, Sequence

from .base import KeysVerdict, Verdict

__all__ = [
    "headline",
    "payload_line",
    "payload_value",
    "lines",
    "rows",
    "technical_rows",
    "keys_lines",
    "keys_summary",
    "keys_correction",
    "keys_marginal",
]

DISPUTE_DOC = "docs/dispute.md"


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


# --------------------------------------------------------------------------- several keys


def _short_payload(v: Verdict) -> str:
    if v.payload_confirmed:
        return repr(v.payload) if v.payload is not None else v.bits
    return "unconfirmed"


def keys_summary(kv: KeysVerdict, names: Sequence[str]) -> Optional[str]:
    """ "this copy carries the marks of N of M keys: A (payload 'OWNR'), B (payload unconfirmed); ..." when
    at least two keys read marked (``names``: one per key), else None."""
    marked = kv.marked_keys
    if len(marked) < 2:
        return None
    who = ", ".join(f"{names[i]} (payload {_short_payload(kv.verdicts[i])})" for i in marked)
    return (
        f"this copy carries the marks of {len(marked)} of {kv.tried} keys: {who}; several owners' marks are on it, "
        f"and the files each side kept settle who marked it first ({DISPUTE_DOC})"
    )


def keys_correction(kv: KeysVerdict) -> Optional[str]:
    """What the correction for the keys tried does, when more than one key was tried, else None."""
    if kv.tried < 2:
        return None
    return (
        f"each p-value is the key's own times {kv.tried}, the keys tried (Bonferroni): trying {kv.tried} keys "
        f"on one copy makes a chance 'marked' up to {kv.tried} times likelier"
    )


def keys_marginal(kv: KeysVerdict, i: int) -> Optional[str]:
    """For key ``i`` below the threshold on its own but not after the correction: a sentence saying so;
    else None."""
    v, p = kv.verdicts[i], kv.p_single[i]
    if v.marked or not p < v.p_threshold:
        return None
    return (
        f"p = {p:.3g} with this key alone, below the threshold, but not after the correction for {kv.tried} keys: "
        "a marginal reading; verify with this key alone only if it was the one in question before reading"
    )


def keys_lines(kv: KeysVerdict, names: Sequence[str]) -> list[str]:
    """Everything the command line prints for a suspect read with several keys (``names``: one per key):
    each key's ``lines`` under its name, a marginal reading said, then the correction and the summary."""
    out = []
    for i, (name, v) in enumerate(zip(names, kv.verdicts)):
        first, *rest = lines(v)
        marginal = keys_marginal(kv, i)
        out += [f"{name}: {first}", *(f"  {line}" for line in rest), *([f"  {marginal}"] if marginal else [])]
    return out + [line for line in (keys_correction(kv), keys_summary(kv, names)) if line]
