"""The ``pmwm`` command line: embed, verify, decode, info, attack, demo, bench; fingerprint, trace,
catalogue.

Exit codes follow grep: 0 success (verify: marked; with several keys: marked by at least one), 1 verify:
not marked (by any key), 2 error.
Errors are one line on stderr, never a traceback; nothing existing is overwritten
without ``--force`` and an input is never overwritten at all.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import sys
import time
from importlib import resources
from typing import Optional, Sequence

import numpy as np

from . import __version__, wording
from .api import embed, read_key, verify, verify_keys
from .atomic import atomic_write_bytes
from .base import PASS_PHRASE, EmbedOptions, Verdict
from .errors import OutputExistsError, PmwmError
from .key import write_key
from .meshio import SUPPORTED_EXTENSIONS, read_mesh, write_marked, write_mesh
from .progressive import read_pm, record_size, write_pm
from .scene import (
    SceneDetail,
    embed_objects,
    read_asset,
    read_keys,
    read_objects,
    verify_objects,
    write_asset,
    write_keys,
)
from .schemes import SCHEMES, keyed_by

EXIT_OK, EXIT_NOT_MARKED, EXIT_ERROR = 0, 1, 2


class UsageError(PmwmError):
    """Bad command-line arguments."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, like every other error
        raise UsageError(f"{message} (see 'pmwm {self.prog.split()[-1]} --help')" if " " in self.prog else message)


def _progress(quiet: bool):
    if quiet or not sys.stderr.isatty():
        return None
    last = [-1]

    def show(fraction: float, message: str) -> None:
        pct = int(fraction * 100)
        if pct != last[0]:
            last[0] = pct
            print(f"\r{pct:3d}% {message[:60]:<60}", end="", file=sys.stderr, flush=True)
            if fraction >= 1:
                print(file=sys.stderr)

    return show


def _check_outputs(outputs: Sequence[Optional[str]], inputs: Sequence[str], force: bool) -> None:
    """Refuse before any work: an output that is an input, exists, or has no folder."""
    real_inputs = {os.path.realpath(p) for p in inputs}
    seen = set()
    for out in outputs:
        if out is None:
            continue
        real = os.path.realpath(out)
        if real in real_inputs:
            raise UsageError(f"{out} is also an input; pmwm never overwrites its input, choose another name")
        if real in seen:
            raise UsageError(f"{out} is named twice as an output")
        seen.add(real)
        folder = os.path.dirname(os.path.abspath(out))
        if not os.path.isdir(folder):
            raise UsageError(f"the folder of {out} does not exist; create it first")
        if os.path.isdir(out):
            raise UsageError(f"{out} is a directory; give a file name")
        if os.path.exists(out) and not force:
            raise OutputExistsError(f"{out} exists; pass --force to overwrite it")


def _mesh_ext(path: str, what: str) -> None:
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise UsageError(f"{what} {path} has an unsupported extension; use one of {', '.join(SUPPORTED_EXTENSIONS)}")


# --------------------------------------------------------------------------- commands


PASSPHRASE_ENV = "PMWM_PASSPHRASE"


def _passphrase(path: Optional[str]) -> Optional[str]:
    """The pass phrase of a scheme keyed by one (blind): the first line of ``path`` (its line ending
    dropped), else $PMWM_PASSPHRASE, else None. Never printed."""
    if path is None:
        return os.environ.get(PASSPHRASE_ENV) or None
    try:
        with open(path, "rb") as fh:
            raw = fh.read(65537)
    except OSError as exc:
        raise UsageError(f"cannot read the pass-phrase file {path}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8").splitlines()[0] if raw.strip() else ""
    except UnicodeDecodeError:
        raise UsageError(f"the pass-phrase file {path} is not UTF-8 text") from None
    if not text or len(raw) > 65536:
        raise UsageError(f"the pass-phrase file {path} is empty or too long (its first line is the pass phrase)")
    return text


def _schemes_keyed_by(keying: str) -> str:
    """The --scheme options of the schemes keyed by ``keying``, for messages: "--scheme blind"."""
    return " or ".join(f"--scheme {name}" for name in keyed_by(keying))


