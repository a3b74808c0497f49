"""Any pose, any copy: the robust scheme on near-symmetric shapes never tuned on, and the speed of verify.

Part 1 (``--copies N``): shapes of the near-symmetric families of ``pmwm_bench.corpus``, never tuned on
(``--shapes tuning``: those of ``pose_shapes`` beside this file, the ones the pose search was tuned on),
each marked with a random text payload under a random key, then attacked:
a random pose (rotation, scale, translation), mirrored or not, and one damage drawn at random: quadric
simplification (10-50 %), noise, Laplacian smoothing, overmarking by another key at 1-4x the strength,
quantization, or a chain (simplification, then quantization, noise or smoothing). Each copy is verified with
its key; counted: copies read exactly (marked, payload confirmed and right), a wrong payload shown (a
payload printed that is not the one marked: the target is none), a mirror reported wrongly. Every copy is
also verified with a wrong key (false positives). Seeds are drawn fresh at each run and printed; ``--seed S``
replays a run.

Part 2 (``--speed``): the time of ``pmwm.verify`` (median of ``--repeat`` runs, loading excluded) on the
bundled bunny for the cases verify is held to (the marked mesh, a reordered copy, half cropped and posed,
50 % simplified, a wrong key) and for a mirrored posed copy and a posed near-symmetric shape, with this
worktree's code and, with ``--compare PATH`` (a checkout's ``core`` folder), with that code in a subprocess.

Run: nice -n 10 python benchmarks/bench_pose.py --copies 200 --out pose.jsonl
     nice -n 10 python benchmarks/bench_pose.py --copies 100 --damage simplify --families cad4,cad2
     nice -n 10 python benchmarks/bench_pose.py --copies 60 --damage overmark --seed S   (one damage alone)
     nice -n 10 python benchmarks/bench_pose.py --speed --compare /work/main/core
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import pmwm  # noqa: E402
from pmwm import attacks  # noqa: E402

import pose_shapes  # noqa: E402
from pmwm_bench import corpus  # noqa: E402

SHAPES = {
    "report": (corpus.generate, "pmwm_bench.corpus"),  # never tuned on
    "tuning": (pose_shapes.generate, "benchmarks/pose_shapes.py"),
}  # the pose search was tuned on these
generate, SHAPES_FROM = SHAPES["report"]

FAMILIES = ("ellipsoid", "bilateral", "cad2", "cad4")
DAMAGES = ("simplify", "noise", "smooth", "overmark", "quantize", "chain")
LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"


def mirror(V: np.ndarray, F: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A mirror image across a random coordinate plane; faces flipped back or not (both happen)."""
    W = V.copy()
    W[:, rng.integers(3)] *= -1.0
    return W, (F[:, ::-1].copy() if rng.random() < 0.5 else F)


def damage(V, F, kind: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, dict]:
    """One damage of ``kind``, its parameters drawn from rng."""
    seed = int(rng.integers(1 << 31))
    if kind == "simplify":
        r = float(rng.uniform(0.1, 0.5))
        return (*attacks.simplify(V, F, r), {"simplify": round(r, 3)})
    if kind == "noise":
        a = float(rng.uniform(0.0005, 0.002))
        return (*attacks.noise_benchmark(V, F, a, seed=seed), {"noise": round(a, 5)})
    if kind == "smooth":
        lam, it = float(rng.uniform(0.1, 0.5)), int(rng.integers(1, 6))
        return (*attacks.smooth_laplacian(V, F, lam, it), {"smooth": [round(lam, 3), it]})
    if kind == "quantize":
        b = int(rng.integers(8, 12))
        return (*attacks.quantize(V, F, b), {"quantize": b})
    if kind == "chain":
        W, G = attacks.simplify(V, F, float(rng.uniform(0.1, 0.5)))
        then = DAMAGES[int(rng.integers(3))]
        W, G, p = damage(W, G, {"simplify": "quantize", "noise": "noise", "smooth": "smooth"}[then], rng)
        return W, G, {"chain": p}
    raise ValueError(kind)


