"""Keys written by an earlier pmwm still read their marked meshes: the robust key formats 2 (no payload code) and
3 (a BCH code), each with a small marked mesh, committed in ``tests/data/robust_keys`` (what wrote them: the
README there). A change that breaks an old key fails here, however the embedder changes."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

import pmwm
from pmwm import attacks

FIXTURES = Path(__file__).parent / "data" / "robust_keys"
WRITTEN = {  # fixture: (the key's robust format, the text payload or the bits marked)
    "format2": (2, "OWNR"),
    "format3": (3, "0110100111010010"),
}


def _unpacked(tmp_path: Path, name: str) -> tuple[pmwm.SourceMesh, pmwm.WatermarkKey, dict]:
    """The fixture's marked mesh and key, read from their files as a user's would be."""
    mesh, key = tmp_path / f"{name}.ply", tmp_path / f"{name}.key.json"
    mesh.write_bytes(gzip.decompress((FIXTURES / f"{name}.ply.gz").read_bytes()))
    key.write_bytes(gzip.decompress((FIXTURES / f"{name}.key.json.gz").read_bytes()))
    return pmwm.read_mesh(mesh), pmwm.read_key(key), json.loads(key.read_text())


def _payload(verdict: pmwm.Verdict, key: pmwm.WatermarkKey) -> str:
    return verdict.payload if key.payload_kind == "text" else verdict.bits


@pytest.mark.parametrize("name", sorted(WRITTEN))
def test_an_old_key_reads_its_marked_mesh_with_the_payload_confirmed(tmp_path, name):
    version, payload = WRITTEN[name]
    src, key, doc = _unpacked(tmp_path, name)
    assert doc["extra"]["robust_version"] == version  # (the fixture is the format it stands for)
    v = pmwm.verify(src.vertices, src.faces, key)
    assert v.marked and v.payload_confirmed and _payload(v, key) == payload


@pytest.mark.parametrize("name", sorted(WRITTEN))
def test_an_old_key_reads_a_reposed_lightly_simplified_copy(tmp_path, name):
    src, key, _ = _unpacked(tmp_path, name)
    Vp, Fp = attacks.reorder(*attacks.similarity(src.vertices, src.faces, seed=10), seed=20)
    Vs, Fs = attacks.simplify(Vp.astype(np.float32).astype(np.float64), Fp, 0.1)
    v = pmwm.verify(Vs, Fs, key)
    assert v.marked and v.payload_confirmed and _payload(v, key) == WRITTEN[name][1]
