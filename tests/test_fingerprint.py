"""Fingerprinting: a marked copy per recipient (exact files and progressive meshes), tracing after
attacks and averaging collusion, the resumable job, the key/registry pairing, the Dask catalogue."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pmwm
import pmwm.cli
from pmwm import attacks
from pmwm.fingerprint import (
    FingerprintKey,
    FingerprintOptions,
    Registry,
    RegistryError,
    analyse_asset,
    fingerprint_asset,
    read_fingerprint_key,
    read_recipients,
    read_registry,
    trace,
)
from pmwm.fingerprint.codes import codewords, pack_codeword
from pmwm.fingerprint.registry import RegistryEntry

import meshes


@pytest.fixture(scope="module")
def cap():
    """The open cap analysed once (384 sites), and a registry of 300 recipients (codewords only)."""
    V, F = meshes.open_cap()
    an = analyse_asset(V, F, FingerprintOptions(seed=11))
    fk = FingerprintKey(an.key, an.options, an.asset_sha256)
    reg = Registry.for_key(fk)
    ids = [f"r{i:03d}" for i in range(300)]
    for rid, c in zip(ids, codewords(an.key.secret, ids, an.n_sites)):
        reg.entries[rid] = RegistryEntry(pack_codeword(c))
    return an, fk, reg


def _named(result) -> list:
    return [a.recipient for a in result.accused]


def test_a_copy_is_its_files_exactly_and_its_progressive_mesh_decodes_to_it(cap, tmp_path):
    an, fk, reg = cap
    files = an.write_copy(tmp_path, "r007", pm=True)
    X = an.marked(an.codeword("r007"))
    src = pmwm.read_mesh(tmp_path / "r007.ply")
    assert np.array_equal(src.vertices, X) and np.array_equal(src.faces, an.sites.faces)
    pm = pmwm.read_pm(tmp_path / "r007.pmwm")
    V, F = pm.decode()
    assert np.array_equal(V, X[an.pm.vertex_order])
    assert np.array_equal(
        np.sort(np.sort(F, axis=1), axis=0),  # the asset's faces, in the PM's numbering
        np.sort(np.sort(np.argsort(an.pm.vertex_order)[an.sites.faces], axis=1), axis=0),
    )
    for name, sha in files.items():
        assert hashlib.sha256((tmp_path / name).read_bytes()).hexdigest() == sha
    # two recipients differ only where the sites are; the distortion is the embed's
    Y = an.marked(an.codeword("r008"))
    moved = np.flatnonzero(np.any(X != Y, axis=1))
    assert 0 < len(moved) < 0.5 * len(X)
    assert _named(trace(V, F, fk, reg)) == ["r007"]


def test_trace_names_the_recipient_after_a_similarity_and_10_percent_simplification(cap):
    an, fk, reg = cap
    X = an.marked(an.codeword("r042"))
    V, F = attacks.simplify(*attacks.similarity(X, an.sites.faces, seed=5), ratio=0.1)
    r = trace(V, F, fk, reg)
    assert _named(r) == ["r042"] and r.mode == "registered"
    assert r.accused[0].p_value < 1e-6 and np.sort(r.p_values)[1] > 1e-3


def test_a_mirrored_posed_simplified_copy_names_its_recipient_and_pays_for_its_poses(cap):
    """A copy mirrored, then posed and simplified by 10 %: traced to its recipient, the trace saying it
    was mirrored; its p-values pay for the poses the reader may try, so no innocent comes near."""
    from pmwm.register import POSES

    an, fk, reg = cap
    X = an.marked(an.codeword("r123")) * [-1.0, 1.0, 1.0]
    V, F = attacks.simplify(*attacks.similarity(X, an.sites.faces[:, ::-1], seed=8), ratio=0.1)
    r = trace(V, F, fk, reg)
    assert _named(r) == ["r123"] and r.detail.mirrored and r.detail.poses_paid == POSES
    assert np.sort(r.p_values)[1] > 1e-3


def test_averaged_copies_name_their_colluders_and_no_innocent(cap):
    an, fk, reg = cap
    F = an.sites.faces
    two = (an.marked(an.codeword("r010")) + an.marked(an.codeword("r020"))) / 2
    assert sorted(_named(trace(two, F, fk, reg))) == ["r010", "r020"]
    three = sum(an.marked(an.codeword(r)) for r in ("r100", "r200", "r250")) / 3
    named = _named(trace(three, F, fk, reg))
    assert named and set(named) <= {"r100", "r200", "r250"}
    noisy = attacks.noise_benchmark(two, F, amplitude=0.001, seed=3)
    assert sorted(_named(trace(*noisy, fk, reg))) == ["r010", "r020"]


def test_an_unmarked_asset_names_no_recipient(cap):
    an, fk, reg = cap
    r = trace(an.sites.vertices, an.sites.faces, fk, reg)
    assert r.accused == [] and r.p_values.min() > 1e-3


@pytest.mark.slow
def test_fingerprint_command_resumes_and_trace_command_exit_codes(tmp_path, capsys):
    asset = str(meshes.mesh_file("open_cap.off"))
    (tmp_path / "people.csv").write_text("id,name\nalice,Alice A.\nbob,Bob B.\ncarol,Carol C.\n")
    args = [
        "fingerprint",
        asset,
        "--key",
        str(tmp_path / "cap.key.json"),
        "--recipients",
        str(tmp_path / "people.csv"),
        "--out",
        str(tmp_path / "out"),
        "--pm",
        "--seed",
        "4",
        "-q",
    ]
    assert pmwm.cli.main(args) == 0
    out = tmp_path / "out"
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(before) == {"registry.json", *(f"{r}.{e}" for r in ("alice", "bob", "carol") for e in ("ply", "pmwm"))}
    assert oct(os.stat(tmp_path / "cap.key.json").st_mode & 0o777) == "0o600"
    # a lost copy, a damaged one, and a stale temporary file of a killed run: the rerun rewrites the two
    (out / "bob.ply").unlink()
    (out / "carol.pmwm").write_bytes(b"damaged")
    (out / ".alice.tmp-dead.ply").write_bytes(b"half")
    run = fingerprint_asset(asset, tmp_path / "cap.key.json", ["alice", "bob", "carol"], out, pm=True)
    assert sorted(run.written) == ["bob", "carol"] and run.skipped == ["alice"]
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    capsys.readouterr()
    trace_args = ["--key", str(tmp_path / "cap.key.json"), "--registry", str(out / "registry.json")]
    assert pmwm.cli.main(["trace", str(out / "bob.pmwm"), *trace_args]) == 0
    assert "TRACED to bob" in capsys.readouterr().out
    assert pmwm.cli.main(["trace", asset, *trace_args, "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["accused"] == []


@pytest.mark.slow
def test_a_key_and_registry_that_do_not_belong_together_are_a_clear_error(tmp_path, capsys):
    (tmp_path / "r.csv").write_text("ann\nben\n")
    for name in ("blob", "open_cap"):
        assert (
            pmwm.cli.main(
                [
                    "fingerprint",
                    str(meshes.mesh_file(f"{name}.off")),
                    "--key",
                    str(tmp_path / f"{name}.key"),
                    "--recipients",
                    str(tmp_path / "r.csv"),
                    "--out",
                    str(tmp_path / name),
                    "-q",
                ]
            )
            == 0
        )
    capsys.readouterr()
    code = pmwm.cli.main(
        [
            "trace",
            str(tmp_path / "blob" / "ann.ply"),
            "--key",
            str(tmp_path / "open_cap.key"),
            "--registry",
            str(tmp_path / "blob" / "registry.json"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "belongs to another fingerprinting key" in err
    with pytest.raises(RegistryError, match="another fingerprinting key"):
        trace(
            *meshes.blob(),
            read_fingerprint_key(tmp_path / "open_cap.key"),
            read_registry(tmp_path / "blob" / "registry.json"),
        )
    # the key of one asset given with another asset
    code = pmwm.cli.main(
        [
            "fingerprint",
            str(meshes.mesh_file("blob.off")),
            "--key",
            str(tmp_path / "open_cap.key"),
            "--recipients",
            str(tmp_path / "r.csv"),
            "--out",
            str(tmp_path / "x"),
            "-q",
        ]
    )
    assert code == 2 and "fingerprinting key of another asset" in capsys.readouterr().err
    # a payload key is not a fingerprinting key
    assert (
        pmwm.cli.main(
            [
                "trace",
                str(tmp_path / "blob" / "ann.ply"),
                "--key",
                str(tmp_path / "blob" / "registry.json"),
                "--registry",
                str(tmp_path / "blob" / "registry.json"),
            ]
        )
        == 2
    )
    assert "not a fingerprinting key" in capsys.readouterr().err


def test_recipient_lists_are_checked(tmp_path):
    (tmp_path / "a.csv").write_text("x1\nx2\n")
    assert read_recipients(tmp_path / "a.csv") == ["x1", "x2"]
    for text, what in (("id\nok\n../evil\n", "not valid"), ("a\na\n", "twice"), ("id\n", "no recipient")):
        (tmp_path / "b.csv").write_text(text)
        with pytest.raises(pmwm.PayloadError, match=what):
            read_recipients(tmp_path / "b.csv")


# --------------------------------------------------------------------------- the catalogue on Dask


def _tree(root: Path) -> dict:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.slow
def test_catalogue_on_a_local_cluster_reports_a_failing_asset_and_resumes_identically(tmp_path):
    from pmwm.fingerprint.catalogue import run_catalogue

    bad = tmp_path / "broken.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    assets = [str(meshes.mesh_file("blob.off")), str(meshes.mesh_file("open_cap.off")), str(bad)]
    ids = ["u1", "u2", "u3", "u4", "u5"]
    opts = FingerprintOptions(seed=9)
    res = run_catalogue(assets, ids, tmp_path / "a", pm=True, options=opts, n_workers=2, batch=2)
    assert res.written == 10 and set(res.failed) == {"broken"} and "broken.off" in res.failed["broken"]
    full = _tree(tmp_path / "a")
    assert len([k for k in full if k.endswith(".ply")]) == 10
    reg = read_registry(tmp_path / "a" / "blob" / "registry.json")
    fk = read_fingerprint_key(tmp_path / "a" / "blob.key.json")
    src = pmwm.read_mesh(tmp_path / "a" / "blob" / "u3.ply")
    assert [a.recipient for a in trace(src.vertices, src.faces, fk, reg).accused] == ["u3"]

    # the same catalogue from the command line, interrupted (SIGTERM, a plain kill) once copies appear, then resumed
    (tmp_path / "ids.csv").write_text("\n".join(ids) + "\n")
    cmd = [
        sys.executable,
        "-m",
        "pmwm",
        "catalogue",
        *assets[:2],
        "--recipients",
        str(tmp_path / "ids.csv"),
        "--out",
        str(tmp_path / "b"),
        "--pm",
        "--seed",
        "9",
        "--workers",
        "2",
        "-q",
    ]
    proc = subprocess.Popen(
        cmd,
        env={**os.environ, "PYTHONPATH": str(Path(pmwm.__file__).parents[1])},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        t0 = time.monotonic()
        while proc.poll() is None and time.monotonic() - t0 < 120:
            if list((tmp_path / "b").glob("*/*.ply")):
                proc.send_signal(signal.SIGTERM)
                break
            time.sleep(0.05)
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=":0") as cluster:  # --scheduler ADDRESS
        res = run_catalogue(assets[:2], ids, tmp_path / "b", pm=True, options=opts, scheduler=cluster.scheduler_address)
    assert not res.failed and res.written + res.skipped == 10
    assert _tree(tmp_path / "b") == {k: v for k, v in full.items() if not k.startswith("broken")}


@pytest.mark.slow
def test_without_a_progressive_mesh_the_copies_are_the_same_and_trace(cap, tmp_path, monkeypatch):
    """An asset analysed with ``progressive=False`` (copies without .pmwm, the default of ``pmwm
    fingerprint`` and ``pmwm catalogue``) builds no progressive mesh and gives the same copies; asking
    it for a .pmwm copy is a clear error."""
    an, fk, reg = cap
    from pmwm.fingerprint import copies

    def refuse(*args, **kwargs):
        raise AssertionError("a progressive mesh was built for copies without .pmwm")

    monkeypatch.setattr(copies, "build_progressive_mesh", refuse)
    flat = analyse_asset(*meshes.open_cap(), FingerprintOptions(seed=11), progressive=False)
    assert flat.pm is None and flat.key.secret == an.key.secret
    c = an.codeword("r042")
    assert np.array_equal(flat.marked(c), an.marked(c))
    files = flat.write_copy(tmp_path, "r042")
    assert sorted(files) == ["r042.ply"]
    src = pmwm.read_mesh(tmp_path / "r042.ply")
    assert _named(trace(src.vertices, src.faces, fk, reg)) == ["r042"]
    with pytest.raises(ValueError, match="without a progressive mesh"):
        flat.copy(c, pm=True)
    # the command without --pm: the same, through the files
    (tmp_path / "people.csv").write_text("id\nalice\nbob\n")
    args = [
        "fingerprint",
        str(meshes.mesh_file("open_cap.off")),
        "--key",
        str(tmp_path / "cap.key.json"),
        "--recipients",
        str(tmp_path / "people.csv"),
        "--out",
        str(tmp_path / "out"),
        "--seed",
        "4",
        "-q",
    ]
    assert pmwm.cli.main(args) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["alice.ply", "bob.ply", "registry.json"]
