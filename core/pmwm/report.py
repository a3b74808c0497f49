"""Markdown reports made of named sections, so several benchmarks can share one BENCHMARKS.md."""

from __future__ import annotations

import re
from pathlib import Path

from .meshio import atomic_write_bytes

HEADER = "# Benchmarks\n\nFigures from real runs; each section names its command and machine.\n"


def write_section(path, name: str, body: str) -> None:
    """Replace (or append) the section ``name`` of the markdown file ``path``, atomically."""
    path = Path(path)
    start, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    text = path.read_text(encoding="utf-8") if path.exists() else HEADER
    block = f"{start}\n{body.rstrip()}\n{end}"
    if start in text and end in text:
        text = re.sub(re.escape(start) + r".*?" + re.escape(end), lambda m: block, text, flags=re.S)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    atomic_write_bytes(path, text.encode("utf-8"), force=True)
