"""The pmwm command line as a user runs it: what it writes, what it prints, its exit codes
(0 marked / done, 1 not marked, 2 error), one-line errors, and nothing left behind on failure."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

import meshes
import pmwm
from pmwm import cli

COW = meshes.mesh_file("blob.off")  # a small closed organic mesh (2.9k vertices), generated
PAYLOAD = "test"
VERDICT_FIELDS = {
    "marked",
    "p_value",
    "bits",
    "payload",
    "matches",
    "bit_errors",
    "correlation",
    "carriers_found",
    "carriers_total",
    "payload_confirmed",
}


def run(*args, umask: int | None = None) -> subprocess.CompletedProcess:
    """``python -m pmwm ARGS`` as a user would run it."""
    pre = (lambda: os.umask(umask)) if umask is not None else None
    return subprocess.run(
        [sys.executable, "-m", "pmwm", *map(str, args)], capture_output=True, text=True, timeout=300, preexec_fn=pre
    )


def call(*args) -> subprocess.CompletedProcess:
    """``pmwm.cli.main(ARGS)`` in this process: the same exit code and output, much faster.
    An exception escaping main() (a traceback for the user) fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main([str(a) for a in args])
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def assert_error(proc: subprocess.CompletedProcess, *mentions: str) -> str:
    """Exit 2 and exactly one stderr line ``pmwm: error: ...`` naming the problem; no traceback."""
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("pmwm: error:"), lines[0]
    for word in mentions:
        assert word.lower() in lines[0].lower(), (word, lines[0])
    return lines[0]


def fails_cleanly(out: Path, *args, mentions: tuple[str, ...] = (), real: bool = False) -> str:
    """Run a command that must fail (in a real process if ``real``); the output folder must be
    exactly as before: no partial or temporary file."""
    before = listing(out)
    line = assert_error((run if real else call)(*args), *mentions)
    assert listing(out) == before
    return line


def verdict(*args, real: bool = False) -> tuple[int, dict]:
    proc = (run if real else call)("verify", *args, "--json")
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 1, proc.stdout  # one JSON object
    return proc.returncode, json.loads(lines[0])


def vertex_count(path: Path) -> int:
    return len(trimesh.load(path, process=False, force="mesh").vertices)


def sorted_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


# ---------------------------------------------------------------- one marked sample per module


@pytest.fixture(scope="module")
def sample(tmp_path_factory) -> SimpleNamespace:
    """The small mesh COW (2.9k vertices) marked once with --seed 1 --payload test, under a permissive umask."""
    d = tmp_path_factory.mktemp("sample")
    s = SimpleNamespace(dir=d, mesh=d / "cow_marked.ply", key=d / "cow.key.json", pm=d / "cow.pmwm")
    s.proc = run("embed", COW, "-o", s.mesh, "--key", s.key, "--pm", s.pm, "--seed", 1, "--payload", PAYLOAD, umask=0)
    assert s.proc.returncode == 0, s.proc.stderr
    return s


@pytest.fixture(scope="module")
def other_key(tmp_path_factory) -> Path:
    """The key of the same mesh marked with another seed."""
    d = tmp_path_factory.mktemp("other")
    proc = run(
        "embed", COW, "-o", d / "cow2.ply", "--key", d / "cow2.key.json", "--seed", 2, "--payload", PAYLOAD, "-q"
    )
    assert proc.returncode == 0, proc.stderr
    return d / "cow2.key.json"


