"""The verdict in the panel's words: the rows of the verdict box, its numbers, the one-line report.

Everything comes from ``pmwm.wording`` (the words every front end shares); the add-on only picks
which rows its box shows. A payload is shown only when the verdict confirms it.
"""

from __future__ import annotations

# Rows of wording.rows left out of the sidebar's box (too long for it; the report has them).
LEFT_OUT = {"Payload bits"}


def box_rows(v) -> list[tuple[str, str]]:
    """(label, value) rows of the verdict box in plain words."""
    from pmwm import wording

    return [(k, val) for k, val in wording.rows(v) if k not in LEFT_OUT]


def numbers(v) -> list[tuple[str, str]]:
    """(name, value) rows of the verdict's figures, for the box's closed Numbers section."""
    from pmwm import wording

    return wording.technical_rows(v)


def report_line(v) -> str:
    """The verdict in one line for Blender's report: headline, how it was read, payload line."""
    from pmwm import wording

    return "; ".join(wording.lines(v))


def confirmed_payload(v) -> str:
    """The payload text when the verdict confirms it, else "" (what scripts read)."""
    return v.payload if v.payload_confirmed and v.payload is not None else ""
