"""Held-out robustness: the keyed ("robust") and blind schemes on meshes nobody tuned them on.

Run: nice -n 10 python benchmarks/bench_heldout.py [--meshes report] [--per-family 1] [--vertices 0]
     [--fp-secrets 500] [--out benchmarks/results/heldout.json] [--md benchmarks/results/heldout.md]
     python benchmarks/bench_heldout.py --markdown-only [--also MORE.json ...]   (the fragment from the JSON)

Meshes: the REPORT_ONLY meshes of ``pmwm_bench.split`` and shapes of every family of
``pmwm_bench.corpus`` from seeds drawn fresh at each run (recorded in the JSON with the attack seed and
the pass phrase). Default settings, payload "ACME-2026". Attacks (the held-out protocol): pose and reorder;
re-export OBJ/PLY/STL/GLB; 8-bit quantization; uniform noise of 0.1 % of the bounding-box diagonal
per coordinate; five uniform Laplacian steps (lambda 0.5); five cotangent steps (pymeshlab's
Laplacian smoothing, its default weights); 50 % simplification by fast-simplification and by
pymeshlab's quadric edge collapse; one midpoint and one Loop subdivision; a 10 % plane crop; isotropic
remeshing at the mean edge length (pymeshlab, its default 10 iterations). A copy counts as read when the
verdict is marked (p < 1e-6) and gives the whole payload.

False positives: every unmarked shape read by the blind reader with ``--fp-secrets`` random secrets
(the bins' statistics do not depend on the secret: measured once per shape, decided for every secret;
a secret stands for the phrase scrypt maps to it), the blind-marked copies with as many wrong secrets,
and for the keyed scheme each unmarked original verified with the key of its own marked copy and with
the keys of two other shapes of the run. Rates counted at p < 1e-2, 1e-3 and 1e-6.

The JSON is rewritten after every mesh, so a run cut short keeps what it measured.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import command, mesh_path

import pmwm
from pmwm import attacks, metrics
from pmwm.errors import PmwmError
from pmwm.schemes import blind
from pmwm_bench import corpus, split
from pmwm_bench.report import commit, machine

PAYLOAD = "ACME-2026"
ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def _ml(V, F, run):
    """pymeshlab's filter ``run(meshset)`` on the mesh; its result as (vertices float64, faces int64)."""
    import pymeshlab as ml

    ms = ml.MeshSet()
    ms.add_mesh(ml.Mesh(np.asarray(V, np.float64), np.asarray(F, np.int32)))
    run(ms, ml)
    m = ms.current_mesh()
    return np.asarray(m.vertex_matrix(), np.float64), np.asarray(m.face_matrix(), np.int64)


def mean_edge(V, F) -> float:
    e = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    return float(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1).mean())


def noise_diagonal(V, F, seed):
    """Uniform noise in +- 0.1 % of the bounding-box diagonal on every coordinate."""
    rng = np.random.default_rng(seed)
    return V + rng.uniform(-1, 1, V.shape) * 0.001 * metrics.bbox_diagonal(V), F


def pose_reorder(V, F, seed):
    return attacks.reorder(*attacks.similarity(V, F, seed=seed), seed=seed + 1)


