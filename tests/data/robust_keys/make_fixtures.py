"""Write the robust-key fixtures of this folder: the small blob of ``tests/meshes.py`` marked by the robust
scheme, and its key, for key format 2 (no payload code: a 64-bit payload, whose codeword's sites the blob
cannot hold) and key format 3 (a 16-bit payload and its BCH code). Each as gzipped files (the key's 3,000
registration samples alone are 220 KB of JSON): NAME.ply.gz (binary PLY, float32, as ``pmwm embed`` writes
it) and NAME.key.json.gz (the key file's bytes).

Run from the repository root with the pmwm to record (its commit goes in README.md):
    PYTHONPATH=core:tests python tests/data/robust_keys/make_fixtures.py
The tests read the committed files; they do not run this.
"""

from __future__ import annotations

import gzip
import json
import sys
import tempfile
from pathlib import Path

import meshes
import pmwm

HERE = Path(__file__).resolve().parent
FIXTURES = {  # name: (embed options, the robust key format expected)
    "format2": (dict(payload="OWNR", seed=2), 2),
    "format3": (dict(bits="0110100111010010", seed=2), 3),
}


def main() -> int:
    V, F = meshes.blob()
    for name, (options, version) in FIXTURES.items():
        res = pmwm.embed(V, F, pmwm.EmbedOptions(progressive=False, **options))
        got = json.loads(res.key.to_json())["extra"]["robust_version"]
        if got != version:
            raise SystemExit(f"{name}: this pmwm wrote key format {got}, not {version}")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "m.ply"
            pmwm.write_mesh(path, res.vertices, res.faces)
            mesh = path.read_bytes()
        (HERE / f"{name}.ply.gz").write_bytes(gzip.compress(mesh, 9, mtime=0))
        (HERE / f"{name}.key.json.gz").write_bytes(gzip.compress(res.key.to_json().encode(), 9, mtime=0))
        print(name, "written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
