"""The benchmark report (docs/benchmarks.md): generated from the fragments in benchmarks/results/, up to date,
readable (at most 600 lines, no heading named by a work-log label or an issue number), and no result folder at
the top of the checkout."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from pmwm_bench.report import raw_folder, write_section

ROOT = Path(__file__).resolve().parents[1]


def generator():
    spec = importlib.util.spec_from_file_location("bench_report", ROOT / "benchmarks" / "report.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_the_report_is_what_its_fragments_give():
    gen = generator()
    text = gen.render()
    assert gen.REPORT.read_text(encoding="utf-8") == text, "run: python benchmarks/report.py"
    assert text.count("\n") <= 600
    headings = [ln for ln in text.split("\n") if ln.startswith("#")]
    assert not [h for h in headings if gen.BAD_HEADING.search(h)]
    for s in gen.SECTIONS:  # every section the report names has its fragment, and names its command
        fragment = gen.RESULTS / f"{s.name}.md"
        assert fragment.exists(), fragment
        assert "ommand" in fragment.read_text(encoding="utf-8") or s.name == "heldout", s.name


def test_the_check_refuses_long_reports_and_work_log_headings():
    gen = generator()
    for bad in (
        "## Blind scheme (issue 14)",
        "## The crop search (twenty-sixth session)",
        "### session-31",
        "## blind-s18 figures",
    ):
        with pytest.raises(ValueError, match="work-log"):
            gen.check(f"# Benchmarks\n\n{bad}\n")
    with pytest.raises(ValueError, match="lines"):
        gen.check("x\n" * 601)
    gen.check("# Benchmarks\n\n## Verify speed: the blind scheme\n")


def test_no_result_folder_at_the_top_and_the_raw_data_under_results():
    assert not list(ROOT.glob("BENCHMARKS*")), "results belong in benchmarks/results/"
    for name in ("robustness", "robustness-igea", "equal-distortion", "equal-distortion-paper-noise", "fingerprint"):
        folder = ROOT / "benchmarks" / "results" / name
        assert folder.is_dir() and any(folder.glob("*.json")), folder


def test_a_fragment_is_its_section_alone_and_a_shared_file_keeps_the_others(tmp_path):
    fragment = tmp_path / "speed.md"
    write_section(fragment, "speed", "## Speed\n\nfast\n")
    write_section(fragment, "speed", "## Speed\n\nfaster\n")
    assert fragment.read_text() == "## Speed\n\nfaster\n"
    assert raw_folder(fragment, "speed") == tmp_path / "speed" and (tmp_path / "speed").is_dir()
    shared = tmp_path / "REPORT.md"
    write_section(shared, "a", "## A\n\none")
    write_section(shared, "b", "## B\n\ntwo")
    write_section(shared, "a", "## A\n\nthree")
    text = shared.read_text()
    assert "three" in text and "two" in text and "one" not in text
    assert raw_folder(shared, "a") == tmp_path / "REPORT-a"