def cmd_embed(a) -> int:
    _mesh_ext(a.output, "output")
    by_phrase = SCHEMES[a.scheme].keying == PASS_PHRASE
    passphrase = _passphrase(a.passphrase_file) if by_phrase else None
    if by_phrase and a.key is not None:
        raise UsageError(f"the {a.scheme} scheme writes no key file (the pass phrase is the key); omit --key")
    if by_phrase and passphrase is None:
        raise UsageError(f"the {a.scheme} scheme needs a pass phrase: --passphrase-file F or ${PASSPHRASE_ENV}")
    if not by_phrase and a.key is None:
        raise UsageError(
            f"the key file to write is missing: --key KEY.json (only {_schemes_keyed_by(PASS_PHRASE)} needs none)"
        )
    if not by_phrase and a.passphrase_file is not None:
        raise UsageError(
            f"--passphrase-file is for {_schemes_keyed_by(PASS_PHRASE)}; the other schemes write a key file"
        )
    _check_outputs([a.output, a.key, a.pm], [a.input], a.force)
    asset = _scene(a.input, a.output)  # a scene is marked object by object and written back in place
    if asset is not None and a.pm and len(asset.objects) > 1:
        raise UsageError(
            f"--pm writes the progressive mesh of one mesh; {a.input} holds {len(asset.objects)} objects: omit --pm"
        )
    src = read_mesh(a.input) if asset is None else None
    objects = (
        [(a.input, src.vertices, src.faces)]
        if asset is None
        else [(o.name, o.vertices, o.faces) for o in asset.objects]
    )
    # the progressive mesh only when it is written (--pm): without it the embed skips most of its work
    opts = EmbedOptions(
        payload=a.payload,
        bits=a.bits,
        n_bits=a.n_bits,
        strength=a.strength,
        base_ratio=a.base_ratio,
        seed=a.seed,
        scheme=a.scheme,
        passphrase=passphrase,
        progressive=a.pm is not None,
    )
    marking = embed_objects(objects, opts, progress=_progress(a.quiet))
    res = marking.results[0]
    written: list[str] = []
    try:
        if marking.key is not None:
            write_keys(a.key, marking.key, overwrite=a.force)
            written.append(a.key)
        if a.pm:
            write_pm(a.pm, res.pm, force=a.force)
            written.append(a.pm)
        if asset is None:
            write_marked(a.output, src, res.vertices, force=a.force)
        else:
            write_asset(a.output, asset, marking.marked, force=a.force)
        written.append(a.output)
    except BaseException:
        for path in written:  # all or nothing: no key without its mesh
            try:
                os.remove(path)
            except OSError:
                pass
        raise
    if len(res.bits) < 20:
        print(
            f"warning: {len(res.bits)} bits can never give p < 1e-6 (2^-{len(res.bits)} at best); "
            "use at least 20 bits for a 'marked' verdict",
            file=sys.stderr,
        )
    if not a.quiet:
        for w in (src or asset).warnings:
            print(f"warning: {w}", file=sys.stderr)
        for name, r in zip(marking.names, marking.results):
            for note in r.notes:
                print(f"note: {name + ': ' if len(marking.results) > 1 else ''}{note}", file=sys.stderr)
        if asset is not None and len(objects) > 1:
            print(
                f"marked {len(res.bits)} bits in each of the {len(objects)} objects of {a.input} ("
                + ", ".join(f"{n}: VSNR {r.vsnr_db:.1f} dB" for n, r in zip(marking.names, marking.results))
                + f") -> {a.output}"
            )
        else:
            where = f"on {len(res.carriers)} carriers of" if len(res.carriers) else "in"  # (blind: no carriers)
            print(f"marked {len(res.bits)} bits {where} {a.input} (VSNR {res.vsnr_db:.1f} dB) -> {a.output}")
        if res.key is None:
            print(f"payload bits: {''.join(map(str, res.bits.tolist()))} (no key file: the pass phrase reads it)")
        else:
            print(f"key -> {a.key} (keep it secret: it reveals where the mark is)")
        if a.pm:
            print(
                f"progressive mesh -> {a.pm} ({res.pm.n_base_vertices} base vertices, "
                f"{res.pm.n_records} records, {len(res.pm.level_records)} levels)"
            )
    return EXIT_OK