ATTACKS = {
    "pose+reorder": pose_reorder,
    **{
        f"re-export {e[1:].upper()}": (lambda e: lambda V, F, s: attacks.reexport(V, F, e))(e)
        for e in (".obj", ".ply", ".stl", ".glb")
    },
    "quantization 8 bits": lambda V, F, s: attacks.quantize(V, F, bits=8),
    "noise 0.1 % diag": noise_diagonal,
    "Laplacian 5 x 0.5": lambda V, F, s: attacks.smooth_laplacian(V, F, lam=0.5, iterations=5),
    "cotangent 5 (pymeshlab)": lambda V, F, s: _ml(
        V, F, lambda ms, ml: ms.apply_coord_laplacian_smoothing(stepsmoothnum=5)
    ),
    "simplify 50 % (fast-simplification)": lambda V, F, s: attacks.simplify(V, F, ratio=0.5),
    "simplify 50 % (pymeshlab quadric)": lambda V, F, s: _ml(
        V, F, lambda ms, ml: ms.meshing_decimation_quadric_edge_collapse(targetfacenum=len(F) // 2)
    ),
    "subdivision midpoint": lambda V, F, s: attacks.subdivide(V, F, "midpoint"),
    "subdivision Loop": lambda V, F, s: attacks.subdivide(V, F, "loop"),
    "crop 10 % plane": lambda V, F, s: attacks.crop_plane(V, F, fraction=0.1, seed=s),
    "isotropic remesh (pymeshlab)": lambda V, F, s: _ml(
        V, F, lambda ms, ml: ms.meshing_isotropic_explicit_remeshing(targetlen=ml.PureValue(mean_edge(V, F)))
    ),
}


def read_ok(v) -> bool:
    return bool(v.marked and v.payload == PAYLOAD)


SCHEMES = ("robust", "blind")


def run_mesh(name, V, F, phrase, attack_seed, doc, keys, schemes=SCHEMES):
    """Embed with each of ``schemes``, attack, verify; append the rows to ``doc``."""
    entry = {"mesh": name, "vertices": len(V), "faces": len(F), "schemes": {}}
    for scheme in schemes:
        t0 = time.perf_counter()
        opts = pmwm.EmbedOptions(
            scheme=scheme, payload=PAYLOAD, progressive=False, passphrase=phrase if scheme == "blind" else None
        )
        try:
            res = pmwm.embed(V, F, opts)
        except PmwmError as exc:
            entry["schemes"][scheme] = {"refused": str(exc)}
            print(f"  {name} {scheme}: refused: {exc}", flush=True)
            continue
        out = {
            "embed_s": time.perf_counter() - t0,
            "mrms": metrics.surface_distance(V, F, res.vertices, res.faces, 20000, seed=1)[0],
            "attacks": {},
            "notes": list(res.notes),
        }
        if scheme == "robust":
            keys.append((name, res.key))
        verify = (
            (lambda Va, Fa: pmwm.verify(Va, Fa, res.key))
            if scheme == "robust"
            else (lambda Va, Fa: pmwm.verify(Va, Fa, passphrase=phrase))
        )
        for i, (label, fn) in enumerate(ATTACKS.items()):
            try:
                Va, Fa = fn(res.vertices, res.faces, attack_seed + i)
            except Exception as exc:  # an attack that cannot run on this mesh is recorded, not counted
                out["attacks"][label] = {"attack_failed": f"{type(exc).__name__}: {exc}"[:200]}
                continue
            try:
                v = verify(Va, Fa)
                out["attacks"][label] = {
                    "read": read_ok(v),
                    "p": float(v.p_value),
                    "marked": bool(v.marked),
                    "reader": type(v.detail).__name__,
                }
            except PmwmError as exc:
                out["attacks"][label] = {"read": False, "error": str(exc)[:200]}
        n_read = sum(a.get("read", False) for a in out["attacks"].values())
        print(f"  {name} {scheme}: MRMS {out['mrms']:.4f} %, {n_read}/{len(ATTACKS)} read", flush=True)
        if scheme == "blind":
            out["_marked"] = res.vertices  # (for the false positives; dropped before saving)
        entry["schemes"][scheme] = out
    doc["meshes"].append(entry)
    return entry


def blind_false_positives(shapes, n_secrets, rng):
    """Verdicts marked at p < 1e-2, 1e-3, 1e-6 among shapes x random secrets (statistics once per shape)."""
    counts = {"verifications": 0, "p<1e-2": 0, "p<1e-3": 0, "p<1e-6": 0}
    for V, F in shapes:
        stats = blind.bin_statistics(V, F)
        for _ in range(n_secrets):
            p = blind.decide(stats, rng.bytes(16).hex()).p_value
            counts["verifications"] += 1
            for t, k in ((1e-2, "p<1e-2"), (1e-3, "p<1e-3"), (1e-6, "p<1e-6")):
                counts[k] += int(p < t)
    return counts


def robust_false_positives(originals, keys, others_per_mesh: int = 2):
    """Unmarked originals verified with the key of their own marked copy and ``others_per_mesh`` keys of
    other shapes of the run."""
    counts = {"verifications": 0, "own_key": 0, "refused": 0, "p<1e-2": 0, "p<1e-3": 0, "p<1e-6": 0}
    for i, (name, V, F) in enumerate(originals):
        own = [k for k in keys if k[0] == name]
        others = [k for k in keys if k[0] != name]
        for kname, key in own + [others[(i + j) % len(others)] for j in range(min(others_per_mesh, len(others)))]:
            try:
                p = pmwm.verify(V, F, key).p_value
            except PmwmError:
                counts["refused"] += 1
                continue
            counts["verifications"] += 1
            counts["own_key"] += int(kname == name)
            for t, k in ((1e-2, "p<1e-2"), (1e-3, "p<1e-3"), (1e-6, "p<1e-6")):
                counts[k] += int(p < t)
    return counts


def merged(docs: list) -> dict:
    """Several runs as one: their meshes side by side, their false-positive counts summed. A run of some schemes
    alone (``--schemes``) replaces those schemes' figures of the runs listed before it (runs after it add up)."""
    ran = [tuple(d.get("schemes_run", SCHEMES)) for d in docs]
    again = {s: min((i for i, r in enumerate(ran) if s in r and len(r) < len(SCHEMES)), default=0) for s in SCHEMES}
    keep = [{s for s in r if i >= again[s]} for i, r in enumerate(ran)]
    meshes = []
    for d, k in zip(docs, keep):
        meshes += [{**m, "schemes": {s: x for s, x in m["schemes"].items() if s in k}} for m in d["meshes"]]
    doc = {"meshes": [m for m in meshes if m["schemes"]], "runs": [d for d, k in zip(docs, keep) if k]}
    fp_keys = {"blind": ("blind_unmarked", "blind_wrong_phrase"), "robust": ("robust",)}
    fps = {
        name: [
            d["false_positives"][name] for d, k in zip(docs, keep) if s in k and name in d.get("false_positives", {})
        ]
        for s, names in fp_keys.items()
        for name in names
    }
    doc["false_positives"] = {
        name: {c: sum(f[c] for f in fs) for c in fs[0] if c != "command"} for name, fs in fps.items() if fs
    }
    return doc


def markdown(doc) -> str:
    groups = {
        "report-only data meshes": [m for m in doc["meshes"] if ":" not in m["mesh"]],
        "generated shapes": [m for m in doc["meshes"] if ":" in m["mesh"]],
    }
    lines = [
        f"Held-out robustness (`benchmarks/bench_heldout.py`): payload `{PAYLOAD}`, default settings; "
        "a copy counts when the verdict is marked (p < 1e-6) with the whole payload; a refused embed "
        "counts as a copy not read.",
        "",
    ]
    for run in doc.get("runs", [doc]):
        lines += [
            f"- run `{run['command']}` ({', '.join(run.get('schemes_run', SCHEMES))}) at commit {run['commit']}, "
            f"{run['started']} - "
            f"{run.get('finished', 'cut short')}; attack seed {run['attack_seed']}, blind pass phrase "
            f"`{run['phrase']}`; generated shapes (family: seeds from os.urandom): "
            + ("; ".join(f"{f}: {', '.join(map(str, s))}" for f, s in run["corpus_seeds"].items()) or "none")
        ]
    lines += [f"- machine: {doc.get('runs', [doc])[0]['machine']}", ""]
    head = (
        "| attack | "
        + " | ".join(
            f"{s} on {g} ({sum(s in m['schemes'] for m in ms)})"
            for s in ("robust", "blind")
            for g, ms in groups.items()
        )
        + " |"
    )
    lines += [head, "|" + "---|" * (1 + 2 * len(groups))]

    def cell(scheme, ms, label):
        got = [m["schemes"].get(scheme, {}) for m in ms]
        rows = [
            g["attacks"][label]
            for g in got
            if "attacks" in g and label in g["attacks"] and "attack_failed" not in g["attacks"][label]
        ]
        refused = sum("refused" in g for g in got)
        return f"{sum(r['read'] for r in rows)}/{len(rows) + refused}"

    for label in ATTACKS:
        lines.append(
            f"| {label} | "
            + " | ".join(cell(s, ms, label) for s in ("robust", "blind") for ms in groups.values())
            + " |"
        )
    lines.append("")
    for s in ("robust", "blind"):
        for g, ms in groups.items():
            got = [m["schemes"].get(s, {}) for m in ms]
            mr = [x["mrms"] for x in got if "mrms" in x]
            refused = [m["mesh"] for m in ms if "refused" in m["schemes"].get(s, {})]
            if mr:
                lines.append(
                    f"- {s} on {g}: marking MRMS (% of the bbox diagonal) median {np.median(mr):.4f}, "
                    f"max {max(mr):.4f}" + (f"; embed refused on {', '.join(refused)}" if refused else "")
                )
    for s in ("robust", "blind"):
        wrong = [
            f"{m['mesh']} / {a}"
            for m in doc["meshes"]
            for a, r in m["schemes"].get(s, {}).get("attacks", {}).items()
            if r.get("marked") and not r.get("read")
        ]
        if wrong:
            lines.append(
                f"- {s}: marked (p < 1e-6) without the whole payload in {len(wrong)} copies: " + "; ".join(wrong)
            )
    fp = doc.get("false_positives") or {}
    fp_rows = [
        (lab, fp[k])
        for k, lab in (
            ("blind_unmarked", "blind, unmarked shapes x random phrases"),
            ("blind_wrong_phrase", "blind, marked copies x wrong phrases"),
            ("robust", "robust, unmarked originals x own key and 2 others"),
        )
        if k in fp
    ]
    if fp_rows:
        lines += [
            "",
            "False positives (verdicts with p below each level):",
            "",
            "| reading | verifications | p < 1e-2 | p < 1e-3 | p < 1e-6 (marked) |",
            "|---|---|---|---|---|",
            *[
                f"| {lab} | {c['verifications']} | {c['p<1e-2']} | {c['p<1e-3']} | {c['p<1e-6']} |"
                for lab, c in fp_rows
            ],
        ]
    failed = [
        (m["mesh"], s, a, r["attack_failed"])
        for m in doc["meshes"]
        for s, x in m["schemes"].items()
        for a, r in x.get("attacks", {}).items()
        if "attack_failed" in r
    ]
    if failed:
        lines += [
            "",
            "Attacks that could not run (not counted): " + "; ".join(f"{m} {s} {a}: {e}" for m, s, a, e in failed),
        ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="report", help="'report' (REPORT_ONLY), 'none', or file names")
    ap.add_argument("--per-family", type=int, default=1)
    ap.add_argument("--families", default="all")
    ap.add_argument("--vertices", type=int, default=0, help="generated shapes' vertices aimed at (0: the seed's)")
    ap.add_argument("--fp-secrets", type=int, default=500)
    ap.add_argument("--schemes", default=",".join(SCHEMES), help="the schemes to run, e.g. 'robust'")
    ap.add_argument("--out", default=str(RESULTS / "heldout.json"))
    ap.add_argument("--md", default=str(RESULTS / "heldout.md"))
    ap.add_argument("--markdown-only", action="store_true")
    ap.add_argument("--also", nargs="*", default=[], help="with --markdown-only: more results files to merge")
    ap.add_argument(
        "--fp-only",
        action="store_true",
        help="the false positives alone, on the shapes of the results file (a run cut short)",
    )
    a = ap.parse_args(argv)
    if a.fp_only:
        return false_positives_again(a)
    if a.markdown_only:
        docs = [json.loads(Path(f).read_text()) for f in [a.out, *a.also]]
        Path(a.md).write_text(markdown(merged(docs)))
        return 0
    names = list(split.REPORT_ONLY) if a.meshes == "report" else [] if a.meshes == "none" else a.meshes.split(",")
    fams = None if a.families == "all" else a.families.split(",")
    seeds = split.draw_corpus(a.per_family, fams) if a.per_family else {}
    attack_seed = split.fresh_seeds(1)[0] % 2**40
    phrase = f"heldout {split.fresh_seeds(1)[0]:x}"
    doc = {
        "command": command(),
        "commit": commit(),
        "machine": machine(),
        "started": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "corpus_seeds": seeds,
        "vertices_aimed": a.vertices,
        "attack_seed": attack_seed,
        "phrase": phrase,
        "schemes_run": a.schemes.split(","),
        "meshes": [],
    }

    def save():
        clean = json.loads(json.dumps(doc, default=lambda o: None))
        for m in clean["meshes"]:
            m["schemes"].get("blind", {}).pop("_marked", None)
        tmp = a.out + ".tmp"
        Path(tmp).write_text(json.dumps(clean, indent=1))
        os.replace(tmp, a.out)

    generated = [(f, s) for f, ss in seeds.items() for s in ss]
    order = [x for pair in zip(names, generated) for x in pair] + names[len(generated) :] + generated[len(names) :]
    shapes = []
    keys, marked = [], []
    for item in order:  # data meshes and generated shapes in turn: a run cut short has some of each
        name, V, F = (
            (item, *pmwm_load(item))
            if isinstance(item, str)
            else (f"{item[0]}:{item[1]}", *corpus.generate(item[0], item[1], a.vertices or None))
        )
        shapes.append((name, V, F))
        print(name, len(V), flush=True)
        entry = run_mesh(name, V, F, phrase, attack_seed, doc, keys, doc["schemes_run"])
        if "_marked" in entry["schemes"].get("blind", {}):
            marked.append((entry["schemes"]["blind"]["_marked"], F))
        save()
    rng = np.random.default_rng(attack_seed)
    doc["false_positives"] = {}
    if "blind" in doc["schemes_run"]:
        doc["false_positives"]["blind_unmarked"] = blind_false_positives(
            [(V, F) for _, V, F in shapes], a.fp_secrets, rng
        )
        doc["false_positives"]["blind_wrong_phrase"] = blind_false_positives(marked, a.fp_secrets, rng)
    if "robust" in doc["schemes_run"]:
        doc["false_positives"]["robust"] = robust_false_positives(shapes, keys)
    doc["finished"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    save()
    Path(a.md).write_text(markdown(merged([json.loads(Path(a.out).read_text())])))
    print(Path(a.md).read_text())
    return 0


def false_positives_again(a) -> int:
    """The false-positive stage on the shapes a results file names (its run cut short before it): the
    shapes loaded or generated again, marked again with the same phrase and payload."""
    doc = json.loads(Path(a.out).read_text())
    shapes, keys, marked = [], [], []
    for m in doc["meshes"]:
        name = m["mesh"]
        if ":" in name:
            fam, seed = name.split(":")
            V, F = corpus.generate(fam, int(seed), doc["vertices_aimed"] or None)
        else:
            V, F = pmwm_load(name)
        shapes.append((name, V, F))
        for scheme in ("robust", "blind"):
            if "refused" in m["schemes"].get(scheme, {"refused": 1}):
                continue
            res = pmwm.embed(
                V,
                F,
                pmwm.EmbedOptions(
                    scheme=scheme,
                    payload=PAYLOAD,
                    progressive=False,
                    passphrase=doc["phrase"] if scheme == "blind" else None,
                ),
            )
            (keys.append((name, res.key)) if scheme == "robust" else marked.append((res.vertices, F)))
        print(name, flush=True)
    rng = np.random.default_rng(doc["attack_seed"])
    doc["false_positives"] = {
        "blind_unmarked": blind_false_positives([(V, F) for _, V, F in shapes], a.fp_secrets, rng),
        "blind_wrong_phrase": blind_false_positives(marked, a.fp_secrets, rng),
        "robust": robust_false_positives(shapes, keys),
        "command": command(),
    }
    tmp = a.out + ".tmp"
    Path(tmp).write_text(json.dumps(doc, indent=1))
    os.replace(tmp, a.out)
    Path(a.md).write_text(markdown(doc))
    print(Path(a.md).read_text())
    return 0


def pmwm_load(name):
    src = pmwm.read_mesh(str(mesh_path(name)))
    return np.asarray(src.vertices, np.float64), np.asarray(src.faces, np.int64)


if __name__ == "__main__":
    sys.exit(main())
