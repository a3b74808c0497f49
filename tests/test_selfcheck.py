"""The blind embed checks its own output: a mark that does not read back from the mesh as written, or
from a light copy of it, is never handed back; the user gets one line saying why and what to try."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import meshes
import pmwm
from pmwm.errors import PayloadError
from pmwm.schemes.blind import read, selfcheck, word

PHRASE = "correct horse battery staple"


@pytest.fixture(scope="module")
def bunny():
    return meshes.bunny()


def test_a_default_embed_reads_back_from_every_light_copy(bunny):
    V, F = bunny
    res = pmwm.embed(
        V, F, pmwm.EmbedOptions(scheme="blind-histogram", payload="ACME-2026", passphrase=PHRASE, progressive=False)
    )
    secret = word.derive_secret(PHRASE)
    names = []
    for name, Vc, Fc in selfcheck.light_copies(res.vertices, res.faces, secret):
        v = read(Vc, Fc, secret)
        assert v.marked and v.payload == "ACME-2026", name
        names.append(name)
    assert len(names) == 3 and not (Vc == res.vertices).all()  # (the copies differ from the mesh)


def test_a_mark_too_weak_to_read_back_is_refused_in_one_line(bunny):
    V, F = bunny
    with pytest.raises(PayloadError) as err:
        pmwm.embed(
            V,
            F,
            pmwm.EmbedOptions(
                scheme="blind-histogram", payload="OWNR", passphrase=PHRASE, strength=0.002, progressive=False
            ),
        )
    msg = str(err.value)
    assert "\n" not in msg and "does not read back" in msg and "--strength" in msg and "nothing written" in msg


def test_the_check_is_the_same_for_the_same_phrase_and_mesh(bunny):
    V, F = bunny
    a = [c[1] for c in selfcheck.light_copies(V, F, "s1")]
    b = [c[1] for c in selfcheck.light_copies(V, F, "s1")]
    c = [c[1] for c in selfcheck.light_copies(V, F, "s2")]
    assert all((x == y).all() for x, y in zip(a, b))
    assert not (a[1] == c[1]).all() and not (a[2] == c[2]).all()


def test_cli_refuses_a_mark_that_does_not_read_back_and_writes_nothing(tmp_path):
    src = tmp_path / "cap.off"
    meshes.write_off(src, *meshes.open_cap())
    out = tmp_path / "marked.ply"
    env = dict(os.environ, PYTHONPATH=str(Path(pmwm.__file__).parent.parent), PMWM_PASSPHRASE=PHRASE)
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmwm",
            "embed",
            str(src),
            "-o",
            str(out),
            "--scheme",
            "blind-histogram",
            "--payload",
            "OWNR",
            "--strength",
            "0.002",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "does not read back" in p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["cap.off"]
