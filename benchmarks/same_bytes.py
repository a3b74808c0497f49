"""Same files before and after a change that must not change behaviour: the bytes ``pmwm embed`` writes.

Run: python benchmarks/same_bytes.py OUT.json [--meshes bunny_wm_benchmark,fandisk,...] [--schemes ...]
     python benchmarks/same_bytes.py --compare OLD.json NEW.json

For every data mesh (../shared/data or $PMWM_TEST_DATA) and scheme, runs ``pmwm embed`` with a fixed seed,
payload and pass phrase, writing the marked mesh (PLY), the progressive mesh (.pmwm) and the key, and records
the SHA-256 of each file and of ``pmwm verify --json`` on the marked mesh. ``--compare`` lists the
differences between two such runs and exits non-zero when there is any.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import data_dirs  # noqa: E402

MESHES = "bunny_wm_benchmark.off,fandisk.obj,cow.obj,horse_cyberware.ply,igea_cyberware.ply,rocker_arm.obj"
SCHEMES = "robust,paper,cho1,cho2,blind"


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.exists() else "missing"


def run(meshes: list[str], schemes: list[str]) -> dict:
    data = next(d for d in data_dirs() if d.is_dir())
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        phrase = t / "phrase.txt"
        phrase.write_text("correct horse battery staple\n")
        for mesh in meshes:
            for scheme in schemes:
                stem = f"{Path(mesh).stem}-{scheme}"
                marked, pm, key = t / f"{stem}.ply", t / f"{stem}.pmwm", t / f"{stem}.json"
                cmd = [
                    sys.executable,
                    "-m",
                    "pmwm",
                    "embed",
                    str(data / mesh),
                    "-o",
                    str(marked),
                    "--pm",
                    str(pm),
                    "--seed",
                    "7",
                    "--payload",
                    "OWNR",
                    "--scheme",
                    scheme,
                    "-q",
                ]
                cmd += ["--passphrase-file", str(phrase)] if scheme == "blind" else ["--key", str(key)]
                e = subprocess.run(cmd, capture_output=True, text=True)
                vcmd = [sys.executable, "-m", "pmwm", "verify", str(marked), "--json"]
                vcmd += ["--passphrase-file", str(phrase)] if scheme == "blind" else ["--key", str(key)]
                v = subprocess.run(vcmd, capture_output=True, text=True)
                out[stem] = {
                    "embed_exit": e.returncode,
                    "marked": _sha(marked),
                    "pmwm": _sha(pm),
                    "key": _sha(key) if scheme != "blind" else "none",
                    "verify": hashlib.sha256(v.stdout.encode()).hexdigest(),
                    "verify_exit": v.returncode,
                }
                print(stem, out[stem], flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?")
    ap.add_argument("--meshes", default=MESHES)
    ap.add_argument("--schemes", default=SCHEMES)
    ap.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"))
    a = ap.parse_args()
    if a.compare:
        old, new = (json.loads(Path(p).read_text()) for p in a.compare)
        both = [k for k in old if k in new]
        diff = [(k, f, old[k][f], new[k].get(f)) for k in both for f in old[k] if new[k].get(f) != old[k][f]]
        for row in diff:
            print("differs:", *row)
        print(f"{len(both) - len({d[0] for d in diff})} of {len(both)} runs in both identical")
        return 1 if diff else 0
    os.environ.setdefault("PYTHONHASHSEED", "0")
    Path(a.out).write_text(json.dumps(run(a.meshes.split(","), a.schemes.split(",")), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
