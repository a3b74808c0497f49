"""`pmwm bench --quick`: both protocols run end to end and the report says what it measured."""

from __future__ import annotations

import json

import pmwm.cli


def test_quick_bench_writes_both_protocols(tmp_path):
    out = tmp_path / "B.md"
    rc = pmwm.cli.main(["bench", "--quick", "--keys", "1", "--no-plots", "-o", str(out)])
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