def _scene(path: str, output: str):
    """The scene read from ``path`` (``pmwm.scene.read_asset``), None for a file of one mesh or for one
    object written to another format (then read as one mesh); a scene of several objects is written
    back in its own format only."""
    asset = read_asset(path)
    same = os.path.splitext(path)[1].lower() == os.path.splitext(output)[1].lower()
    if asset is None or (not same and len(asset.objects) == 1):
        return None
    if not same:
        raise UsageError(
            f"{path} holds {len(asset.objects)} objects, written back in its own format only: "
            f"use -o NAME{os.path.splitext(path)[1]}"
        )
    return asset


def _print_verdict(v: Verdict, as_json: bool) -> None:
    if as_json:
        doc = v.to_dict()
        if isinstance(v.detail, SceneDetail):  # a verdict over objects: which were read
            doc["objects"] = v.detail.to_dict()
        print(json.dumps(doc))
        return
    for line in wording.lines(v):
        print(line)


def cmd_verify(a) -> int:
    key_paths = a.key or []
    if a.report is not None:
        if not a.report.lower().endswith((".html", ".htm")):
            raise UsageError(f"--report {a.report}: give an .html file name")
        _check_outputs([a.report], [a.suspect, *key_paths], a.force)
    passphrase = _passphrase(a.passphrase_file) if not key_paths else None
    phrase_schemes = " or ".join(keyed_by(PASS_PHRASE))
    if key_paths and a.passphrase_file is not None:
        raise UsageError("give --key or --passphrase-file, not both")
    if not key_paths and passphrase is None:
        raise UsageError(
            f"give --key KEY.json, or a pass phrase for a {phrase_schemes} mark "
            f"(--passphrase-file F or ${PASSPHRASE_ENV})"
        )
    if passphrase is not None and a.report is not None:
        raise UsageError(f"--report needs a key file; a {phrase_schemes} mark has none")
    _distinct_keys(key_paths)
    key_files = [read_keys(path) for path in key_paths]  # a scene's key: one per object
    if a.suspect.lower().endswith(".pmwm"):
        pm = read_pm(a.suspect)
        records = pm.records_for_vertices(a.vertices) if a.vertices is not None else a.level
        objects = [(a.suspect, *pm.decode(records=records))]
    else:
        if a.level is not None or a.vertices is not None:
            raise UsageError("--level/--vertices apply to a .pmwm progressive mesh only")
        objects = read_objects(a.suspect)
    if len(key_paths) > 1:
        return _verify_keys(a, key_paths, key_files, objects)
    keys = key_files[0] if key_files else None
    if a.report is not None and (len(objects) > 1 or len(keys) > 1):
        raise UsageError("--report reads one mesh with the key of one mesh; verify the scene without it")
    v = verify_objects(objects, keys, p_threshold=a.p_threshold, passphrase=passphrase)
    if a.report is not None:
        key, (_, V, F) = keys[0][1], objects[0]
        from .verify_report import write_report

        write_report(a.report, v, key, V, F, suspect_path=a.suspect, key_path=a.key[0], force=a.force)
    _print_verdict(v, a.json)
    if a.report is not None and not a.json:
        print(f"report -> {a.report}")
    return EXIT_OK if v.marked else EXIT_NOT_MARKED


def _distinct_keys(paths: Sequence[str]) -> None:
    """Refuse a key file named twice (it would be counted twice in the correction for the keys tried)."""
    seen = set()
    for path in paths:
        real = os.path.realpath(path)
        if real in seen:
            raise UsageError(f"the key file {path} is given twice; give each --key once")
        seen.add(real)


