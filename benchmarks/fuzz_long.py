"""Longer fuzz run of the .pmwm and key readers (the bounded one runs in CI: tests/test_pmfile.py).

Mutates valid files at random: bit flips, byte overwrites, truncation, insertion, header fields
rewritten with the checksum recomputed (so that the structural checks are reached), and for keys
random edits of the JSON text and of its fields. A failure is any exception other than
PMFormatError / KeyFileError, or a parsed progressive mesh whose decode raises.
Run: python benchmarks/fuzz_long.py [--seconds 300]. Writes the "fuzz" section of the report (its
fragment in benchmarks/results/).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, commit, load, machine, write_section  # noqa: E402

import pmwm  # noqa: E402
from pmwm.api import load_key_data  # noqa: E402
from pmwm.errors import KeyFileError, PMFormatError  # noqa: E402
from pmwm.key import WatermarkKey  # noqa: E402
from pmwm.progressive import HEADER, from_bytes, to_bytes  # noqa: E402


def mutate_pm(data: bytes, rng: np.random.Generator) -> bytes:
    b = bytearray(data)
    kind = rng.integers(0, 6)
    if kind == 0:  # flip bits
        for _ in range(rng.integers(1, 4)):
            i = rng.integers(0, len(b))
            b[i] ^= 1 << rng.integers(0, 8)
    elif kind == 1:  # truncate
        b = b[: rng.integers(0, len(b))]
    elif kind == 2:  # insert bytes
        i = rng.integers(0, len(b))
        b[i:i] = rng.integers(0, 256, rng.integers(1, 16)).astype(np.uint8).tobytes()
    elif kind == 3:  # overwrite a run
        i = rng.integers(0, len(b))
        n = rng.integers(1, 32)
        b[i : i + n] = rng.integers(0, 256, n).astype(np.uint8).tobytes()[: len(b) - i]
    else:  # header or body edit with a valid checksum, to reach the structural checks
        body = bytearray(b[:-32])
        if kind == 4:
            field = rng.integers(2, 8)
            vals = list(HEADER.unpack_from(body, 0))
            vals[field] = (
                int(rng.choice([0, 1, vals[field] + rng.integers(-3, 4), 2**32 - 1, rng.integers(0, 2**32)])) % 2**32
                if field >= 3
                else int(rng.integers(0, 2**16))
            )
            HEADER.pack_into(body, 0, *vals)
        else:
            i = rng.integers(HEADER.size, len(body))
            body[i] = rng.integers(0, 256)
        b = body + hashlib.sha256(body).digest()
    return bytes(b)


def mutate_key(text: str, rng: np.random.Generator) -> str:
    doc = json.loads(text)
    kind = rng.integers(0, 4)
    if kind == 0:
        chars = list(text)
        for _ in range(rng.integers(1, 6)):
            chars[rng.integers(0, len(chars))] = chr(rng.integers(32, 127))
        return "".join(chars)
    if kind == 1:
        return text[: rng.integers(0, len(text))]
    junk = [None, -1, 0, 1e400, "x", [], {}, 2**70, -(2**70), 1.5, "0" * 64, [[0, 0, 0, 0, 0]]]
    if kind == 2:
        key = str(rng.choice(list(doc.keys())))
        doc[key] = junk[rng.integers(0, len(junk))]
    else:
        if doc["carriers"]:
            row = doc["carriers"][rng.integers(0, len(doc["carriers"]))]
            row[rng.integers(0, 5)] = junk[rng.integers(0, len(junk))]
    return json.dumps(doc)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=300)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    V0, F0 = load("cow")
    res = pmwm.embed(V0, F0, pmwm.EmbedOptions(bits="1" * 16 + "0" * 16, seed=3))
    pm_bytes = to_bytes(res.pm)
    key_text = res.key.to_json()
    counts = {"pm": [0, 0, 0], "key": [0, 0, 0]}  # tried, rejected cleanly, failures
    failures: list[str] = []
    end = time.monotonic() + args.seconds
    V, F = res.vertices, res.faces
    while time.monotonic() < end:
        data = mutate_pm(pm_bytes, rng)
        c = counts["pm"]
        c[0] += 1
        try:
            pm = from_bytes(data)
            pm.decode()
        except PMFormatError:
            c[1] += 1
        except Exception:  # noqa: BLE001 - a failure is exactly what we count
            c[2] += 1
            failures.append("pm: " + traceback.format_exc().strip().splitlines()[-1])
        text = mutate_key(key_text, rng)
        c = counts["key"]
        c[0] += 1
        try:
            key = load_key_data(WatermarkKey.from_json(text))
            pmwm.verify(V, F, key)
        except KeyFileError:
            c[1] += 1
        except Exception:  # noqa: BLE001
            c[2] += 1
            failures.append("key: " + traceback.format_exc().strip().splitlines()[-1])
    lines = [
        "## Fuzzing the .pmwm and key readers",
        "",
        f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.",
        "",
        "| reader | inputs tried | rejected with the one-line error | parsed (and then decoded / verified) "
        "| failures |",
        "|---|---|---|---|---|",
    ]
    for name, (tried, rejected, failed) in counts.items():
        lines.append(
            f"| {'.pmwm' if name == 'pm' else 'key'} | {tried:,} | {rejected:,} | "
            f"{tried - rejected - failed:,} | {failed} |"
        )
    if failures:
        lines += ["", "Failures (first 10):", *[f"- `{f}`" for f in failures[:10]]]
    write_section("fuzz", "\n".join(lines))


if __name__ == "__main__":
    main()
