"""`pmwm bench`: both protocols run end to end and the report says what it measured; the
equal-distortion sweep writes its tables, one computed verdict per attack and one plot per attack.

The runs use the bunny packaged with pmwm (no data folder), so they work from a clone alone.
"""

from __future__ import annotations

import importlib.metadata
import json

import numpy as np
import pytest

import pmwm.cli
import pmwm_bench.cli
from pmwm_bench.markdown import verdict_line
from pmwm_bench.sweep import QUICK_ATTACKS, SWEEP_ATTACKS, compare_at_equal_mrms


@pytest.fixture(autouse=True)
def _packaged_bunny_only(monkeypatch):
    """The named models resolve to the bunny shipped with pmwm, whatever the environment says."""
    monkeypatch.delenv("PMWM_BENCH_DATA", raising=False)


def test_bench_is_the_pmwm_commands_plugin(capsys):
    eps = list(importlib.metadata.entry_points(group="pmwm.commands", name="bench"))
    assert [ep.value for ep in eps] == ["pmwm_bench.cli:main"]
    with pytest.raises(SystemExit) as exit_info:  # `pmwm bench --help` reaches pmwm_bench's parser
        pmwm.cli.main(["bench", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "--sweep" in out and "pmwm bench --sweep --models bunny,dragon" in out


@pytest.mark.slow
def test_quick_bench_writes_both_protocols(tmp_path):
    out = tmp_path / "B.md"
    rc = pmwm_bench.cli.main(["--quick", "--keys", "1", "--no-plots", "-o", str(out)])
    assert rc == 0
    text = out.read_text()
    for heading in ("Table 1", "Table 2", "Table 3", "Table 4", "Benchmark protocol"):
        assert heading in text
    assert "<!-- bench:robustness -->" in text
    trials = json.loads((tmp_path / "B-robustness" / "trials.json").read_text())["trials"]
    methods = {t["method"] for t in trials}
    assert {"pmwm", "pmwm-paper", "Cho I", "Cho II"} <= methods
    by = {(t["method"], t["group"]): t for t in trials if t["protocol"] == "benchmark"}
    # element reordering destroys neither method; Cho's histogram also survives a similarity transform
    for m in ("pmwm", "pmwm-paper", "Cho I", "Cho II"):
        assert by[(m, "reordering")]["ber"] == 0.0
    assert by[("Cho I", "similarity")]["ber"] == 0.0
    # the default (robust) scheme registers the copy first: a similarity transform does not defeat it
    assert by[("pmwm", "similarity")]["ber"] == 0.0
    # mild paper-protocol smoothing: both our schemes still read far better than chance
    for m in ("pmwm", "pmwm-paper"):
        smooth = [t for t in trials if t["protocol"] == "paper" and t["group"] == "smoothing" and t["method"] == m]
        assert smooth and max(t["correlation"] for t in smooth) > 0.8
    # every distortion row of both protocols carries MRMS, Hausdorff and vertex RMSE
    report = json.loads((tmp_path / "B-robustness" / "trials.json").read_text())["distortions"]
    for d in report:
        if d["protocol"] in ("paper", "benchmark"):
            assert d["mrms_percent"] > 0 and d["hausdorff_percent"] > 0 and d["rmse_percent"] > 0
    assert "vertex RMSE (% diag)" in text and text.count("MRMS (% diag)") >= 2


@pytest.mark.slow
def test_quick_sweep_writes_tables_verdicts_and_one_plot_per_attack(tmp_path):
    out = tmp_path / "B.md"
    out.write_text("# Benchmarks\n\n<!-- bench:other -->\nkept\n<!-- /bench:other -->\n")
    rc = pmwm_bench.cli.main(["--sweep", "--quick", "-o", str(out)])
    assert rc == 0
    text = out.read_text()
    assert "<!-- bench:equal-distortion -->" in text and "kept" in text  # its own section, others kept
    assert "Command: `pmwm bench --sweep --quick -o " in text and "commit " in text and "Machine: " in text
    labels = {a.key: a.label for a in SWEEP_ATTACKS}
    verdicts = [ln for ln in text.splitlines() if ln.startswith("- **")]
    assert len(verdicts) == len(QUICK_ATTACKS)  # one line per attack
    for key in QUICK_ATTACKS:
        line = next(ln for ln in verdicts if ln.startswith(f"- **{labels[key]}**:"))
        assert "bunny: " in line and ("over MRMS" in line or "no overlap" in line)
        assert f"### {labels[key]}: BER against MRMS" in text
        assert (tmp_path / "B-equal-distortion" / f"ber_vs_mrms_{key}.png").stat().st_size > 0
    assert sorted(p.name for p in (tmp_path / "B-equal-distortion").glob("*.png")) == sorted(
        f"ber_vs_mrms_{k}.png" for k in QUICK_ATTACKS
    )
    # the table: every method at both of its strengths, MRMS and BER per model
    for method in ("pmwm", "pmwm-paper", "Cho I", "Cho II", "pmwm-blind"):  # every scheme, the blind one too
        assert sum(1 for ln in text.splitlines() if ln.startswith(f"| {method} |")) == 2 * len(QUICK_ATTACKS)
    raw = json.loads((tmp_path / "B-equal-distortion" / "sweep.json").read_text())
    assert len(raw["embeddings"]) == 5 * 2 and len(raw["trials"]) == 5 * 2 * len(QUICK_ATTACKS)
    by_method: dict[str, list[tuple[float, float]]] = {}
    for e in raw["embeddings"]:
        assert e["mrms_percent"] > 0 and e["n_bits"] == 64
        by_method.setdefault(e["method"], []).append((e["strength"], e["mrms_percent"]))
    for pts in by_method.values():  # a higher strength distorts more
        (s0, m0), (s1, m1) = sorted(pts)
        assert s0 < s1 and m0 < m1
    assert all(0.0 <= t["ber"] <= 1.0 for t in raw["trials"])
    # the blind scheme reads its 64-bit payload blind (pass phrase only) at its higher strength
    blind = {t["attack"]: t["ber"] for t in raw["trials"] if t["method"] == "pmwm-blind" and t["strength"] == 0.12}
    assert blind["noise"] == 0.0 and blind["quantization"] < 0.1


def test_compare_at_equal_mrms_interpolates_inside_the_overlap_only():
    curves = {  # method -> (MRMS, BER) per strength
        "A": (np.array([0.01, 0.02, 0.04]), np.array([0.30, 0.20, 0.10])),
        "B": (np.array([0.05, 0.02, 0.005]), np.array([0.0, 0.05, 0.10])),  # any order of strengths
    }
    c = compare_at_equal_mrms(curves, tolerance=1 / 320, attack="noise", model="bunny")
    assert c.overlap == pytest.approx((0.01, 0.04))
    assert c.winner == "B" and c.tied == ["B"] and c.ranking == ["B", "A"] and c.lowest_share == 1.0
    # at MRMS 0.02 (a grid end of neither) A reads 0.20 and B 0.05; the averages lie between the ends
    assert 0.1 < c.mean_ber["A"] < 0.3 and 0.0 < c.mean_ber["B"] < 0.1
    line = verdict_line("noise 0.3 %", [c])
    assert line.startswith("- **noise 0.3 %**: bunny: **B** (over MRMS 0.0100–0.0400 %") and "lowest on 100 %" in line

    # curves that cross: each method wins part of the overlap
    cross = {"A": (np.array([0.01, 0.04]), np.array([0.0, 0.4])), "B": (np.array([0.01, 0.04]), np.array([0.3, 0.1]))}
    c = compare_at_equal_mrms(cross, tolerance=0.0)
    assert 0.0 < c.lowest_share < 1.0

    # the same curve twice: a tie, named as such
    same = {"A": curves["A"], "C": curves["A"]}
    c = compare_at_equal_mrms(same, tolerance=1 / 320, model="dragon")
    assert c.tied == ["A", "C"] and "tie between **A** and **C**" in verdict_line("x", [c])

    # every method at chance at every strength: no winner is named
    c = compare_at_equal_mrms(curves, tolerance=1 / 320, model="bunny")
    c.at_chance = ["A", "B"]
    assert "bunny: none: every method reads at chance" in verdict_line("x", [c])

    # disjoint MRMS ranges: nothing is extrapolated
    apart = {"A": (np.array([0.01, 0.02]), np.array([0.2, 0.1])), "B": (np.array([0.03, 0.04]), np.array([0.0, 0.0]))}
    c = compare_at_equal_mrms(apart, model="bunny")
    assert c.overlap is None and c.winner is None
    assert "bunny: no overlap" in verdict_line("x", [c])