def _verify_keys(a, key_paths: list[str], key_files: list, objects: list) -> int:
    """``pmwm verify SUSPECT --key A --key B ...``: the suspect, one mesh read once, with each key
    (``pmwm.verify_keys``): each key's verdict, the correction for the keys tried, and whose marks the
    copy carries. Exit 0 when at least one key reads marked, else 1."""
    scenes = [path for path, keys in zip(key_paths, key_files) if len(keys) > 1]
    if scenes or len(objects) > 1:
        what = f"{scenes[0]} is the key of a scene" if scenes else f"{a.suspect} holds {len(objects)} objects"
        raise UsageError(f"several --key read one mesh; {what}: verify a scene with one key at a time")
    keys = [keys[0][1] for keys in key_files]
    _, V, F = objects[0]
    kv = verify_keys(V, F, keys, p_threshold=a.p_threshold)
    if a.report is not None:
        from .verify_report import write_keys_report

        base = [os.path.basename(p) for p in key_paths]
        names = base if len(set(base)) == len(base) else key_paths
        write_keys_report(a.report, kv, keys, names, V, F, suspect_path=a.suspect, key_paths=key_paths, force=a.force)
    if a.json:
        print(json.dumps(kv.to_dict(key_paths)))
    else:
        for line in wording.keys_lines(kv, key_paths):
            print(line)
        if a.report is not None:
            print(f"report -> {a.report}")
    return EXIT_OK if kv.marked_keys else EXIT_NOT_MARKED


def cmd_decode(a) -> int:
    _mesh_ext(a.output, "output")
    _check_outputs([a.output], [a.input], a.force)
    pm = read_pm(a.input)
    if a.level is not None and a.level < 0:
        raise UsageError("--level must be 0 or more")
    V, F = pm.decode(records=a.level, vertices=a.vertices)
    write_mesh(a.output, V, F, force=a.force)
    if not a.quiet:
        print(f"{a.output}: {len(V)} vertices, {len(F)} faces")
    return EXIT_OK


def cmd_info(a) -> int:
    pm = read_pm(a.input)
    size = os.path.getsize(a.input)
    info = {
        "file": a.input,
        "bytes": size,
        "base_vertices": pm.n_base_vertices,
        "base_faces": len(pm.base_faces),
        "records": pm.n_records,
        "levels": len(pm.level_records),
        "full_vertices": pm.n_vertices,
        "full_faces": pm.n_faces,
        "position_precision": "float32" if pm.float32 else "float64",
        "bytes_per_record": record_size(not pm.float32),
        "level_vertices": (pm.n_base_vertices + pm.level_records).tolist(),
    }
    if a.json:
        print(json.dumps(info))
    else:
        for k, v in info.items():
            print(f"{k}: {v}")
    return EXIT_OK


def cmd_viewer(a) -> int:
    from .viewer import write_site

    out = write_site(
        read_pm(a.input), a.output, title=a.title or os.path.splitext(os.path.basename(a.input))[0], force=a.force
    )
    if not a.quiet:
        print(
            f"{out}: a web page streaming {os.path.basename(a.input)}; try it: python -m http.server -d {out}, "
            "then open http://localhost:8000"
        )
    return EXIT_OK


def cmd_attack(a) -> int:
    from .attacks import ATTACKS

    _mesh_ext(a.output, "output")
    _check_outputs([a.output], [a.input], a.force)
    fn = ATTACKS[a.kind]
    params = {name: getattr(a, name) for name in _attack_params(fn) if getattr(a, name) is not None}
    src = read_mesh(a.input)
    V, F = fn(src.vertices, src.faces, **params)
    write_mesh(a.output, V, F, force=a.force)
    if not a.quiet:
        print(f"{a.kind} -> {a.output}: {len(V)} vertices, {len(F)} faces")
    return EXIT_OK


