#!/usr/bin/env python3
"""Build the installable Blender extension ``dist/<id>-<version>.zip``.

    python build_addon.py [--out-dir dist] [--trimesh VERSION] [--no-validate]

The zip holds ``blender_manifest.toml`` and the add-on (``blender_pmwm/``) at its root, and under
``wheels/`` the pure-python wheels the add-on imports: ``pmwm`` itself (built from this checkout with
``pip wheel --no-deps``) and ``trimesh`` (``pip download --no-deps``). numpy is never bundled:
Blender ships it. The manifest's ``wheels`` list is rewritten to name exactly the bundled files, and
the archive is checked with Blender's own validator (``blender_ext.py validate``, found inside the
installed ``bpy`` wheel). The archive is reproducible: sorted entries, fixed timestamps.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
ADDON = ROOT / "blender_pmwm"
DEFAULT_TRIMESH = "5.2.0"  # pinned for reproducible builds; override with --trimesh
SKIP = ("__pycache__", ".pyc", ".pyo", ".DS_Store")


def _run(cmd: list[str]) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def build_pmwm_wheel(dest: Path) -> Path:
    """Build the pmwm wheel from a clean copy of the project (keeps build/ out of the checkout)."""
    with tempfile.TemporaryDirectory(prefix="pmwm-src-") as tmp:
        src = Path(tmp)
        for name in ("pyproject.toml", "README.md", "LICENSE", "LICENSE.txt", "COPYING"):
            if (ROOT / name).is_file():
                shutil.copy2(ROOT / name, src / name)
        shutil.copytree(ROOT / "core", src / "core",
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info"))
        _run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(dest), str(src)])
    return _one(dest, "pmwm-*.whl")


def download_trimesh_wheel(dest: Path, version: str) -> Path:
    """Fetch the pure-python trimesh wheel (no dependencies: Blender provides numpy)."""
    _run([sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
          "-d", str(dest), f"trimesh=={version}"])
    return _one(dest, "trimesh-*.whl")


def _one(folder: Path, pattern: str) -> Path:
    found = sorted(folder.glob(pattern))
    if len(found) != 1:
        raise SystemExit(f"expected one {pattern} in {folder}, found {[p.name for p in found]}")
    if not found[0].name.endswith("-py3-none-any.whl"):
        raise SystemExit(f"{found[0].name} is not a pure-python wheel: it cannot be bundled")
    return found[0]


def manifest_with_wheels(text: str, wheels: list[str]) -> str:
    """The manifest text with its ``wheels = [...]`` list naming exactly ``wheels``."""
    listing = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    new, n = re.subn(r"(?ms)^wheels\s*=\s*\[.*?\]", listing, text)
    if n != 1:
        raise SystemExit("blender_manifest.toml must hold exactly one 'wheels = [...]' list")
    return new


def addon_files() -> list[Path]:
    """The add-on's files (relative to blender_pmwm/), without caches and the manifest."""
    files = []
    for path in sorted(ADDON.rglob("*")):
        rel = path.relative_to(ADDON)
        if path.is_file() and not any(part.endswith(SKIP) for part in rel.parts):
            if rel.as_posix() != "blender_manifest.toml":
                files.append(rel)
    return files


def write_zip(out: Path, manifest: str, wheels: list[Path]) -> None:
    """Write the extension archive deterministically."""
    def add(zf: zipfile.ZipFile, name: str, data: bytes) -> None:
        info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
        info.external_attr = 0o644 << 16
        info.compress_type = zipfile.ZIP_DEFLATED
        zf.writestr(info, data)

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".zip.tmp")
    with zipfile.ZipFile(tmp, "w") as zf:
        add(zf, "blender_manifest.toml", manifest.encode("utf-8"))
        for rel in addon_files():
            add(zf, rel.as_posix(), (ADDON / rel).read_bytes())
        for wheel in wheels:
            add(zf, f"wheels/{wheel.name}", wheel.read_bytes())
    tmp.replace(out)


def find_blender_ext() -> Path | None:
    """Blender's extension tool inside the installed bpy wheel (not imported: bpy is slow to load)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        return None
    for base in spec.submodule_search_locations:
        found = sorted(Path(base).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    return None


def validate(zip_path: Path) -> None:
    tool = find_blender_ext()
    if tool is None:
        raise SystemExit("bpy is not installed: cannot run Blender's validator (pass --no-validate to skip)")
    _run([sys.executable, str(tool), "validate", str(zip_path)])


def build(out_dir: Path, trimesh_version: str, check: bool = True) -> Path:
    """Build, write and (optionally) validate the extension zip; returns its path."""
    manifest_text = (ADDON / "blender_manifest.toml").read_text(encoding="utf-8")
    meta = tomllib.loads(manifest_text)
    with tempfile.TemporaryDirectory(prefix="pmwm-wheels-") as tmp:
        wheel_dir = Path(tmp)
        wheels = [build_pmwm_wheel(wheel_dir / "pmwm"), download_trimesh_wheel(wheel_dir / "trimesh", trimesh_version)]
        pmwm_version = wheels[0].name.split("-")[1]
        if pmwm_version != meta["version"]:
            raise SystemExit(f"manifest version {meta['version']} differs from the pmwm wheel's {pmwm_version}")
        manifest = manifest_with_wheels(manifest_text, [w.name for w in wheels])
        out = out_dir / f"{meta['id']}-{meta['version']}.zip"
        write_zip(out, manifest, wheels)
    if check:
        validate(out)
    print(f"built {out}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out-dir", type=Path, default=ROOT / "dist", help="output folder (default: dist/)")
    ap.add_argument("--trimesh", default=None,
                    help=f"trimesh version to bundle (default: the installed one, else {DEFAULT_TRIMESH})")
    ap.add_argument("--no-validate", action="store_true", help="skip Blender's validator")
    args = ap.parse_args(argv)
    version = args.trimesh
    if version is None:
        try:
            version = importlib.metadata.version("trimesh")
        except importlib.metadata.PackageNotFoundError:
            version = DEFAULT_TRIMESH
    build(args.out_dir, version, check=not args.no_validate)
    return 0


if __name__ == "__main__":
    sys.exit(main())
