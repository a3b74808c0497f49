"""Watermark every mesh object of a .blend with the PM Watermark extension, headless.

    blender --background scene.blend --python watermark_all.py -- \\
        --key-dir keys --payload "ACME 2026" [--strength 2.0] [--base-ratio 0.03] \\
        [--export-pm] [--overwrite] [--save]

Writes one key file per mesh, ``<key-dir>/<object>.key.json`` (keep them secret), and with
``--export-pm`` the progressive mesh ``<key-dir>/<object>.pmwm``. Objects sharing a mesh are marked
once. ``--save`` saves the .blend with the marked meshes. Exit code 1 when any object failed.
The extension must be installed and enabled in the Blender that runs this script.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

import bpy


def parse_args(argv: list[str]) -> argparse.Namespace:
    """Parse the arguments after ``--`` (Blender keeps the ones before it)."""
    argv = argv[argv.index("--") + 1 :] if "--" in argv else []
    ap = argparse.ArgumentParser(prog="watermark_all.py", description="Watermark every mesh object.")
    ap.add_argument("--key-dir", required=True, help="folder for the key files (created if needed)")
    ap.add_argument("--payload", required=True, help="text to embed, e.g. an owner id")
    ap.add_argument("--strength", type=float, default=2.0)
    ap.add_argument("--base-ratio", type=float, default=0.03)
    ap.add_argument("--export-pm", action="store_true", help="also write <object>.pmwm progressive meshes")
    ap.add_argument("--overwrite", action="store_true", help="replace existing key files")
    ap.add_argument("--save", action="store_true", help="save the .blend afterwards")
    return ap.parse_args(argv)


def _file_stem(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "object"


def watermark_all(
    key_dir: str,
    payload: str,
    strength: float = 2.0,
    base_ratio: float = 0.03,
    export_pm: bool = False,
    overwrite: bool = False,
) -> list[tuple[str, str]]:
    """Watermark each mesh object of the view layer; returns (object name, outcome) pairs."""
    os.makedirs(key_dir, exist_ok=True)
    if bpy.context.object is not None and bpy.context.object.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    view_layer = bpy.context.view_layer
    done: dict[str, str] = {}  # mesh name -> object that carried it
    results = []
    for ob in [o for o in view_layer.objects if o.type == "MESH"]:
        if ob.data.name in done:
            results.append((ob.name, f"skipped: shares its mesh with {done[ob.data.name]}"))
            continue
        view_layer.objects.active = ob
        stem = os.path.join(key_dir, _file_stem(ob.name))
        try:
            bpy.ops.pmwm.watermark(
                payload=payload,
                key_path=stem + ".key.json",
                strength=strength,
                base_ratio=base_ratio,
                overwrite_key=overwrite,
            )
            if export_pm:
                bpy.ops.pmwm.export_pm(filepath=stem + ".pmwm")
        except RuntimeError as exc:  # the operator's ERROR report
            results.append((ob.name, "failed: " + str(exc).strip()))
            continue
        done[ob.data.name] = ob.name
        results.append((ob.name, "marked: " + stem + ".key.json"))
    return results


def main(argv: list[str]) -> int:
    args = parse_args(argv)
    try:
        bpy.ops.pmwm.watermark.get_rna_type()
    except KeyError:
        print("watermark_all.py: the PM Watermark extension is not enabled in this Blender", file=sys.stderr)
        return 2
    results = watermark_all(args.key_dir, args.payload, args.strength, args.base_ratio, args.export_pm, args.overwrite)
    for name, outcome in results:
        print(f"{name}: {outcome}")
    if args.save and bpy.data.filepath:
        bpy.ops.wm.save_mainfile()
    return 1 if any(outcome.startswith("failed") for _, outcome in results) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