def cmd_demo(a) -> int:
    out = a.dir
    if os.path.exists(out) and not os.path.isdir(out):
        raise UsageError(f"{out} exists and is not a folder")
    os.makedirs(out, exist_ok=True)
    names = {
        k: os.path.join(out, v)
        for k, v in dict(mesh="bunny_marked.ply", pm="bunny.pmwm", key="bunny.key.json", report="verify.json").items()
    }
    _check_outputs(list(names.values()), [], a.force)
    sample = resources.files("pmwm") / "data" / "bunny.off"
    with resources.as_file(sample) as path:
        t0 = time.perf_counter()
        src = read_mesh(str(path))
        res = embed(src.vertices, src.faces, EmbedOptions(payload=a.payload, seed=a.seed), progress=_progress(False))
        t_embed = time.perf_counter() - t0
    write_key(names["key"], res.key, overwrite=a.force)
    write_pm(names["pm"], res.pm, force=a.force)
    write_marked(names["mesh"], src, res.vertices, force=a.force)
    check = read_mesh(names["mesh"])
    v = verify(check.vertices, check.faces, read_key(names["key"]))
    atomic_write_bytes(names["report"], (json.dumps(v.to_dict(), indent=1) + "\n").encode(), force=a.force)
    print(f"sample: the Stanford Bunny ({len(src.vertices)} vertices; Stanford Computer Graphics Laboratory)")
    print(
        f"embedded {len(res.bits)} bits in {t_embed:.2f} s, VSNR {res.vsnr_db:.1f} dB; wrote {out}/: "
        + ", ".join(os.path.basename(p) for p in names.values())
    )
    _print_verdict(v, False)
    return EXIT_OK if v.marked else EXIT_NOT_MARKED


def cmd_bench(argv: Sequence[str]) -> int:
    """``pmwm bench``: the evaluation (package ``pmwm_bench``), found as the ``bench`` entry point of
    the ``pmwm.commands`` group; the library never imports it."""
    from importlib.metadata import entry_points

    found = list(entry_points(group="pmwm.commands", name="bench"))
    if not found:
        raise UsageError("pmwm bench needs the evaluation part, installed from a checkout with pip install '.[bench]'")
    try:
        command = found[0].load()
    except ImportError as exc:
        raise UsageError(f"pmwm bench cannot start ({exc}); install the bench extra: pip install '.[bench]'") from None
    return command(list(argv))


# --------------------------------------------------------------------------- fingerprinting


def _count_progress(quiet: bool, what: str):
    """A progress(done, total) callback drawing a bar on a terminal (None otherwise)."""
    if quiet or not sys.stderr.isatty():
        return None

    def show(done: int, total: int) -> None:
        n = 30 * done // max(total, 1)
        print(f"\r[{'#' * n}{'.' * (30 - n)}] {done}/{total} {what}", end="", file=sys.stderr, flush=True)
        if done >= total:
            print(file=sys.stderr)

    return show


def _fingerprint_options(a):
    from .fingerprint import FingerprintOptions

    return FingerprintOptions(strength=a.strength, n_sites=a.sites, base_ratio=a.base_ratio, seed=a.seed)


def cmd_fingerprint(a) -> int:
    from .fingerprint import fingerprint_asset, read_recipients
    from .fingerprint.scene import fingerprint_scene, prepare_scene

    _check_outputs([a.key if not os.path.exists(a.key) else None], [a.asset], False)
    if os.path.exists(a.out) and not os.path.isdir(a.out):
        raise UsageError(f"--out {a.out} exists and is not a folder")
    recipients = read_recipients(a.recipients)
    new_key = not os.path.exists(a.key)
    if not new_key and a.seed is not None:
        print(f"warning: {a.key} exists: its secret and options are used, --seed is ignored", file=sys.stderr)
    asset = read_asset(a.asset)  # a scene of several objects: every object marked, copies in the scene's format
    if asset is not None and len(asset.objects) > 1:
        if a.pm:
            raise UsageError(f"--pm writes progressive meshes of one mesh; {a.asset} is a scene: omit --pm")
        t0 = time.perf_counter()
        scene = prepare_scene(a.asset, a.key, _fingerprint_options(a), asset=asset)
        run = fingerprint_scene(scene, recipients, a.out, progress=_count_progress(a.quiet, "copies"))
        run.analysis_seconds = time.perf_counter() - t0 - run.copies_seconds
    else:
        run = fingerprint_asset(
            a.asset,
            a.key,
            recipients,
            a.out,
            pm=a.pm,
            options=_fingerprint_options(a),
            progress=_count_progress(a.quiet, "copies"),
        )
    if not a.quiet:
        per = run.copies_seconds / max(len(run.written), 1)
        print(
            f"fingerprinted {a.asset} for {len(recipients)} recipients: {len(run.written)} copies written "
            f"({per * 1000:.0f} ms each after a {run.analysis_seconds:.2f} s analysis), {len(run.skipped)} "
            f"already delivered intact -> {a.out}"
        )
        print(f"registry -> {run.registry_path}")
        print(f"key -> {a.key} ({'new' if new_key else 'reused'}; keep it secret, with the registry)")
    return EXIT_OK


