"""`pmwm bench --quick`: both protocols run end to end and the report says what it measured."""

from __future__ import annotations

import json

import pmwm.cli


def test_quick_bench_writes_both_protocols(tmp_path):
    out = tmp_path / "B.md"
    rc = pmwm.cli.main(["bench", "--quick", "--keys", "1", "--no-plots", "--with-robust", "-o", str(out)])
    assert rc == 0
    text = out.read_text()
    for heading in ("Table 1", "Table 2", "Table 3", "Table 4", "Benchmark protocol"):
        assert heading in text
    assert "<!-- bench:robustness -->" in text
    trials = json.loads((tmp_path / "B-robustness" / "trials.json").read_text())["trials"]
    methods = {t["method"] for t in trials}
    assert {"pmwm", "Cho I", "Cho II", "pmwm-robust"} <= methods
    by = {(t["method"], t["group"]): t for t in trials if t["protocol"] == "benchmark"}
    # element reordering destroys neither method; Cho's histogram also survives a similarity transform
    for m in ("pmwm", "Cho I", "Cho II", "pmwm-robust"):
        assert by[(m, "reordering")]["ber"] == 0.0
    assert by[("Cho I", "similarity")]["ber"] == 0.0
    # the robust scheme registers the copy first: a similarity transform no longer defeats it
    assert by[("pmwm-robust", "similarity")]["ber"] == 0.0
    # mild paper-protocol smoothing: our scheme still reads far better than chance
    smooth = [t for t in trials if t["protocol"] == "paper" and t["group"] == "smoothing" and t["method"] == "pmwm"]
    assert smooth and max(t["correlation"] for t in smooth) > 0.8