def one_shape(
    family: str, shape_seed: int, rng: np.random.Generator, copies: int, out, kinds: tuple = DAMAGES
) -> list[dict]:
    V, F = generate(family, shape_seed)
    payload = "".join(rng.choice(list(LETTERS), int(rng.integers(3, 8))))
    key_seed = int(rng.integers(1 << 31))
    try:
        res = pmwm.embed(V, F, pmwm.EmbedOptions(payload=payload, seed=key_seed, progressive=False))
        wrong_key = pmwm.embed(V, F, pmwm.EmbedOptions(payload="WRONG", seed=key_seed + 1, progressive=False)).key
    except pmwm.PayloadError as exc:  # a shape too small for the payload: recorded, not counted
        out.write(json.dumps({"family": family, "shape_seed": shape_seed, "embed_refused": str(exc)}) + "\n")
        return []
    rows = []
    for _ in range(copies):
        W, G = res.vertices, res.faces
        kind = kinds[int(rng.integers(len(kinds)))]
        params: dict = {}
        if kind == "overmark":
            f = float(rng.uniform(1.0, 4.0))
            try:
                W = pmwm.embed(
                    W,
                    G,
                    pmwm.EmbedOptions(
                        payload="THIEF", seed=int(rng.integers(1 << 31)), strength=2.0 * f, progressive=False
                    ),
                ).vertices
            except pmwm.PayloadError:
                continue
            params = {"overmark": round(f, 2)}
        mirrored = bool(rng.random() < 0.5)
        if mirrored:
            W, G = mirror(W, G, rng)
        W, G = attacks.similarity(W, G, seed=int(rng.integers(1 << 31)))
        if kind != "overmark":
            W, G, params = damage(W, G, kind, rng)
        t, c = time.perf_counter(), time.process_time()
        v = pmwm.verify(W, G, res.key)
        dt, dc = time.perf_counter() - t, time.process_time() - c
        c = time.process_time()
        w = pmwm.verify(W, G, wrong_key)
        wc = time.process_time() - c
        confirmed = bool(v.payload_confirmed)
        row = {
            "family": family,
            "shape_seed": shape_seed,
            "payload": payload,
            "mirrored": mirrored,
            "attack": params,
            "marked": v.marked,
            "p": v.p_value,
            "confirmed": confirmed,
            "shown": v.payload,
            "exact": bool(v.marked and confirmed and v.payload == payload),
            "wrong_shown": v.payload is not None and v.payload != payload,
            "mirror_said": getattr(v.detail, "mirrored", None),
            "corrected": getattr(v.detail, "corrected", None),
            "bit_errors": v.bit_errors,
            "code": getattr(v.detail, "payload_code", None),
            "poses_read": getattr(v.detail, "poses_read", None),
            "verify_s": round(dt, 3),
            "verify_cpu_s": round(dc, 3),
            "wrong_key_cpu_s": round(wc, 3),
            "wrong_key_marked": w.marked,
            "wrong_key_shown": w.payload,
        }
        rows.append(row)
        out.write(json.dumps(row) + "\n")
        out.flush()
    return rows


def _spread(rows: list[dict], name: str) -> str:
    """Median / max of a timing column ('-' for rows of runs that did not record it)."""
    x = [r[name] for r in rows if name in r]
    return f"{np.median(x):.2f} / {max(x):.2f}" if x else "-"