def cmd_trace(a) -> int:
    from .fingerprint import read_registry, trace
    from .fingerprint.scene import SceneFingerprintKey, read_any_fingerprint_key, read_scene_registry, trace_objects

    fk = read_any_fingerprint_key(a.key)
    scene = isinstance(fk, SceneFingerprintKey)  # a scene's key: its objects traced, the union bound paid
    reg = read_scene_registry(a.registry) if scene else read_registry(a.registry)
    reg.check(fk, a.registry)
    if a.suspect.lower().endswith(".pmwm"):
        objects = [(a.suspect, *read_pm(a.suspect).decode())]
    elif scene:
        objects = read_objects(a.suspect)
    else:
        src = read_mesh(a.suspect)
        objects = [(a.suspect, src.vertices, src.faces)]
    if scene:
        r = trace_objects(objects, fk, reg, p_threshold=a.p_threshold)
    else:
        r = trace(objects[0][1], objects[0][2], fk, reg, p_threshold=a.p_threshold)
    if a.json:
        print(json.dumps(r.to_dict()))
    elif r.accused:
        for acc in r.accused:
            print(
                f"TRACED to {acc.recipient}: score {acc.score:.1f}, p = {acc.p_value:.3g} corrected for "
                f"{r.n_recipients} recipients (threshold {r.p_threshold:g})"
            )
        print(f"{r.sites_read}/{r.sites_total} sites read ({r.mode})")
    else:
        best = int(np.argmax(r.scores)) if r.n_recipients else -1
        tail = f"; best {r.recipients[best]}, p = {r.p_values[best]:.3g}" if best >= 0 else ""
        print(
            f"no recipient: none of {r.n_recipients} recipients is significant at p < {r.p_threshold:g}{tail} "
            f"({r.sites_read}/{r.sites_total} sites read, {r.mode})"
        )
    return EXIT_OK if r.accused else EXIT_NOT_MARKED


def cmd_catalogue(a) -> int:
    from .fingerprint import read_recipients

    try:
        from .fingerprint.catalogue import run_catalogue
    except ImportError as exc:
        raise UsageError(f"pmwm catalogue needs dask.distributed ({exc}); pip install 'pmwm[catalogue]'") from None
    if os.path.exists(a.out) and not os.path.isdir(a.out):
        raise UsageError(f"--out {a.out} exists and is not a folder")
    recipients = read_recipients(a.recipients)
    res = run_catalogue(
        a.assets,
        recipients,
        a.out,
        pm=a.pm,
        options=_fingerprint_options(a),
        n_workers=a.workers,
        scheduler=a.scheduler,
        progress=_count_progress(a.quiet, "copies"),
    )
    if not a.quiet:
        print(
            f"catalogue: {len(a.assets)} assets x {len(recipients)} recipients: {res.written} copies written, "
            f"{res.skipped} already delivered intact, in {res.seconds:.1f} s -> {a.out}"
        )
    for name, err in res.failed.items():
        print(f"pmwm: error: {name}: {err}", file=sys.stderr)
    return EXIT_ERROR if res.failed else EXIT_OK


