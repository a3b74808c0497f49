"""A suspect read with several keys (``pmwm.verify_keys``, ``pmwm verify SUSPECT --key A --key B``): one
verdict per key, each p-value paying for the keys tried, a plain line when several owners' marks are on
one copy, its JSON and its report; one key reads exactly as before.

The copies: a small generated mesh marked by key A (the owner's published model), that copy marked again
by key B at the same strength (a pirate's copy), and the unmarked original; every embed seeded."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

import meshes
import pmwm
from pmwm import cli, wording

VERDICT_FIELDS = {"marked", "p_value", "p_threshold", "payload_confirmed", "bits", "payload", "matches", "mode"}


def call(*args) -> subprocess.CompletedProcess:
    """``pmwm.cli.main(ARGS)`` in this process (an exception escaping main() fails the test)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main([str(a) for a in args])
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


@pytest.fixture(scope="module")
def copies(tmp_path_factory) -> SimpleNamespace:
    """original.ply (unmarked), owner.ply (marked by A, payload OWNR), pirate.ply (owner.ply marked again
    by B at the same strength, payload PIRT), A.key.json and B.key.json."""
    d = tmp_path_factory.mktemp("multikey")
    V, F = meshes.blob()
    a = pmwm.embed(V, F, pmwm.EmbedOptions(payload="OWNR", seed=20, progressive=False))
    b = pmwm.embed(a.vertices, F, pmwm.EmbedOptions(payload="PIRT", seed=40, progressive=False))
    s = SimpleNamespace(dir=d, A=d / "A.key.json", B=d / "B.key.json", F=F)
    for name, X in (("original", V), ("owner", a.vertices), ("pirate", b.vertices)):
        pmwm.write_mesh(d / f"{name}.ply", X, F)
        setattr(s, name, d / f"{name}.ply")
    pmwm.write_key(s.A, a.key)
    pmwm.write_key(s.B, b.key)
    return s


def _read(path: Path):
    src = pmwm.read_mesh(path)
    return src.vertices, src.faces


def test_an_overmarked_copy_reads_both_keys_with_their_confirmed_payloads(copies):
    V, F = _read(copies.pirate)
    keys = [pmwm.read_key(copies.A), pmwm.read_key(copies.B)]
    kv = pmwm.verify_keys(V, F, keys)
    assert kv.tried == 2 and kv.marked_keys == [0, 1]
    assert [v.payload for v in kv.verdicts] == ["OWNR", "PIRT"]
    assert all(v.payload_confirmed for v in kv.verdicts)
    for key, v, p in zip(keys, kv.verdicts, kv.p_single):  # each key's own verdict, its p-value times 2
        alone = pmwm.verify(V, F, key)
        assert p == alone.p_value and v.p_value == 2 * alone.p_value
        assert (v.matches, v.bits, v.mode) == (alone.matches, alone.bits, alone.mode)


def test_one_key_reads_as_verify_does(copies):
    V, F = _read(copies.owner)
    key = pmwm.read_key(copies.A)
    (v,) = pmwm.verify_keys(V, F, [key]).verdicts
    assert v.to_dict() == pmwm.verify(V, F, key).to_dict()
    with pytest.raises(pmwm.PayloadError, match="at least one key"):
        pmwm.verify_keys(V, F, [])


def test_the_command_names_both_owners_of_an_overmarked_copy(copies):
    proc = call("verify", copies.pirate, "--key", copies.A, "--key", copies.B)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(f"{copies.A}: MARKED: ")
    assert "  payload: 'OWNR'" in lines and "  payload: 'PIRT'" in lines
    assert any(line.startswith(f"{copies.B}: MARKED: ") for line in lines)
    assert any("times 2, the keys tried (Bonferroni)" in line for line in lines)
    last = lines[-1]
    assert last.startswith("this copy carries the marks of 2 of 2 keys: ")
    assert f"{copies.A} (payload 'OWNR')" in last and f"{copies.B} (payload 'PIRT')" in last
    assert "several owners' marks" in last and "docs/dispute.md" in last


def test_a_copy_of_one_owner_reads_that_key_alone(copies):
    proc = call("verify", copies.owner, "--key", copies.A, "--key", copies.B)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(f"{copies.A}: MARKED: ") and "  payload: 'OWNR'" in lines
    b = [i for i, line in enumerate(lines) if line.startswith(f"{copies.B}: ")]
    assert len(b) == 1 and lines[b[0]].startswith(f"{copies.B}: not marked: ")
    assert "PIRT" not in proc.stdout and "carries the marks of" not in proc.stdout
    # the owner's original carries neither: exit 1, as one key's "not marked"
    proc = call("verify", copies.original, "--key", copies.A, "--key", copies.B)
    assert proc.returncode == 1, proc.stderr
    assert proc.stdout.count(": not marked: ") == 2 and "payload: '" not in proc.stdout