def summary(rows: list[dict]) -> str:
    lines = [
        "| family | copies | read exactly | marked | wrong payload shown | mirror misreported | "
        "wrong key marked | verify CPU s, median / max | wrong key CPU s, median / max |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for fam in sorted({r["family"] for r in rows}) + ["all"]:
        rs = [r for r in rows if fam in ("all", r["family"])]
        mis = sum(bool(r["marked"]) and bool(r["mirror_said"]) != r["mirrored"] for r in rs)
        lines.append(
            f"| {fam} | {len(rs)} | {sum(r['exact'] for r in rs)} | {sum(r['marked'] for r in rs)} | "
            f"{sum(r['wrong_shown'] or r['wrong_key_shown'] is not None for r in rs)} | {mis} | "
            f"{sum(r['wrong_key_marked'] for r in rs)} | {_spread(rs, 'verify_cpu_s')} | "
            f"{_spread(rs, 'wrong_key_cpu_s')} |"
        )
    lines += ["", "| damage | copies | read exactly |", "|---|---|---|"]
    for kind in DAMAGES:
        rs = [r for r in rows if kind in r["attack"]]
        if rs:
            lines.append(f"| {kind} | {len(rs)} | {sum(r['exact'] for r in rs)} |")
    return "\n".join(lines)


SPEED_CASES = """
import sys, time, json
import numpy as np
import pmwm
from pmwm import attacks
src = pmwm.read_mesh(pmwm.__path__[0] + "/data/bunny.off")
V, F = src.vertices, src.faces
res = pmwm.embed(V, F, pmwm.EmbedOptions(payload="OWNR", seed=1, progressive=False))
wrong = pmwm.embed(V, F, pmwm.EmbedOptions(payload="OWNR", seed=2, progressive=False)).key
M, G = res.vertices, res.faces
posed = attacks.similarity
cases = {
    "marked": (M, G, res.key),
    "reordered": (*attacks.reorder(M, G, seed=1), res.key),
    "half cropped, posed": (*posed(*attacks.crop_plane(M, G, 0.5, seed=1), seed=1), res.key),
    "50 % simplified": (*attacks.simplify(M, G, 0.5), res.key),
    "posed, 50 % simplified": (*attacks.simplify(*posed(M, G, seed=3), 0.5), res.key),
    "wrong key": (M, G, wrong),
    "mirrored, posed, 30 % simplified": (*attacks.simplify(*posed(M * [-1, 1, 1], G[:, ::-1], seed=2), 0.3), res.key),
}
out = {}
for name, (A, B, key) in cases.items():
    pmwm.verify(A, B, key)
    wall, cpu = [], []
    for _ in range(int(sys.argv[1])):
        t, c = time.perf_counter(), time.process_time()
        v = pmwm.verify(A, B, key)
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    out[name] = [float(np.median(wall)), float(np.median(cpu)), bool(v.marked), v.payload]
print(json.dumps(out))
"""


def speed(repeat: int, compare: str | None) -> None:
    runs = {"this worktree": str(HERE.parent / "core")}
    if compare:
        runs["compare " + compare] = compare
    env = dict(os.environ)
    for label, core in runs.items():
        env["PYTHONPATH"] = core
        got = json.loads(
            subprocess.run(
                [sys.executable, "-c", SPEED_CASES, str(repeat)], env=env, check=True, capture_output=True, text=True
            ).stdout
        )
        print(f"\n{label} ({core}): median of {repeat} verifies, wall and CPU seconds (loading excluded)")
        for name, (t, c, marked, payload) in got.items():
            print(f"  {name:36s} wall {t:6.3f}  cpu {c:6.3f}  marked={marked} payload={payload!r}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--copies", type=int, default=0, help="attacked copies in all (part 1)")
    ap.add_argument("--per-shape", type=int, default=6, help="attacked copies per marked shape")
    ap.add_argument("--seed", type=int, default=None, help="replay a run (default: fresh)")
    ap.add_argument("--out", default="pose.jsonl", help="one JSON line per copy (appended)")
    ap.add_argument(
        "--shapes",
        choices=sorted(SHAPES),
        default="report",
        help="report: pmwm_bench.corpus (never tuned on); tuning: pose_shapes.py",
    )
    ap.add_argument(
        "--uncoded", action="store_true", help="mark without the payload code (as keys of format 2), to compare"
    )
    ap.add_argument("--families", default=",".join(FAMILIES), help="comma-separated families drawn from")
    ap.add_argument(
        "--damage",
        default=",".join(DAMAGES),
        help=f"the damages drawn from, comma-separated (default: all of {','.join(DAMAGES)})",
    )
    ap.add_argument("--speed", action="store_true", help="part 2: verify's speed on the bunny")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--summarize", default=None, help="print the tables of a JSON-lines file of an earlier run")
    ap.add_argument("--compare", default=None, help="another checkout's core folder, for --speed")
    a = ap.parse_args()
    global generate, SHAPES_FROM
    generate, SHAPES_FROM = SHAPES[a.shapes]
    commit = subprocess.run(
        ["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    print(
        f"commit {commit}, {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}; shapes from {SHAPES_FROM}"
    )
    if a.summarize:
        rows = [json.loads(line) for line in open(a.summarize)]
        print(summary([r for r in rows if "marked" in r]))
    if a.uncoded:
        import importlib

        importlib.import_module("pmwm.schemes.robust.embed").payload_code = lambda k: None
    if a.copies:
        kinds = tuple(a.damage.split(","))
        if set(kinds) - set(DAMAGES):
            ap.error(f"--damage: unknown {sorted(set(kinds) - set(DAMAGES))}; known: {','.join(DAMAGES)}")
        seed = a.seed if a.seed is not None else int.from_bytes(os.urandom(4), "little")
        print(f"run seed {seed} (replay with --seed {seed})", flush=True)
        rng = np.random.default_rng(seed)
        rows: list = []
        with open(a.out, "a") as out:
            families = tuple(a.families.split(","))
            head = {"run_seed": seed, "commit": commit, "shapes": SHAPES_FROM, "uncoded": a.uncoded, "damages": kinds}
            head["families"] = families
            out.write(json.dumps(head) + "\n")
            while len(rows) < a.copies:  # (a shape too small for the payload adds no row)
                family = families[int(rng.integers(len(families)))]
                shape_seed, n = int(rng.integers(1 << 31)), min(a.per_shape, a.copies - len(rows))
                rows += one_shape(family, shape_seed, rng, n, out, kinds)
                print(f"{len(rows)} copies", flush=True)
        print(summary(rows))
    if a.speed:
        speed(a.repeat, a.compare)


if __name__ == "__main__":
    main()