def _add_fingerprint_commands(sub) -> None:
    def options(c) -> None:
        c.add_argument("--pm", action="store_true", help="also write each copy's progressive mesh (.pmwm)")
        c.add_argument("--seed", type=int, help="seed of a new key's secret (default: fresh)")
        c.add_argument("--strength", type=float, default=2.0, help="a new key's: as embed's (default 2)")
        c.add_argument("--sites", type=int, default=384, help="a new key's: sites carrying the codeword (default 384)")
        c.add_argument(
            "--base-ratio", type=float, default=0.03, help="a new key's: base mesh vertices / input vertices"
        )
        c.add_argument("-q", "--quiet", action="store_true")

    f = sub.add_parser("fingerprint", help="one marked copy per recipient, and a registry to trace leaks")
    f.add_argument("asset")
    f.add_argument(
        "--key",
        required=True,
        help="the asset's fingerprinting key (written by the first run, "
        "reused and checked on later runs; keep it secret)",
    )
    f.add_argument("--recipients", required=True, help="CSV of recipient ids (column 'id', or the first)")
    f.add_argument(
        "--out",
        required=True,
        help="folder of the copies and registry.json (a rerun skips copies already written intact)",
    )
    options(f)
    f.set_defaults(func=cmd_fingerprint)

    t = sub.add_parser("trace", help="name the recipient(s) whose copy a suspect mesh is")
    t.add_argument("suspect")
    t.add_argument("--key", required=True, help="the asset's fingerprinting key")
    t.add_argument("--registry", required=True, help="the registry.json written with the copies")
    t.add_argument("--p-threshold", type=float, default=1e-6, help="corrected p-value to name a recipient")
    t.add_argument("--json", action="store_true", help="one JSON object on stdout")
    t.set_defaults(func=cmd_trace)

    c = sub.add_parser("catalogue", help="fingerprint many assets for many recipients on Dask")
    c.add_argument("assets", nargs="+", help="mesh files (each: OUT/<name>/ copies and registry, OUT/<name>.key.json)")
    c.add_argument("--recipients", required=True, help="CSV of recipient ids (column 'id', or the first)")
    c.add_argument("--out", required=True)
    c.add_argument("--workers", type=int, default=None, help="LocalCluster workers (default: the cores)")
    c.add_argument("--scheduler", help="address of an existing Dask scheduler (default: a LocalCluster)")
    options(c)
    c.set_defaults(func=cmd_catalogue)


# --------------------------------------------------------------------------- parser