def test_the_correction_for_the_keys_tried_is_applied_and_said(copies):
    """A threshold between the key's own p-value and twice it: one key reads marked, two keys do not, and
    then its payload is not shown and the marginal reading is said."""
    V, F = _read(copies.owner)
    p = pmwm.verify(V, F, pmwm.read_key(copies.A)).p_value
    threshold = f"{1.5 * p:.6g}"
    alone = call("verify", copies.owner, "--key", copies.A, "--p-threshold", threshold)
    assert alone.returncode == 0 and "payload: 'OWNR'" in alone.stdout
    both = call("verify", copies.owner, "--key", copies.A, "--key", copies.B, "--p-threshold", threshold)
    assert both.returncode == 1, both.stdout
    lines = both.stdout.splitlines()
    assert lines[0].startswith(f"{copies.A}: not marked: ") and "OWNR" not in both.stdout
    assert any("with this key alone, below the threshold, but not after the correction for 2 keys" in x for x in lines)


def test_the_json_of_several_keys_holds_each_keys_verdict(copies):
    proc = call("verify", copies.owner, "--key", copies.A, "--key", copies.B, "--json")
    assert proc.returncode == 0, proc.stderr
    (line,) = proc.stdout.strip().splitlines()
    doc = json.loads(line)
    assert (doc["keys_tried"], doc["keys_marked"]) == (2, 1) and "Bonferroni" in doc["correction"]
    a, b = doc["verdicts"]
    assert (a["key"], b["key"]) == (str(copies.A), str(copies.B))
    assert VERDICT_FIELDS | {"p_value_single_key"} <= set(a) and set(a) == set(b)
    assert a["marked"] and a["payload"] == "OWNR" and a["p_value"] == 2 * a["p_value_single_key"]
    assert not b["marked"] and b["payload"] is None and b["bits"] is None


def test_one_key_prints_and_writes_json_as_before(copies):
    """With one --key the command prints ``wording.lines`` of ``pmwm.verify``'s verdict, and its JSON is
    that verdict's ``to_dict()``: nothing of the several keys' output."""
    V, F = _read(copies.pirate)
    v = pmwm.verify(V, F, pmwm.read_key(copies.A))
    proc = call("verify", copies.pirate, "--key", copies.A)
    assert proc.returncode == 0 and proc.stdout.splitlines() == wording.lines(v)
    proc = call("verify", copies.pirate, "--key", copies.A, "--json")
    assert json.loads(proc.stdout) == json.loads(json.dumps(v.to_dict()))


def test_the_report_of_several_keys_has_a_summary_and_a_section_per_key(copies):
    out = copies.dir / "pirate.html"
    proc = call("verify", copies.pirate, "--key", copies.A, "--key", copies.B, "--report", out)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1] == f"report -> {out}"
    html = out.read_text()
    summary = html.split('<p id="summary">', 1)[1].split("</p>", 1)[0]
    assert "This copy carries the marks of 2 of 2 keys: A.key.json (payload &#x27;OWNR&#x27;)" in summary
    assert "B.key.json (payload &#x27;PIRT&#x27;)" in summary
    one, two = html.split('<section id="key-1">', 1)[1].split('<section id="key-2">', 1)
    assert "<h2>Key 1 of 2: A.key.json</h2>" in one and "<h2>Key 2 of 2: B.key.json</h2>" in two
    assert '<div id="verdict-1" class="verdict marked">MARKED</div>' in one and "&#x27;OWNR&#x27;" in one
    assert '<div id="verdict-2" class="verdict marked">MARKED</div>' in two and "&#x27;PIRT&#x27;" in two
    assert html.count("data:image/png;base64,") == 6  # each key's three views

    out = copies.dir / "owner.html"
    assert call("verify", copies.owner, "--key", copies.A, "--key", copies.B, "--report", out).returncode == 0
    html = out.read_text()
    assert "the mark of 1 of the 2 keys: A.key.json (payload OWNR)" in html
    assert '<div id="verdict-2" class="verdict notmarked">NOT MARKED</div>' in html and "PIRT" not in html


@pytest.mark.parametrize(
    "extra, mention",
    [(("--key", "{A}"), "given twice"), (("--passphrase-file", "{A}"), "not both")],
)
def test_several_keys_refuse_a_key_twice_and_a_pass_phrase(copies, extra, mention):
    args = [a.format(A=copies.A) for a in extra]
    proc = call("verify", copies.owner, "--key", copies.A, "--key", copies.B, *args)
    assert proc.returncode == 2 and proc.stderr.startswith("pmwm: error:") and mention in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_several_keys_refuse_a_scene_of_several_objects(copies):
    """Several keys read one mesh: a suspect of two objects gets one line saying to read it with one key."""
    V, F = meshes.blob()
    scene = copies.dir / "two.obj"
    with open(scene, "w") as fh:
        for i, name in enumerate("AB"):
            fh.write(f"o {name}\n" + "".join(f"v {x + 3 * i} {y} {z}\n" for x, y, z in V))
            fh.write("".join(f"f {a} {b} {c}\n" for a, b, c in F + 1 + len(V) * i))
    proc = call("verify", scene, "--key", copies.A, "--key", copies.B)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.strip() == (
        f"pmwm: error: several --key read one mesh; {scene} holds 2 objects: verify a scene with one key at a time"
    )
