"""Speed of ``pmwm.verify`` (the call, not reading the files) on the cases of the speed target, against an
older commit run side by side.

Run: python benchmarks/bench_verify.py [--repeat 3] [--rounds 2] [--baseline REV]
(meshes from $PMWM_TEST_DATA or ../shared/data beside the checkout). Writes the "verify-speed"
section of the report (its fragment in benchmarks/results/).

Cases, on the bunny and igea, marked by the robust scheme (payload "bench", seed 1): the marked
mesh; a re-ordered copy; a copy cut in half by a plane, then rotated, scaled and moved; a copy
simplified by 50 %; the unmarked mesh read with a key made for the other mesh (registration finds
no fit: every start is tried), and with a key for this mesh made with another secret. Then the
paper scheme on a re-ordered copy (carriers found by position) and Cho et al. I (no spatial search).

With ``--scheme blind`` (section "verify-speed-blind"): the same meshes marked by the blind scheme
(payload "Acme", a pass phrase), the same attacks plus a 10 % plane crop, the unmarked mesh and the
marked one read with another pass phrase, the unmarked mesh cut in half (the crop search runs on
suspects with a planar cut, marked or not), the mesh cut flat before it was marked, read intact (its
own frame shows the mark in full: no crop search since db80848), and a copy subdivided once by Loop's
scheme (read on the coarse mesh under it since 7c3a7d4, when it shows more energy), and a copy quantized
to 8 bits (read after three smoothing steps too since 6037447, when its bins show the blur).

Every case is timed by two child processes, one importing this checkout's ``core``, one importing
``core`` of ``--baseline`` (extracted with ``git archive``); the two alternate for ``--rounds``
rounds of ``--repeat`` calls each, and the table gives the median of all calls. The verdicts of
both are compared. With ``--fresh``, every case is timed in a process of its own, its first and only
call (as ``pmwm verify`` reads one suspect per process: memory not yet mapped, caches cold), the two
commits alternating for ``--rounds`` rounds; the section's name then ends in "-fresh".

With ``--cli``, every case is timed as the user runs it: the suspect written to a PLY file (and the key to
a JSON file, or the pass phrase to a file), ``python -m pmwm verify`` as a whole process, beside a process
that only reads the two files as ``pmwm verify`` does (the same imports, ``read_key`` or the pass phrase
file, ``read_mesh``), the two alternating, best of ``--repeat`` each; their difference is the time
``pmwm verify`` takes beyond reading the two files. The section's name then ends in
"-cli"; no baseline. Its processes run with OMP_NUM_THREADS=1 and OPENBLAS_NUM_THREADS=1 (steadier on a
shared machine), unless ``--threads-as-set`` leaves them as this process has them (a user's default:
unset, every library's threads on every core); the section's name then ends in "-cli-threads".
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Optional

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import ROOT, best_alternating, byte_compiled, command, commit, load, machine, write_section  # noqa: E402

MODELS = ("bunny", "igea")  # names in the catalogue, pmwm_bench.models
BASELINE = "88eb246"  # the last commit with brute-force spatial search
CASES = (
    "marked",
    "re-ordered",
    "cut in half, posed",
    "simplified 50 %",
    "unmarked, other mesh's key",
    "unmarked, other secret",
    "paper: re-ordered",
    "cho1: marked",
)
BLIND_CASES = (
    "marked",
    "re-ordered",
    "cut in half, posed",
    "cut 10 %",
    "simplified 50 %",
    "unmarked, the phrase",
    "marked, another phrase",
    "unmarked, cut in half",
    "cut flat, then marked",
    "Loop-subdivided",
    "Catmull-Clark-subdivided",
    "quantized to 8 bits",
)
BLIND_BASELINE = "8ddfaa7"  # the crop search screening every candidate 0.3 bin widths apart
BASELINES = {
    BASELINE: "brute-force nearest-point and radius queries, one start at a time",
    "c28a68c": "the crop search scoring every candidate centre over 23 widths x 5 phases",
    BLIND_BASELINE: "the crop search screening every candidate centre 0.3 bin widths apart",
    "70ca2f2": "the allocator left to its defaults; the crop search on the family's plane alone, "
    "its width fit on 20,000 vertices",
    "4a70b94": "the crop search's word lengths one after the other, in one thread",
    "ccfa066": "the screening's cell tables reaching as far again as the farthest vertex; Chase over "
    "the 10 least reliable bits and the Viterbi equalizer",
    "90f8c1e": "the crop search's lattice cells kept by np.unique over rows of three integers; the crop "
    "search on every suspect with a planar cut",
    "d959176": "no coarse mesh looked for under a subdivided suspect",
    "ad122bd": "no Catmull-Clark step undone",
    "c64bf81": "no suspect read after smoothing steps against noise",
    "fb3c27f": "np.unique (numpy 2 finds the values with a hash set) for the subdivision's and the "
    "crop search's keys; the equalizer's Viterbi costs computed a bin at a time; the "
    "check bits hashed one candidate at a time",
    "12131df": "every frame's upper end (the 98 % area quantile of the distances) from a sort of all "
    "the distances; np.linalg.norm for the rows' norms, axis-0 reductions for the "
    "bounding box, the bin statistics on compressed arrays",
}
TARGET = 0.5  # seconds: the verify speed target


def build_cases(path: Path) -> None:
    """Embed and attack every model once (this checkout's code) and pickle the suspects and keys."""
    import pmwm
    from pmwm import attacks

    meshes = {m: load(m) for m in MODELS}
    keys, cases = {}, {}
    for m, (V, F) in meshes.items():
        res = pmwm.embed(V, F, pmwm.EmbedOptions(payload="bench", seed=1))
        keys[m] = res.key
        MV, MF = res.vertices, res.faces
        other = pmwm.embed(V, F, pmwm.EmbedOptions(payload="bench", seed=2)).key
        paper = pmwm.embed(V, F, pmwm.EmbedOptions(payload="bench", seed=1, scheme="paper"))
        cho = pmwm.embed(V, F, pmwm.EmbedOptions(payload="bench", seed=1, scheme="cho1"))
        cases[m] = {
            "marked": (MV, MF, res.key),
            "re-ordered": (*attacks.reorder(MV, MF, seed=1), res.key),
            "cut in half, posed": (*attacks.similarity(*attacks.crop_plane(MV, MF, 0.5, seed=2), seed=2), res.key),
            "simplified 50 %": (*attacks.simplify(MV, MF, ratio=0.5), res.key),
            "unmarked, other secret": (V, F, other),
            "paper: re-ordered": (*attacks.reorder(paper.vertices, paper.faces, seed=1), paper.key),
            "cho1: marked": (cho.vertices, cho.faces, cho.key),
        }
    for m in MODELS:
        other_mesh = [o for o in MODELS if o != m][0]
        cases[m]["unmarked, other mesh's key"] = (*meshes[m], keys[other_mesh])
    rows = [(m, c, *cases[m][c][:2], cases[m][c][2].to_json()) for m in MODELS for c in CASES]
    with open(path, "wb") as f:
        pickle.dump(rows, f)


BENCH_PHRASE = "bench phrase"  # every blind case's pass phrase (the mark's and the reader's), but:
OTHER_PHRASES = {"marked, another phrase": "another phrase"}  # the reader's, in these cases


def phrase_of(case: str) -> str:
    """The pass phrase a blind case is read with (``build_blind_cases``)."""
    return OTHER_PHRASES.get(case, BENCH_PHRASE)


def flat_marked(V, F):
    """The mesh cut 10 % by a plane, then marked with the blind scheme ("Acme", BENCH_PHRASE)."""
    import pmwm
    from pmwm import attacks

    Vc, Fc = attacks.crop_plane(V, F, 0.1, seed=7)
    res = pmwm.embed(
        Vc, Fc, pmwm.EmbedOptions(scheme="blind", payload="Acme", passphrase=BENCH_PHRASE, progressive=False)
    )
    return res.vertices, res.faces


def build_blind_cases(path: Path) -> None:
    """The blind scheme's cases (module docstring), pickled like ``build_cases``'."""
    import pmwm
    from pmwm import attacks

    rows = []
    for m in MODELS:
        V, F = load(m)
        res = pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind", payload="Acme", passphrase=BENCH_PHRASE))
        MV, MF = res.vertices, res.faces
        half = attacks.crop_plane(MV, MF, 0.5, seed=2)
        cases = {
            "marked": (MV, MF),
            "re-ordered": attacks.reorder(MV, MF, seed=1),
            "cut in half, posed": attacks.similarity(*half, seed=2),
            "cut 10 %": attacks.crop_plane(MV, MF, 0.1, seed=3),
            "simplified 50 %": attacks.simplify(MV, MF, ratio=0.5),
            "unmarked, the phrase": (V, F),
            "marked, another phrase": (MV, MF),
            "unmarked, cut in half": attacks.crop_plane(V, F, 0.5, seed=2),
            # an asset with a planar cut of its own (a bust's base), marked and read intact
            "cut flat, then marked": flat_marked(V, F),
            # one step of Loop subdivision: read on the coarse mesh under it (since 7c3a7d4)
            "Loop-subdivided": attacks.subdivide(MV, MF, "loop"),
            # one step of Catmull-Clark, as Blender's Subdivision Surface leaves it (undone since d46800f)
            "Catmull-Clark-subdivided": attacks.subdivide(MV, MF, "catmull-clark"),
            # blurred radii: read as it is and after a few smoothing steps when its bins show it (since 6037447)
            "quantized to 8 bits": attacks.quantize(MV, MF, bits=8),
        }
        rows += [(m, c, *cases[c], "passphrase:" + phrase_of(c)) for c in BLIND_CASES]
    with open(path, "wb") as f:
        pickle.dump(rows, f)


def child(cases_path: str, out_path: str, repeat: int, only: Optional[int] = None) -> None:
    """Time every case (or the case of index ``only``) ``repeat`` times with the ``pmwm`` on sys.path;
    write JSON."""
    import numpy as np

    import pmwm

    with open(cases_path, "rb") as f:
        rows = pickle.load(f)
    if only is not None:
        rows = rows[only : only + 1]
    out = []
    for m, case, V, F, key_json in rows:  # a key file's text, or "passphrase:" and a pass phrase
        phrase = key_json[len("passphrase:") :] if key_json.startswith("passphrase:") else None
        key = None if phrase is not None else pmwm.WatermarkKey.from_json(key_json)
        times, cpu = [], []
        for _ in range(repeat):
            t, c = time.perf_counter(), time.process_time()
            v = pmwm.verify(V, F, key, passphrase=phrase)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        detail = getattr(v, "detail", None)  # (a baseline commit has a dict "extra" instead)
        extra = {**vars(detail)} if detail is not None else (v.extra if isinstance(v.extra, dict) else {})
        out.append(
            dict(
                model=m,
                case=case,
                times=times,
                cpu=cpu,
                marked=bool(v.marked),
                bit_errors=int(v.bit_errors),
                p_value=float(v.p_value),
                mode=v.mode,
                n_vertices=int(len(V)),
                registration=str(extra.get("registration", extra.get("frame", ""))),
                pmwm=str(Path(pmwm.__file__).parent),
                numpy=np.__version__,
            )
        )
    with open(out_path, "w") as f:
        json.dump(out, f)


def run_child(core: Path, cases_path: Path, out_path: Path, repeat: int, only: Optional[int] = None) -> list[dict]:
    env = dict(os.environ, PYTHONPATH=str(core), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    subprocess.run(
        [
            sys.executable,
            __file__,
            "--child",
            str(cases_path),
            str(out_path),
            str(repeat),
            *([] if only is None else [str(only)]),
        ],
        check=True,
        env=env,
        cwd=str(ROOT),
    )
    with open(out_path) as f:
        return json.load(f)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="calls per case per round (default 3)")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds new/old (default 2)")
    ap.add_argument(
        "--scheme",
        choices=("robust", "blind"),
        default="robust",
        help="the cases of the robust scheme (and paper, cho1), or of the blind scheme",
    )
    ap.add_argument(
        "--baseline",
        default=None,
        help=f"commit to compare with (default {BASELINE}, with --scheme blind {BLIND_BASELINE}); '' for none",
    )
    ap.add_argument(
        "--fresh", action="store_true", help="time each case's first call in a process of its own (section ...-fresh)"
    )
    ap.add_argument(
        "--cli",
        action="store_true",
        help="time `pmwm verify` as whole processes beside reading the files alone (section ...-cli)",
    )
    ap.add_argument(
        "--threads-as-set",
        action="store_true",
        help="with --cli: leave OMP_NUM_THREADS and OPENBLAS_NUM_THREADS as set here (a user's "
        "default: unset) instead of 1 (section ...-cli-threads)",
    )
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child(a.child[0], a.child[1], int(a.child[2]), int(a.child[3]) if len(a.child) > 3 else None)
        return
    if a.cli:
        cli(a)
        return
    if a.fresh:
        a.repeat = 1
    if a.baseline is None:
        a.baseline = BLIND_BASELINE if a.scheme == "blind" else BASELINE
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (build_blind_cases if a.scheme == "blind" else build_cases)(tmp / "cases.pkl")
        cores = {"new": ROOT / "core"}
        if a.baseline:
            archive = subprocess.run(
                ["git", "-C", str(ROOT), "archive", a.baseline, "core"], check=True, capture_output=True
            ).stdout
            subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
            (tmp / "old").mkdir()
            (tmp / "core").rename(tmp / "old" / "core")
            cores["old"] = tmp / "old" / "core"
        for core in cores.values():
            byte_compiled(core / "pmwm")
        runs: dict[str, list[list[dict]]] = {k: [] for k in cores}
        with open(tmp / "cases.pkl", "rb") as f:
            n_cases = len(pickle.load(f))
        for r in range(a.rounds):
            if a.fresh:  # every case in a process of its own, alternating with the baseline case by case
                for label in cores:
                    runs[label].append([])
                for i in range(n_cases):
                    for label, core in cores.items():
                        runs[label][-1] += run_child(core, tmp / "cases.pkl", tmp / f"{label}{r}.json", 1, i)
            else:
                for label, core in cores.items():
                    runs[label].append(run_child(core, tmp / "cases.pkl", tmp / f"{label}{r}.json", a.repeat))
            print(f"round {r + 1} done", flush=True)
    report(runs, a)


READ_ONLY = """
import sys
from pmwm.cli import main  # the imports of `python -m pmwm`
from pmwm.api import read_key
from pmwm.meshio import read_mesh
suspect, key = sys.argv[1:3]
if key.endswith(".json"):
    read_key(key)
else:
    open(key, encoding="utf-8").read()
read_mesh(suspect)
"""


def cli(a) -> None:
    """``--cli``: every case's `pmwm verify` whole process beside reading its two files (module docstring)."""
    from pmwm.key import WatermarkKey, write_key
    from pmwm.meshio import write_mesh

    blind = a.scheme == "blind"
    byte_compiled(ROOT / "core" / "pmwm")
    env = dict(os.environ, PYTHONPATH=str(ROOT / "core"))
    if a.threads_as_set:
        threads = ", ".join(f"{v} {os.environ.get(v, 'unset')}" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"))
    else:
        env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
        threads = "OMP_NUM_THREADS=1"
    lines = []
    over_wall, over_cpu = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (build_blind_cases if blind else build_cases)(tmp / "cases.pkl")
        with open(tmp / "cases.pkl", "rb") as f:
            rows = pickle.load(f)
        for i, (m, case, V, F, key_json) in enumerate(rows):
            suspect = tmp / f"suspect{i}.ply"
            write_mesh(suspect, V, F)
            if blind:
                key = tmp / f"phrase{i}.txt"
                key.write_text(phrase_of(case), encoding="utf-8")
                verify_cmd = [sys.executable, "-m", "pmwm", "verify", str(suspect), "--passphrase-file", str(key)]
            else:
                key = tmp / f"key{i}.json"
                write_key(key, WatermarkKey.from_json(key_json))
                verify_cmd = [sys.executable, "-m", "pmwm", "verify", str(suspect), "--key", str(key)]
            verdict = subprocess.run(verify_cmd + ["--json"], env=env, capture_output=True, text=True)
            if verdict.returncode not in (0, 1):  # 0 marked, 1 not marked; anything else is an error
                raise SystemExit(f"{m} / {case}: pmwm verify failed: {verdict.stderr.strip()}")
            marked = json.loads(verdict.stdout)["marked"]
            (tv, cv), (tr, cr) = best_alternating(
                [verify_cmd, [sys.executable, "-c", READ_ONLY, str(suspect), str(key)]], a.repeat, env, (0, 1)
            )
            lines.append(
                f"| {m} | {case} | {len(V):,} | {'marked' if marked else 'not marked'} | "
                f"{tv:.2f} / {cv:.2f} s | {tr:.2f} / {cr:.2f} s | {tv - tr:.2f} / {cv - cr:.2f} s |"
            )
            print(lines[-1], flush=True)
            if tv - tr >= TARGET:
                over_wall.append(f"{m} / {case} ({tv - tr:.2f} s)")
            if cv - cr >= TARGET:
                over_cpu.append(f"{m} / {case} ({cv - cr:.2f} s)")
    body = "\n".join(
        [
            ("## Verify speed: the blind scheme" if blind else "## Verify speed")
            + ", `pmwm verify` as the user runs it"
            + (" (the thread variables as set)" if a.threads_as_set else ""),
            "",
            f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.",
            "Each case's suspect written to a PLY file (float32 coordinates), "
            + ("its pass phrase to a file; " if blind else "its key to a JSON file; ")
            + "`python -m pmwm verify` as a whole process (Python start-up, imports, reading the files, the "
            f"verdict printed) and a process that only reads the two files as it does (the same imports), alternating, "
            f"best of {a.repeat} each; {threads}. Wall-clock and CPU time (user + system) of each process; "
            "their difference is what `pmwm verify` takes beyond reading the two files"
            + (
                " (deriving the secret from the pass phrase, scrypt, included: it runs in a thread beside the reading)"
                if blind
                else ""
            )
            + ".",
            "",
            "| mesh | case | suspect vertices | verdict | `pmwm verify`: wall / CPU | reading the files: wall / CPU | "
            "beyond reading: wall / CPU |",
            "|---|---|---|---|---|---|---|",
            *lines,
            "",
            f"Target: every case under {TARGET} s beyond reading the two files: in CPU time "
            + ("met" if not over_cpu else "not met for " + "; ".join(over_cpu))
            + "; in wall-clock time "
            + ("met." if not over_wall else "not met for " + "; ".join(over_wall) + "."),
        ]
    )
    write_section(
        ("verify-speed-blind" if blind else "verify-speed") + "-cli" + ("-threads" if a.threads_as_set else ""), body
    )


def report(runs: dict[str, list[list[dict]]], a) -> None:
    def merged(label):
        rows = {}
        for run in runs[label]:
            for x in run:
                row = rows.setdefault((x["model"], x["case"]), dict(x, times=[], cpu=[]))
                row["times"] += x["times"]
                row["cpu"] += x["cpu"]
        return rows

    new = merged("new")
    old = merged("old") if "old" in runs else {}
    n_calls = a.repeat * a.rounds
    blind = a.scheme == "blind"
    lines = [
        ("## Verify speed: the blind scheme" if blind else "## Verify speed: spatial search by KD-tree")
        + (", the first call in a fresh process" if a.fresh else ""),
        "",
        f"Command: `{command()}` at commit {commit()}. Machine: {machine()}.",
        (
            f"`pmwm.verify` alone (the meshes and keys already in memory), each case's first call in a process "
            f"of its own (as `pmwm verify` reads one suspect), median of {a.rounds} processes that alternate "
            "with the baseline's"
            if a.fresh
            else f"`pmwm.verify` alone (the meshes and keys already in memory), median of {n_calls} calls in "
            f"{a.rounds} rounds that alternate with the baseline"
        )
        + (
            (
                f" (commit {a.baseline}: {BASELINES[a.baseline]})"
                if a.baseline in BASELINES
                else f" (commit {a.baseline})"
            )
            if old
            else ""
        )
        + "; OMP_NUM_THREADS=1. Wall-clock time and CPU time of the "
        "process: the machine is shared (2 cores, other jobs running), so the wall-clock figures include "
        "waiting for a core. The blind reader searches a cropped copy's word lengths in parallel threads "
        "(`pmwm.background.parallel_map`): there its CPU time is the sum over both cores, and the "
        "wall-clock time is what the user waits.",
        "",
        "| mesh | case | suspect vertices | verdict | bit errors | read | "
        + ("baseline wall / CPU | " if old else "")
        + "now wall / CPU | "
        + ("speed-up wall / CPU |" if old else ""),
        "|---|---|---|---|---|---|---|" + ("---|---|" if old else ""),
    ]
    changed = []
    for (m, case), x in new.items():
        t, c = statistics.median(x["times"]), statistics.median(x["cpu"])
        how = x["mode"] + (f", {x['registration']}" if x["registration"] else "")
        row = (
            f"| {m} | {case} | {x['n_vertices']:,} | {'marked' if x['marked'] else 'not marked'} | "
            f"{x['bit_errors']} | {how} | "
        )
        if old:
            o = old[(m, case)]
            to, co = statistics.median(o["times"]), statistics.median(o["cpu"])
            row += f"{to:.3f} / {co:.3f} s | {t:.3f} / {c:.3f} s | {to / t:.1f}x / {co / c:.1f}x |"
            if (o["marked"], o["bit_errors"], o["mode"]) != (x["marked"], x["bit_errors"], x["mode"]):
                changed.append(f"{m} / {case}: baseline {o['marked']}, {o['bit_errors']} errors, {o['mode']}")
        else:
            row += f"{t:.3f} / {c:.3f} s |"
        lines.append(row)
    robust = [x for (m, c), x in new.items() if blind or not c.startswith(("paper", "cho"))]

    def over(key):
        return [
            f"{x['model']} / {x['case']} ({statistics.median(x[key]):.2f} s)"
            for x in robust
            if statistics.median(x[key]) >= TARGET
        ]

    lines += [
        "",
        f"Target: every {'blind' if blind else 'robust'} case under {TARGET} s: in CPU time "
        + ("met" if not over("cpu") else "not met for " + "; ".join(over("cpu")))
        + "; in wall-clock time on the loaded machine "
        + ("met." if not over("times") else "not met for " + "; ".join(over("times")) + "."),
        "Verdicts and bit errors "
        + (
            "identical to the baseline's in every case."
            if old and not changed
            else ("changed: " + "; ".join(changed) + ".")
            if changed
            else "(no baseline run)."
        ),
    ]
    write_section(("verify-speed-blind" if blind else "verify-speed") + ("-fresh" if a.fresh else ""), "\n".join(lines))


if __name__ == "__main__":
    main()