@pytest.fixture(scope="module")
def bad(tmp_path_factory, sample) -> SimpleNamespace:
    """Damaged inputs: garbage mesh, directory, wrong extension, broken keys and .pmwm files."""
    d = tmp_path_factory.mktemp("bad")
    b = SimpleNamespace(dir=d)
    rng = np.random.default_rng(0)
    b.garbage = d / "garbage.ply"
    b.garbage.write_bytes(rng.integers(0, 256, 4000, dtype=np.uint8).tobytes())
    b.folder = d / "folder.obj"
    b.folder.mkdir()
    b.xyz = d / "cow.xyz"
    shutil.copy(COW, b.xyz)
    doc = json.loads(sample.key.read_text())

    def key(name: str, text: str) -> Path:
        (d / name).write_text(text)
        return d / name

    b.key_text = key("text.key.json", "this is not JSON\n")
    b.key_empty = key("empty.key.json", "")
    b.key_binary = d / "binary.key.json"
    b.key_binary.write_bytes(b"\xff\xfe\x00garbage")
    b.key_future = key("future.key.json", json.dumps({**doc, "version": doc["version"] + 1}))
    b.key_missing = {}
    for field in ("secret", "carriers", "bits", "mesh"):
        b.key_missing[field] = key(f"no-{field}.key.json", json.dumps({k: v for k, v in doc.items() if k != field}))
    b.key_deep = key("deep.key.json", "[" * 100_000)
    inf = json.loads(json.dumps(doc))
    inf["mesh"]["n_vertices"] = "@INF@"
    b.key_inf = key("inf.key.json", json.dumps(inf).replace('"@INF@"', "1e400"))
    neg = json.loads(json.dumps(doc))
    neg["carriers"][0][0] = neg["carriers"][0][1] = -1_000_000_000
    b.key_negative = key("negative.key.json", json.dumps(neg))
    huge = json.loads(json.dumps(doc))
    huge["carriers"][0][0] = huge["carriers"][0][1] = 1e30
    b.key_huge = key("huge.key.json", json.dumps(huge))

    data = sample.pm.read_bytes()
    b.pm_truncated = d / "truncated.pmwm"
    b.pm_truncated.write_bytes(data[: len(data) // 2])
    flipped = bytearray(data)
    flipped[len(data) // 3] ^= 0x10
    b.pm_corrupt = d / "corrupt.pmwm"
    b.pm_corrupt.write_bytes(bytes(flipped))
    b.pm_empty = d / "empty.pmwm"
    b.pm_empty.write_bytes(b"")
    b.pm_not = d / "mesh.pmwm"
    shutil.copy(COW, b.pm_not)
    # a record of a level splitting a vertex added earlier in the same level, checksum recomputed
    pm = pmwm.read_pm(sample.pm)
    starts = np.r_[0, pm.level_records[:-1]]
    a = int(starts[np.flatnonzero(pm.level_records - starts >= 2)[0]])
    pm.v[a + 1] = pm.n_base_vertices + a
    b.pm_inconsistent = d / "inconsistent.pmwm"
    pmwm.write_pm(b.pm_inconsistent, pm)
    return b


@pytest.fixture
def out(tmp_path) -> Path:
    d = tmp_path / "out"
    d.mkdir()
    return d


# ---------------------------------------------------------------- embed and verify


def test_embed_writes_the_mesh_the_private_key_and_the_progressive_mesh(sample):
    assert sorted(listing(sample.dir)) == sorted([sample.mesh.name, sample.key.name, sample.pm.name])
    assert stat.S_IMODE(sample.key.stat().st_mode) == 0o600  # even under umask 000
    src, marked = pmwm.read_mesh(COW), pmwm.read_mesh(sample.mesh)
    assert marked.vertices.shape == src.vertices.shape and np.array_equal(marked.faces, src.faces)
    assert not np.array_equal(marked.vertices, src.vertices)
    key, pm = pmwm.read_key(sample.key), pmwm.read_pm(sample.pm)
    assert key.n_vertices == pm.n_vertices == len(src.vertices)
    assert key.secret not in sample.mesh.read_bytes().decode("latin-1")
    assert str(sample.mesh) in sample.proc.stdout and str(sample.key) in sample.proc.stdout


def test_embed_is_reproducible_from_the_seed(sample, out):
    assert (
        cli.main(
            [
                "embed",
                str(COW),
                "-o",
                str(out / "again.ply"),
                "--key",
                str(out / "again.key.json"),
                "--seed",
                "1",
                "--payload",
                PAYLOAD,
                "-q",
            ]
        )
        == 0
    )
    assert (out / "again.ply").read_bytes() == sample.mesh.read_bytes()
    assert pmwm.read_key(out / "again.key.json").secret == pmwm.read_key(sample.key).secret


def test_strength_and_base_ratio_are_applied(sample, out):
    """Same seed and payload: a larger --strength moves the carriers further, a larger --base-ratio
    keeps a larger base mesh, and the mark still verifies."""
    assert (
        call(
            "embed",
            COW,
            "-o",
            out / "s.ply",
            "--key",
            out / "s.key.json",
            "--pm",
            out / "s.pmwm",
            "--seed",
            1,
            "--payload",
            PAYLOAD,
            "--strength",
            4,
            "--base-ratio",
            0.2,
            "-q",
        ).returncode
        == 0
    )
    src = pmwm.read_mesh(COW).vertices
    moved_default = np.linalg.norm(pmwm.read_mesh(sample.mesh).vertices - src, axis=1)
    moved_strong = np.linalg.norm(pmwm.read_mesh(out / "s.ply").vertices - src, axis=1)
    assert moved_strong.sum() > 1.5 * moved_default.sum()
    strong_pm, default_pm = pmwm.read_pm(out / "s.pmwm"), pmwm.read_pm(sample.pm)
    # (the default base may exceed 3 %: the robust scheme keeps each bump's stencil in the base mesh)
    assert strong_pm.n_base_vertices >= round(0.2 * strong_pm.n_vertices) > default_pm.n_base_vertices
    assert pmwm.read_key(out / "s.key.json").strength == 4
    code, v = verdict(out / "s.ply", "--key", out / "s.key.json")
    assert code == 0 and v["payload"] == PAYLOAD


def test_verify_reads_the_mark_and_the_payload(sample):
    code, v = verdict(sample.mesh, "--key", sample.key, real=True)
    assert VERDICT_FIELDS <= v.keys()
    assert code == 0 and v["marked"] is True
    assert v["payload"] == PAYLOAD
    assert v["bit_errors"] == 0 and v["matches"] == v["carriers_total"] == len(v["bits"])
    assert v["bits"] == "".join(map(str, pmwm.read_key(sample.key).bits))
    assert v["carriers_found"] == v["carriers_total"]
    assert v["p_value"] < 1e-6 and v["correlation"] > 0.99


def test_verify_human_output(sample):
    proc = run("verify", sample.mesh, "--key", sample.key)
    assert proc.returncode == 0 and proc.stderr == ""
    assert "MARKED" in proc.stdout and repr(PAYLOAD) in proc.stdout


def test_verify_prints_the_verdict_in_the_shared_words(sample):
    """What ``pmwm verify`` prints is ``pmwm.wording.lines`` of the verdict: its headline, then the payload."""
    from pmwm import wording

    proc = call("verify", sample.mesh, "--key", sample.key)
    src = pmwm.read_mesh(sample.mesh)
    v = pmwm.verify(src.vertices, src.faces, pmwm.read_key(sample.key))
    assert proc.stdout.splitlines() == wording.lines(v)
    assert proc.stdout.splitlines()[0].startswith("MARKED: 64/64 bits match, p = ")
    assert proc.stdout.splitlines()[-1] == f"payload: {PAYLOAD!r}"


def test_a_marked_copy_whose_bits_differ_from_the_key_never_shows_them_as_the_payload(sample, out):
    """A key whose payload differs from the mark in 3 of 64 bits still finds the mark (61/64 bits match), but
    the payload read is not the key's: the verdict says "payload unconfirmed (3 of 64 bits differ)" and shows
    neither the text nor the bits it read, in words or in JSON."""
    doc = json.loads(sample.key.read_text())
    flipped = list(doc["bits"])
    for i in (3, 17, 40):  # (bits of the text's first bytes: the text read is still the mark's)
        flipped[i] = "1" if flipped[i] == "0" else "0"
    doc["bits"] = "".join(flipped)
    key = out / "off-by-three.key.json"
    key.write_text(json.dumps(doc))
    code, v = verdict(sample.mesh, "--key", key)
    assert code == 0 and v["marked"] is True and v["bit_errors"] == 3
    assert (v["payload_confirmed"], v["payload"], v["bits"]) == (False, None, None)
    proc = call("verify", sample.mesh, "--key", key)
    assert proc.returncode == 0 and proc.stdout.splitlines()[-1] == "payload unconfirmed (3 of 64 bits differ)"
    assert repr(PAYLOAD) not in proc.stdout and "payload:" not in proc.stdout
    assert not any(len(w) >= 64 and set(w) <= {"0", "1"} for w in proc.stdout.split())


def test_a_scheme_keyed_by_a_pass_phrase_is_told_by_its_keying_not_its_name(out, monkeypatch):
    """The embed's argument checks follow ``Scheme.keying``: a pass-phrase scheme of another name takes a
    pass phrase, refuses --key and writes no key file, as the blind scheme does."""
    from pmwm.schemes import SCHEMES

    seen = {}

    def embed(vertices, faces, options, progress=None):
        seen["passphrase"] = options.passphrase
        return pmwm.EmbedResult(vertices, faces, None, None, np.zeros(0, np.int64), np.zeros(32, np.uint8), 99.0, 0.0)

    phrase_scheme = dataclasses.replace(SCHEMES["blind"], name="phrase", embed=embed)
    monkeypatch.setitem(SCHEMES, "phrase", phrase_scheme)
    monkeypatch.delenv("PMWM_PASSPHRASE", raising=False)
    assert_error(call("embed", COW, "-o", out / "m.ply", "--scheme", "phrase"), "needs a pass phrase")
    monkeypatch.setenv("PMWM_PASSPHRASE", "a phrase")
    assert_error(call("embed", COW, "-o", out / "m.ply", "--scheme", "phrase", "--key", out / "k.json"), "omit --key")
    assert call("embed", COW, "-o", out / "m.ply", "--scheme", "phrase", "-q").returncode == 0
    assert seen["passphrase"] == "a phrase" and listing(out) == ["m.ply"]
    key_file = dataclasses.replace(SCHEMES["robust"], name="keyed")
    monkeypatch.setitem(SCHEMES, "keyed", key_file)
    assert_error(call("embed", COW, "-o", out / "n.ply", "--scheme", "keyed"), "--key")


def test_explicit_bits_come_back_exactly(out):
    bits = "".join(map(str, np.random.default_rng(7).integers(0, 2, 40)))
    mesh, key = out / "bits.obj", out / "bits.key.json"
    assert cli.main(["embed", str(COW), "-o", str(mesh), "--key", str(key), "--bits", bits, "--seed", "3", "-q"]) == 0
    assert listing(out) == ["bits.key.json", "bits.obj"]
    code, v = verdict(mesh, "--key", key)
    assert code == 0 and v["marked"] is True
    assert v["bits"] == bits and v["payload"] is None and v["carriers_total"] == 40


def test_the_unmarked_original_is_not_marked(sample):
    code, v = verdict(COW, "--key", sample.key, real=True)
    assert code == 1 and v["marked"] is False
    assert v["payload"] != PAYLOAD and v["p_value"] >= 1e-6


def test_a_key_of_another_seed_finds_no_mark(sample, other_key):
    code, v = verdict(sample.mesh, "--key", other_key)
    assert code == 1 and v["marked"] is False and v["payload"] != PAYLOAD


def test_main_returns_exit_codes_in_process(sample, capsys):
    assert cli.main(["verify", str(COW), "--key", str(sample.key)]) == 1
    assert "not marked" in capsys.readouterr().out
    assert cli.main(["embed"]) == 2  # usage errors return 2 rather than raising SystemExit
    assert capsys.readouterr().err.startswith("pmwm: error:")


def test_version_and_console_script(sample):
    proc = run("--version")
    assert proc.returncode == 0 and pmwm.__version__ in proc.stdout
    script = Path(sys.executable).parent / "pmwm"
    assert script.exists(), "the console script `pmwm` is not installed"
    proc = subprocess.run(
        [str(script), "verify", str(sample.mesh), "--key", str(sample.key), "--json"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0 and json.loads(proc.stdout)["payload"] == PAYLOAD


# ---------------------------------------------------------------- the progressive mesh


def test_decode_level_writes_that_level_of_detail(sample, out):
    pm = pmwm.read_pm(sample.pm)
    k = int(pm.level_records[len(pm.level_records) // 2])
    proc = run("decode", sample.pm, "-o", out / "lod.ply", "--level", k)
    assert proc.returncode == 0, proc.stderr
    V, F = pm.decode(records=k)
    got = trimesh.load(out / "lod.ply", process=False, force="mesh")
    assert len(got.vertices) == pm.n_base_vertices + k == len(V)
    assert len(got.faces) == len(F)
    assert np.array_equal(sorted_rows(np.asarray(got.vertices, np.float64)), sorted_rows(V))
    assert listing(out) == ["lod.ply"]


@pytest.mark.parametrize("where", ["base", "mid-level", "full"])
def test_decode_vertices_writes_that_many_vertices(sample, out, where):
    pm = pmwm.read_pm(sample.pm)
    wide = int(np.flatnonzero(np.diff(pm.level_records) >= 2)[len(pm.level_records) // 2])
    mid = pm.n_base_vertices + int(pm.level_records[wide]) + 1  # inside a level, not at its end
    n = {"base": pm.n_base_vertices, "mid-level": mid, "full": pm.n_vertices}[where]
    proc = call("decode", sample.pm, "-o", out / "lod.off", "--vertices", n, "-q")
    assert proc.returncode == 0, proc.stderr
    assert vertex_count(out / "lod.off") == n


def test_full_decode_is_the_marked_mesh(sample, out):
    assert cli.main(["decode", str(sample.pm), "-o", str(out / "full.ply"), "-q"]) == 0
    full, marked = pmwm.read_mesh(out / "full.ply"), pmwm.read_mesh(sample.mesh)
    assert np.array_equal(sorted_rows(full.vertices), sorted_rows(marked.vertices))
    assert len(full.faces) == len(marked.faces)


def test_info_prints_the_counts(sample):
    pm = pmwm.read_pm(sample.pm)
    proc = run("info", sample.pm)
    assert proc.returncode == 0, proc.stderr
    assert f"base_vertices: {pm.n_base_vertices}" in proc.stdout
    assert f"records: {pm.n_records}" in proc.stdout
    assert f"full_vertices: {len(pmwm.read_mesh(sample.mesh).vertices)}" in proc.stdout
    proc = call("info", sample.pm, "--json")
    info = json.loads(proc.stdout)
    assert info["base_vertices"] == pm.n_base_vertices and info["records"] == pm.n_records
    assert info["levels"] == len(pm.level_records) == len(info["level_vertices"])
    assert info["full_vertices"] == info["level_vertices"][-1] == pm.n_vertices
    assert info["bytes"] == sample.pm.stat().st_size


def test_verify_a_progressive_mesh_file(sample):
    pm = pmwm.read_pm(sample.pm)
    code, v = verdict(sample.pm, "--key", sample.key, real=True)
    assert code == 0 and v["marked"] is True and v["payload"] == PAYLOAD
    mid = int(pm.level_records[len(pm.level_records) // 2])
    code, v = verdict(sample.pm, "--key", sample.key, "--level", mid)
    assert code == 0 and v["marked"] is True and v["carriers_found"] == v["carriers_total"]
    code, v = verdict(sample.pm, "--key", sample.key, "--vertices", pm.n_base_vertices + mid)
    assert code == 0 and v["marked"] is True


# ---------------------------------------------------------------- errors: one line, exit 2, nothing written


def embed_args(out: Path, src=COW, *extra) -> list:
    return ["embed", src, "-o", out / "m.ply", "--key", out / "m.key.json", "--pm", out / "m.pmwm", *extra]


def test_embed_rejects_an_unreadable_mesh(bad, out):
    fails_cleanly(out, *embed_args(out, bad.garbage), mentions=("garbage.ply",))


def test_embed_rejects_a_missing_input(out):
    fails_cleanly(out, *embed_args(out, out.parent / "nope.obj"), mentions=("nope.obj",))


def test_embed_rejects_a_directory(bad, out):
    fails_cleanly(out, *embed_args(out, bad.folder), mentions=("folder.obj",))


def test_embed_rejects_an_unknown_input_extension(bad, out):
    fails_cleanly(out, *embed_args(out, bad.xyz), mentions=("cow.xyz",))


def test_embed_rejects_an_unknown_output_extension(out):
    fails_cleanly(out, "embed", COW, "-o", out / "m.xyz", "--key", out / "k.json", mentions=("m.xyz",))


@pytest.mark.parametrize(
    "extra,mention",
    [
        (["--bits", "01x"], "bits"),
        (["--bits", ""], "bits"),
        (["--payload", "a", "--bits", "01"], "--bits"),
        (["--payload", ""], "payload"),
        (["--n-bits", "0"], "bits"),
        (["--n-bits", "1000000"], "bits"),
        (["--strength", "0"], "strength"),
        (["--strength", "nan"], "strength"),
        (["--base-ratio", "0"], "ratio"),
        (["--base-ratio", "1.5"], "ratio"),
        (["--seed", "abc"], "seed"),
    ],
    ids=lambda x: " ".join(x) if isinstance(x, list) else None,
)
def test_embed_rejects_bad_options(out, extra, mention):
    fails_cleanly(out, *embed_args(out, COW, *extra), mentions=(mention,))


def test_embed_requires_its_arguments(out):
    fails_cleanly(out, "embed", COW, "-o", out / "m.ply", mentions=("--key",))
    fails_cleanly(out, mentions=("command",))


@pytest.mark.parametrize("which", ["-o", "--key", "--pm"])
def test_embed_refuses_an_output_in_a_missing_folder(out, which):
    args = {"-o": out / "m.ply", "--key": out / "m.key.json", "--pm": out / "m.pmwm"}
    args[which] = out / "missing" / Path(args[which]).name
    fails_cleanly(out, "embed", COW, *[x for kv in args.items() for x in kv], mentions=("missing",))


@pytest.mark.parametrize("which", ["-o", "--key", "--pm"])
def test_embed_never_overwrites_its_input_even_with_force(out, which):
    src = out / "cow.off"
    shutil.copy(COW, src)
    args = {"-o": out / "m.off", "--key": out / "m.key.json", "--pm": out / "m.pmwm"}
    args[which] = src
    fails_cleanly(out, "embed", src, *[x for kv in args.items() for x in kv], "--force", mentions=("input",))
    assert src.read_bytes() == COW.read_bytes()


def test_embed_never_overwrites_its_input_through_a_symlink(out):
    src = out / "cow.off"
    shutil.copy(COW, src)
    (out / "link.off").symlink_to(src)
    fails_cleanly(out, "embed", src, "-o", out / "link.off", "--key", out / "k.json", "--force", mentions=("input",))
    assert src.read_bytes() == COW.read_bytes()


@pytest.mark.parametrize("which", ["m.ply", "m.key.json", "m.pmwm"])
def test_embed_refuses_an_existing_output_and_writes_nothing(out, which):
    (out / which).write_bytes(b"precious\n")
    fails_cleanly(out, *embed_args(out), "--seed", "1", mentions=(which, "--force"))
    assert (out / which).read_bytes() == b"precious\n"


def test_embed_writes_all_outputs_or_none(out):
    """The mesh is written last; when writing it fails, the key and .pmwm already written are removed."""
    long_name = "m" * 300 + ".ply"  # too long for the file system: only the final write fails
    fails_cleanly(
        out, "embed", COW, "-o", out / long_name, "--key", out / "m.key.json", "--pm", out / "m.pmwm", "--seed", "1"
    )


def test_embed_force_overwrites_every_output(out):
    for name in ("m.ply", "m.key.json", "m.pmwm"):
        (out / name).write_bytes(b"old\n")
        (out / name).chmod(0o644)
    proc = call(*embed_args(out), "--seed", "1", "--payload", PAYLOAD, "--force", "-q")
    assert proc.returncode == 0, proc.stderr
    assert listing(out) == ["m.key.json", "m.ply", "m.pmwm"]
    assert stat.S_IMODE((out / "m.key.json").stat().st_mode) == 0o600
    assert pmwm.read_pm(out / "m.pmwm").n_vertices == len(pmwm.read_mesh(out / "m.ply").vertices)
    code, v = verdict(out / "m.ply", "--key", out / "m.key.json")
    assert code == 0 and v["payload"] == PAYLOAD


@pytest.mark.parametrize(
    "key,mention",
    [
        ("missing", "does not exist"),
        ("folder", "directory"),
        ("key_text", "json"),
        ("key_empty", "json"),
        ("key_binary", ""),
        ("key_deep", ""),
        ("key_future", "version"),
        ("key_missing:secret", "secret"),
        ("key_missing:carriers", "carriers"),
        ("key_missing:bits", "bits"),
        ("key_missing:mesh", "mesh"),
        ("key_inf", ""),
    ],
)
def test_verify_rejects_a_bad_key(sample, bad, key, mention):
    if key == "missing":
        path = bad.dir / "nope.key.json"
    elif key.startswith("key_missing:"):
        path = bad.key_missing[key.split(":")[1]]
    else:
        path = getattr(bad, key)
    fails_cleanly(sample.dir, "verify", sample.mesh, "--key", path, mentions=(mention,))


@pytest.mark.parametrize("which,real", [("key_negative", False), ("key_huge", True)])
def test_a_key_with_an_impossible_carrier_index_does_not_crash_verify(sample, bad, which, real):
    """Refused as a damaged key (exit 2, one line), or the carrier counts as not found; nothing else
    on stderr (no traceback, no stray numpy warning)."""
    proc = (run if real else call)("verify", sample.mesh, "--key", getattr(bad, which))
    assert "Traceback" not in proc.stderr, proc.stderr
    if proc.returncode == 2:
        assert_error(proc)
    else:
        assert proc.returncode in (0, 1) and proc.stderr == ""


@pytest.mark.parametrize("suspect", ["garbage", "folder", "xyz", "missing"])
def test_verify_rejects_a_bad_suspect_mesh(sample, bad, suspect):
    path = bad.dir / "nope.ply" if suspect == "missing" else getattr(bad, suspect)
    fails_cleanly(sample.dir, "verify", path, "--key", sample.key, mentions=(path.name,))


def test_verify_level_applies_to_progressive_meshes_only(sample):
    fails_cleanly(sample.dir, "verify", sample.mesh, "--key", sample.key, "--level", 3, mentions=("--level",))


@pytest.mark.parametrize("damage", ["pm_truncated", "pm_corrupt", "pm_empty", "pm_not", "pm_inconsistent"])
@pytest.mark.parametrize("command", ["info", "decode", "verify"])
def test_damaged_progressive_mesh_files_are_refused(sample, bad, out, damage, command):
    path = getattr(bad, damage)
    args = {
        "info": ["info", path],
        "decode": ["decode", path, "-o", out / "lod.ply"],
        "verify": ["verify", path, "--key", sample.key],
    }[command]
    fails_cleanly(out, *args, mentions=(path.name,))


@pytest.mark.parametrize("command", ["info", "decode"])
@pytest.mark.parametrize("what", ["missing", "folder"])
def test_decode_and_info_reject_a_missing_or_directory_input(bad, out, command, what):
    path = bad.dir / "nope.pmwm" if what == "missing" else bad.dir
    args = ["info", path] if command == "info" else ["decode", path, "-o", out / "lod.ply"]
    fails_cleanly(out, *args, mentions=(path.name,))


@pytest.mark.parametrize(
    "extra,mention",
    [
        (["--level", "-1"], "level"),
        (["--level", "3", "--vertices", "300"], "not allowed"),
        (["--level", "x"], "level"),
    ],
)
def test_decode_rejects_bad_levels(sample, out, extra, mention):
    fails_cleanly(out, "decode", sample.pm, "-o", out / "lod.ply", *extra, mentions=(mention,))


def test_decode_output_rules(sample, out):
    fails_cleanly(out, "decode", sample.pm, "-o", out / "missing" / "lod.ply", mentions=("missing",))
    fails_cleanly(out, "decode", sample.pm, "-o", out / "lod.xyz", mentions=("lod.xyz",))
    (out / "lod.ply").write_bytes(b"precious\n")
    fails_cleanly(out, "decode", sample.pm, "-o", out / "lod.ply", mentions=("lod.ply", "--force"))
    assert (out / "lod.ply").read_bytes() == b"precious\n"
    proc = call("decode", sample.pm, "-o", out / "lod.ply", "--vertices", 500, "--force", "-q")
    assert proc.returncode == 0, proc.stderr
    assert listing(out) == ["lod.ply"] and vertex_count(out / "lod.ply") == 500


@pytest.mark.parametrize(
    "case",
    ["garbage mesh", "bad bits", "existing output", "missing key", "future key", "corrupt pmwm", "truncated pmwm"],
)
@pytest.mark.slow
def test_errors_from_a_real_process_are_one_line(sample, bad, out, case):
    """The same checks through ``python -m pmwm``: exit 2, one stderr line, no traceback, nothing left."""
    if case == "existing output":
        (out / "m.ply").write_bytes(b"precious\n")
    args = {
        "garbage mesh": embed_args(out, bad.garbage),
        "bad bits": embed_args(out, COW, "--bits", "01x"),
        "existing output": embed_args(out, COW, "--seed", "1"),
        "missing key": ["verify", sample.mesh, "--key", out / "nope.key.json"],
        "future key": ["verify", sample.mesh, "--key", bad.key_future],
        "corrupt pmwm": ["decode", bad.pm_corrupt, "-o", out / "lod.ply"],
        "truncated pmwm": ["info", bad.pm_truncated],
    }[case]
    fails_cleanly(out, *args, real=True)
    if case == "existing output":
        assert (out / "m.ply").read_bytes() == b"precious\n"


# ---------------------------------------------------------------- pmwm attack


def test_attack_writes_the_attacked_copy_and_the_mark_survives_reordering(sample, out):
    noisy, shuffled = out / "noisy.ply", out / "shuffled.ply"
    proc = call("attack", "noise_paper", sample.mesh, "-o", noisy, "--amplitude", "0.0005", "--seed", 3)
    assert proc.returncode == 0, proc.stderr
    a, b = pmwm.read_mesh(sample.mesh), pmwm.read_mesh(noisy)
    assert len(a.vertices) == len(b.vertices) and not np.array_equal(a.vertices, b.vertices)
    assert call("attack", "reorder", sample.mesh, "-o", shuffled, "--seed", 4).returncode == 0
    code, v = verdict(shuffled, "--key", sample.key)
    assert code == 0 and v["payload"] == PAYLOAD


def test_attack_bad_parameter_is_a_one_line_error(sample, out):
    fails_cleanly(
        out, "attack", "crop_plane", sample.mesh, "-o", out / "c.ply", "--fraction", "1.5", mentions=("fraction",)
    )
    fails_cleanly(out, "attack", "noise_paper", sample.mesh, "-o", out / "n.ply", "--amplitude", "x")


@pytest.mark.parametrize("scheme", ["cho1", "cho2"])
@pytest.mark.slow
def test_cho_schemes_behind_the_same_commands(tmp_path, scheme):
    """`pmwm embed --scheme cho1|cho2`, then `pmwm verify` (which reads the scheme from the key) of a
    copy moved by a similarity transform and re-ordered: every bit."""
    bunny = Path(pmwm.__file__).parent / "data" / "bunny.off"
    bits = "".join(map(str, np.random.default_rng(3).integers(0, 2, 64)))
    marked, key = tmp_path / "m.ply", tmp_path / "m.key.json"
    assert (
        call(
            "embed", bunny, "-o", marked, "--key", key, "--bits", bits, "--scheme", scheme, "--seed", 5, "-q"
        ).returncode
        == 0
    )
    assert json.loads(key.read_text())["scheme"] == scheme
    src = pmwm.read_mesh(marked)
    from pmwm import attacks

    V, F = attacks.reorder(*attacks.similarity(src.vertices, src.faces, seed=1), seed=2)
    pmwm.write_mesh(tmp_path / "suspect.obj", V, F)
    code, v = verdict(tmp_path / "suspect.obj", "--key", key)
    assert code == 0 and v["marked"] and v["bits"] == bits and v["mode"] == "blind"


def test_unknown_scheme_is_refused_with_the_list(tmp_path):
    fails_cleanly(
        tmp_path,
        "embed",
        COW,
        "-o",
        tmp_path / "m.ply",
        "--key",
        tmp_path / "k.json",
        "--scheme",
        "cho3",
        mentions=("cho1", "robust"),
    )


@pytest.mark.parametrize("scheme", ["robust", "blind"])
@pytest.mark.slow
def test_embed_builds_the_progressive_mesh_only_for_pm(tmp_path, monkeypatch, scheme):
    """Without --pm no progressive mesh is built (most of an embed's time) and the mark reads; with --pm
    it is built and decodes to the marked mesh."""
    import sys as _sys

    modules = [_sys.modules["pmwm.schemes.robust.embed"], _sys.modules["pmwm.schemes.blind"]]
    real = modules[0].build_progressive_mesh

    def refuse(*args, **kwargs):
        raise AssertionError("a progressive mesh was built without --pm")

    for m in modules:
        monkeypatch.setattr(m, "build_progressive_mesh", refuse)
    monkeypatch.setenv("PMWM_PASSPHRASE", "a pass phrase")
    src = COW
    if scheme == "blind":  # (a mesh the blind scheme can mark: the blob is too small for its 64 bins)
        src = tmp_path / "cap.off"
        meshes.write_off(src, *meshes.open_cap())
    common = ["--payload", PAYLOAD, "--seed", 2, "-q"] + (
        ["--scheme", "blind"] if scheme == "blind" else ["--key", tmp_path / "k.json"]
    )
    assert call("embed", src, "-o", tmp_path / "m.ply", *common).returncode == 0
    assert not list(tmp_path.glob("*.pmwm"))
    key = ["--key", tmp_path / "k.json"] if scheme == "robust" else []
    code, v = verdict(tmp_path / "m.ply", *key)
    assert code == 0 and v["marked"] and v["payload"] == PAYLOAD
    for m in modules:
        monkeypatch.setattr(m, "build_progressive_mesh", real)
    common = [c if c != tmp_path / "k.json" else tmp_path / "k2.json" for c in common]
    assert call("embed", src, "-o", tmp_path / "m2.ply", "--pm", tmp_path / "m2.pmwm", *common).returncode == 0
    assert (tmp_path / "m2.ply").read_bytes() == (tmp_path / "m.ply").read_bytes()
    V, F = pmwm.read_pm(tmp_path / "m2.pmwm").decode()
    src = pmwm.read_mesh(tmp_path / "m2.ply")
    assert np.array_equal(sorted_rows(V), sorted_rows(src.vertices))


def test_embed_help_names_every_scheme_once():
    """``pmwm embed --help`` lists each scheme as "name: what it does", the name not repeated."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        cli.main(["embed", "--help"])
    text = " ".join(out.getvalue().split())
    for name, scheme in pmwm.schemes.SCHEMES.items():
        assert f"{name}: {scheme.description.split()[0]}" in text
        assert f"{name}: {name}:" not in text
