"""Markdown reports made of named sections, and the provenance every section states.

A section is written either as a fragment of its own, ``NAME.md`` (the file's stem is the section's
name: the whole file is the section; this checkout's benchmarks write ``benchmarks/results/NAME.md`` and
``benchmarks/report.py`` assembles the report from them), or as the block between ``<!-- bench:NAME -->``
and ``<!-- /bench:NAME -->`` of a markdown file that several sections share (``pmwm bench -o
REPORT.md``), rewriting only that block. Raw results and plots of a section go to the folder ``NAME/``
beside a fragment, ``<report stem>-<section>/`` beside a shared file. Every section names its command,
the commit of the code measured and the machine (``commit()``, ``machine()``).
"""

from __future__ import annotations

import os
import platform
import re
import subprocess
from pathlib import Path
from typing import Union

from pmwm.atomic import atomic_write_bytes

HEADER = "# Benchmarks\n\nFigures from real runs; each section names its command and machine.\n"

PathLike = Union[str, os.PathLike]


def is_fragment(path: PathLike, name: str) -> bool:
    """Whether ``path`` is the fragment of section ``name`` (its stem is the name): the whole file is it."""
    return Path(path).stem == name


def write_section(path: PathLike, name: str, body: str) -> None:
    """Replace (or append) the section ``name`` of the markdown file ``path``, atomically; when ``path``
    is the section's fragment (``is_fragment``), the file becomes ``body``."""
    path = Path(path)
    if is_fragment(path, name):
        atomic_write_bytes(path, (body.rstrip() + "\n").encode("utf-8"), force=True)
        return
    start, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    text = path.read_text(encoding="utf-8") if path.exists() else HEADER
    block = f"{start}\n{body.rstrip()}\n{end}"
    if start in text and end in text:
        text = re.sub(re.escape(start) + r".*?" + re.escape(end), lambda m: block, text, flags=re.S)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    atomic_write_bytes(path, text.encode("utf-8"), force=True)


def raw_folder_path(report: PathLike, section: str) -> Path:
    """Where raw JSON and plots of a section go: ``<section>/`` beside the section's fragment
    ``<section>.md``, else ``<report stem>-<section>/`` beside the shared report."""
    report = Path(report)
    return report.with_suffix("") if is_fragment(report, section) else report.with_name(f"{report.stem}-{section}")


def raw_folder(report: PathLike, section: str) -> Path:
    """``raw_folder_path(report, section)``, created."""
    folder = raw_folder_path(report, section)
    folder.mkdir(exist_ok=True)
    return folder


def machine() -> str:
    """One line naming the machine the figures come from (CPU, cores, RAM, Python, numpy, OS)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        mem = f", {kb / 2**20:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    import numpy

    return (
        f"{cpu}, {os.cpu_count()} cores{mem}; Python {platform.python_version()}, "
        f"numpy {numpy.__version__}, {platform.system()} {platform.release()}"
    )


def commit() -> str:
    """The short commit of the pmwm code measured (the git checkout holding the imported ``pmwm``),
    with " + uncommitted changes" when its tracked sources differ from that commit; "unknown" outside
    a checkout (an installed wheel)."""
    import pmwm

    where = Path(pmwm.__file__).resolve().parent.parent  # core/ in a checkout

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(where), *args], capture_output=True, text=True, check=True, timeout=30
        ).stdout.strip()

    try:
        head = git("rev-parse", "--short", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", ".")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head + (" + uncommitted changes" if dirty else "")


__all__ = ["HEADER", "commit", "is_fragment", "machine", "raw_folder", "raw_folder_path", "write_section"]
