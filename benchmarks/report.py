"""Assemble the benchmark report, docs/benchmarks.md, from the section fragments in benchmarks/results/.

Run: python benchmarks/report.py            (writes docs/benchmarks.md)
     python benchmarks/report.py --check    (exit 1 when docs/benchmarks.md is not what the fragments give)

Each benchmark script writes its section as a fragment ``benchmarks/results/NAME.md`` (its raw data and plots
in ``benchmarks/results/NAME/``); nothing here measures. The report takes the fragments in the fixed order of
``SECTIONS``, under a title of its own, keeping of the long ones their opening (command, commit, machine) and the
sub-tables named, and links every fragment in full; a fragment that is not in ``SECTIONS`` is linked at the end.
The report stays within ``MAX_LINES`` lines (a ValueError otherwise: shorten a section's share here).
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from pmwm.atomic import atomic_write_bytes

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
REPORT = ROOT / "docs" / "benchmarks.md"
MAX_LINES = 600
#: a heading named by a work-log label or an issue number (the report's headings name what they measure)
BAD_HEADING = re.compile(r"\bsession\b|-s\d+\b|\bissues?\b|#\d+|\b(?:first|second|third|\w+th) session", re.I)


@dataclass(frozen=True)
class Section:
    """One section of the report: the fragment ``name``, shown under ``title``.

    keep:  sub-headings (their text's start) whose blocks are shown; None: all of them. The text before
           the first sub-heading (command, commit, machine) is always shown.
    paras: paragraphs (their text's start) shown, each with the tables that follow it; None: all of them.
    cap:   at most this many lines of the fragment (whole paragraphs and tables); None: no cap.
    note:  a line shown first (e.g. which meshes the method was tuned on).
    plots: PNG files of the raw folder shown as images.
    """

    name: str
    title: str
    keep: tuple[str, ...] | None = None
    paras: tuple[str, ...] | None = None
    cap: int | None = None
    note: str = ""
    plots: tuple[str, ...] = ()


TUNING = (
    "Tuning meshes: the figures below are measured on the meshes the methods were tuned on (bunny, dragon, "
    "Venus head, Igea); they are not held-out figures."
)

#: the report's order; the fragments' own figures, as the scripts wrote them
SECTIONS: tuple[Section, ...] = (
    Section("heldout", "Held out: meshes no method was tuned on"),
    Section("pose", "Any pose, any copy: near-symmetric shapes never tuned on"),
    Section(
        "robustness",
        "Robustness: both protocols, pmwm against Cho et al. 2007",
        keep=("Benchmark protocol", "Distortion of the 64-bit", "BER — bunny"),
        note=TUNING,
        plots=("correlation_bunny_benchmark.png",),
    ),
    Section(
        "equal-distortion",
        "Equal distortion: BER against embedding MRMS",
        keep=("Which method",),
        note=TUNING,
        plots=("ber_vs_mrms_noise.png",),
    ),
    Section(
        "equal-distortion-paper-noise",
        "Equal distortion under the paper's heavy noise",
        keep=("Which method",),
        note=TUNING,
    ),
    Section(
        "robust",
        "The keyed schemes under each attack, every level of detail, false positives",
        keep=("bunny", "False positives"),
        cap=45,
        note=TUNING,
    ),
    Section(
        "blind",
        "Blind histogram carrier: read with a pass phrase alone",
        note=TUNING,
        paras=("Command:", "Whole payload read"),
    ),
    Section("blind-equal-mrms", "Blind histogram carrier against Cho I and II at equal MRMS", note=TUNING),
    Section(
        "blind-attacks",
        "Blind histogram carrier against an attacker without the pass phrase",
        paras=("Command:", "Strip:", "Overmarking:"),
        plots=("curve.png",),
    ),
    Section("blind-waves-attacks", "Blind keyed waves against an attacker without the pass phrase"),
    Section("fingerprint", "Fingerprinting: tracing and collusion", keep=("Per-copy cost", "Averaging collusion")),
    Section("robust-selfcheck", "The robust embed reads its own output back", keep=()),
    Section("core", "Speed and size"),
    Section("scale", "One million faces"),
    Section("pm-speed", "Progressive mesh speed", cap=18),
    Section("verify-speed-cli", "Verify speed, `pmwm verify` as the user runs it"),
    Section("verify-speed-blind-cli", "Verify speed of the blind scheme, `pmwm verify` as the user runs it", cap=24),
    Section("addon", "The Blender add-on against the core"),
)

HEADER = """# Benchmarks

Figures from real runs, generated: each section below is a fragment of `benchmarks/results/` written by the
script its first line names, with the commit of the code measured and the machine; long sections show their
main tables here and link the fragment in full. Rebuild with `python benchmarks/report.py` after a benchmark
ran (`tests/test_benchmark_report.py` checks that this file is up to date). Meshes: the Stanford bunny and
dragon, a Venus head and Igea (`pmwm_bench.models`); MRMS and Hausdorff are surface distances in % of the
bounding-box diagonal (`pmwm.metrics`). What was tried and measured on the way is in [decisions/](decisions/).
"""


def link(name: str) -> str:
    """The markdown link, from docs/, to the fragment ``name``."""
    return f"[benchmarks/results/{name}.md](../benchmarks/results/{name}.md)"


def split_fragment(text: str) -> tuple[str, list[tuple[str, list[str]]]]:
    """(the fragment's own title, [(sub-heading or "" for the opening, its lines)]); the title is its first
    ``## `` line, wherever it stands."""
    lines = text.rstrip("\n").split("\n")
    title = next((ln for ln in lines if ln.startswith("## ")), "")
    if title:
        lines.remove(title)
    parts: list[tuple[str, list[str]]] = [("", [])]
    for ln in lines:
        if ln.startswith("### ") or ln.startswith("#### "):
            parts.append((ln.lstrip("#").strip(), [ln]))
        else:
            parts[-1][1].append(ln)
    return title[3:].strip(), parts


def blocks(lines: list[str]) -> list[list[str]]:
    """The runs of non-blank lines of ``lines`` (paragraphs, tables, lists)."""
    out: list[list[str]] = []
    block: list[str] = []
    for ln in [*lines, ""]:
        if ln.strip():
            block.append(ln)
        elif block:
            out.append(block)
            block = []
    return out


def chosen(lines: list[str], paras: tuple[str, ...]) -> tuple[list[str], bool]:
    """The paragraphs of ``lines`` that start with one of ``paras``, each with the tables after it, and
    whether anything was left out."""
    out: list[str] = []
    showing, omitted = False, False
    for block in blocks(lines):
        if not block[0].startswith("|"):
            showing = block[0].startswith(paras)
        if showing:
            out += block + [""]
        else:
            omitted = True
    return out, omitted


def capped(lines: list[str], cap: int) -> tuple[list[str], bool]:
    """The first whole blocks (paragraphs, tables: runs of non-blank lines) of ``lines`` within ``cap`` lines,
    and whether anything was left out."""
    out: list[str] = []
    block: list[str] = []
    for ln in [*lines, ""]:
        if ln.strip():
            block.append(ln)
            continue
        if block:
            if len(out) + len(block) + 1 > cap:
                return out, True
            out += block + [""]
            block = []
    return out, False


def render_section(s: Section) -> list[str]:
    """The report's lines for section ``s``."""
    path = RESULTS / f"{s.name}.md"
    out = [f"## {s.title}", ""]
    if s.note:
        out += [f"*{s.note}*", ""]
    if not path.exists():
        return out + [f"Not measured yet: its fragment {link(s.name)} is missing.", ""]
    _title, parts = split_fragment(path.read_text(encoding="utf-8"))
    shown: list[str] = []
    omitted = False
    for heading, lines in parts:
        if heading and s.keep is not None and not heading.startswith(s.keep):
            omitted = True
            continue
        shown += lines
    if s.paras is not None:
        shown, cut = chosen(shown, s.paras)
        omitted |= cut
    if s.cap is not None:
        shown, cut = capped(shown, s.cap)
        omitted |= cut
    while shown and not shown[-1].strip():
        shown.pop()
    while shown and not shown[0].strip():
        shown.pop(0)
    out += shown + [""]
    raw = RESULTS / s.name
    for png in s.plots:
        if (raw / png).exists():
            out += [f"![{png}](../benchmarks/results/{s.name}/{png})", ""]
    more = "Every table of this section" if omitted else "The section as written"
    extra = ""
    if raw.is_dir():
        extra = f"; raw data and plots: [benchmarks/results/{s.name}/](../benchmarks/results/{s.name}/)"
    out += [f"{more}: {link(s.name)}{extra}.", ""]
    return out


def render() -> str:
    """The whole report."""
    named = {s.name for s in SECTIONS}
    others = sorted(p.stem for p in RESULTS.glob("*.md") if p.stem not in named)
    lines = HEADER.rstrip("\n").split("\n") + [""]
    lines += ["Contents: " + ", ".join(f"[{s.title}](#{anchor(s.title)})" for s in SECTIONS) + ".", ""]
    for s in SECTIONS:
        lines += render_section(s)
    if others:
        lines += ["## More sections", "", "Measured and kept in full, not shown here:", ""]
        for name in others:
            title, _parts = split_fragment((RESULTS / f"{name}.md").read_text(encoding="utf-8"))
            lines.append(f"- {BAD_HEADING.sub('', title).strip(' ,:') or name}: {link(name)}")
        lines.append("")
    text = "\n".join(lines).rstrip("\n") + "\n"
    check(text)
    return text


def anchor(title: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def check(text: str) -> None:
    """ValueError when ``text`` is over ``MAX_LINES`` lines or has a heading named by a work-log label or an
    issue number."""
    n = text.count("\n")
    if n > MAX_LINES:
        raise ValueError(f"the report has {n} lines, over {MAX_LINES}: shorten a section's share in SECTIONS")
    bad = [ln for ln in text.split("\n") if ln.startswith("#") and BAD_HEADING.search(ln)]
    if bad:
        raise ValueError(f"headings named by a work-log label or an issue number: {bad}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 when the report is not up to date")
    a = ap.parse_args(argv)
    text = render()
    if a.check:
        current = REPORT.read_text(encoding="utf-8") if REPORT.exists() else ""
        if current != text:
            print(
                f"{REPORT.relative_to(ROOT)} is not up to date with benchmarks/results/: "
                "run python benchmarks/report.py",
                file=sys.stderr,
            )
            return 1
        return 0
    atomic_write_bytes(REPORT, text.encode("utf-8"), force=True)
    print(f"wrote {REPORT.relative_to(ROOT)} ({text.count(chr(10))} lines)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