def _attack_params(fn) -> list[str]:
    skip = {"vertices", "faces", "v", "f"}
    return [p for p in inspect.signature(fn).parameters if p not in skip]


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="pmwm", description="Blind, robust 3D mesh watermarking carried by a progressive mesh.")
    p.add_argument("--version", action="version", version=f"pmwm {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    e = sub.add_parser("embed", help="watermark a mesh")
    e.add_argument("input")
    e.add_argument("-o", "--output", required=True, help="marked mesh (OBJ, PLY, STL, OFF, GLB)")
    e.add_argument("--key", help=f"key file to write (JSON; keep it secret); not with {_schemes_keyed_by(PASS_PHRASE)}")
    e.add_argument(
        "--passphrase-file",
        metavar="F",
        help=f"{_schemes_keyed_by(PASS_PHRASE)}: the pass phrase is F's first line "
        f"(else ${PASSPHRASE_ENV}); never printed",
    )
    e.add_argument("--pm", help="also write the progressive mesh (.pmwm)")
    g = e.add_mutually_exclusive_group()
    g.add_argument("--payload", help="text payload (UTF-8)")
    g.add_argument("--bits", help="payload bits, e.g. 0110...")
    e.add_argument("--n-bits", type=int, default=64, help="random payload length without --payload/--bits")
    e.add_argument("--seed", type=int, help="seed of every random choice (default: a fresh secret)")
    e.add_argument(
        "--strength",
        type=float,
        help="robust and paper: a factor (default 2); cho1, cho2: Cho's alpha (default 0.05); "
        "blind: the bin-mean margin in a bin of median count (default: calibrated per mesh)",
    )
    e.add_argument("--base-ratio", type=float, default=0.03, help="base mesh vertices / input vertices")
    e.add_argument(
        "--scheme",
        choices=tuple(SCHEMES),
        default="robust",
        help="; ".join(f"{s.name}: {s.description}" for s in SCHEMES.values()),
    )
    e.add_argument("--force", action="store_true", help="overwrite existing outputs")
    e.add_argument("-q", "--quiet", action="store_true")
    e.set_defaults(func=cmd_embed)

    v = sub.add_parser("verify", help="check a suspect mesh or .pmwm for the mark")
    v.add_argument("suspect")
    v.add_argument(
        "--key",
        action="append",
        help=f"the key file of the mark (not for a {' or '.join(keyed_by(PASS_PHRASE))} mark); give it again "
        "for each further key: one verdict per key, each p-value times the keys tried",
    )
    v.add_argument(
        "--passphrase-file",
        metavar="F",
        help=f"read a {' or '.join(keyed_by(PASS_PHRASE))} mark with the pass phrase in F's first line "
        f"(else ${PASSPHRASE_ENV})",
    )
    v.add_argument(
        "--json", action="store_true", help="one JSON object on stdout (several keys: one holding each key's verdict)"
    )
    v.add_argument("--level", type=int, help="(.pmwm) records to apply")
    v.add_argument("--vertices", type=int, help="(.pmwm) level of detail by vertex count")
    v.add_argument("--p-threshold", type=float, default=1e-6)
    v.add_argument(
        "--report",
        metavar="REPORT.html",
        help="also write a self-contained HTML verification report (verdict, hashes, per-bit chart, views)",
    )
    v.add_argument("--force", action="store_true", help="overwrite an existing report")
    v.set_defaults(func=cmd_verify)

    d = sub.add_parser("decode", help="write a level of detail of a .pmwm as a mesh")
    d.add_argument("input")
    d.add_argument("-o", "--output", required=True)
    lv = d.add_mutually_exclusive_group()
    lv.add_argument("--level", type=int, help="number of vertex-split records to apply")
    lv.add_argument("--vertices", type=int, help="vertex count of the level of detail")
    d.add_argument("--force", action="store_true")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=cmd_decode)

    i = sub.add_parser("info", help="describe a .pmwm file")
    i.add_argument("input")
    i.add_argument("--json", action="store_true")
    i.set_defaults(func=cmd_info)

    w = sub.add_parser("viewer", help="write a web page that streams a .pmwm: coarse first, refined as it arrives")
    w.add_argument("input", help="the progressive mesh (.pmwm)")
    w.add_argument("-o", "--output", required=True, help="the folder to write (index.html, viewer.js, model.pmwm)")
    w.add_argument("--title", help="the page's title (default: the file's name)")
    w.add_argument("--force", action="store_true", help="write into a folder that is not empty")
    w.add_argument("-q", "--quiet", action="store_true")
    w.set_defaults(func=cmd_viewer)

    at = sub.add_parser("attack", help="apply an attack of the evaluation protocols")
    atk = at.add_subparsers(dest="kind", required=True, parser_class=_Parser)
    try:
        from .attacks import ATTACKS
    except ImportError:  # pragma: no cover - attacks always ship with pmwm
        ATTACKS = {}
    for name, fn in ATTACKS.items():
        ap = atk.add_parser(name, help=(fn.__doc__ or "").strip().splitlines()[0] if fn.__doc__ else None)
        ap.add_argument("input")
        ap.add_argument("-o", "--output", required=True)
        for pname in _attack_params(fn):
            default = inspect.signature(fn).parameters[pname].default
            typ = type(default) if isinstance(default, (int, float, str)) and not isinstance(default, bool) else None
            if pname == "seed":
                typ = int
            ap.add_argument(f"--{pname.replace('_', '-')}", dest=pname, type=typ or str, help=f"default {default!r}")
        ap.add_argument("--force", action="store_true")
        ap.add_argument("-q", "--quiet", action="store_true")
        ap.set_defaults(func=cmd_attack)

    dm = sub.add_parser("demo", help="the whole job on the bundled sample mesh")
    dm.add_argument("dir", nargs="?", default="pmwm-demo")
    dm.add_argument("--payload", default="pmwm demo")
    dm.add_argument("--seed", type=int, default=2026)
    dm.add_argument("--force", action="store_true")
    dm.set_defaults(func=cmd_demo)

    _add_fingerprint_commands(sub)

    b = sub.add_parser(
        "bench",
        add_help=False,
        help="run the robustness benchmark (both protocols, pmwm vs Cho); 'pmwm bench --help' for its options",
    )
    b.add_argument("args", nargs=argparse.REMAINDER)  # handed to the bench entry point by main()
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["bench"]:  # the benchmark has its own options
            return cmd_bench(argv[1:])
        args = build_parser().parse_args(argv)
        return args.func(args)
    except PmwmError as exc:
        print(f"pmwm: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("pmwm: interrupted", file=sys.stderr)
        return EXIT_ERROR
    except MemoryError:
        print("pmwm: error: out of memory; try a smaller mesh", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
