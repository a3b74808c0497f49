#!/usr/bin/env python3
"""Build the installable Blender extension zips ``dist/<id>-<version>-<python>-<platform>.zip``.

    python build_addon.py [--out-dir dist] [--platform P ...] [--python X.Y ...] [--trimesh VERSION]
                          [--no-validate]

pmwm's spatial queries use scipy, a compiled package, so the extension is built per platform (Blender's
split-platform build: linux-x64, windows-x64, macos-arm64, macos-x64) and per Blender Python: Blender
4.2 to 5.0 run Python 3.11 and Blender 5.1 and later run Python 3.13, each zip names its range in
``blender_version_min``/``blender_version_max`` and its platform in ``platforms``. One zip per pair, so
that each carries exactly one scipy wheel: Blender 4.2 does not match a wheel's Python tag and would
pick the newest of two. By default all eight are built; ``--platform this --python this`` builds the
one for the machine at hand (what the add-on tests install).

Each zip holds ``blender_manifest.toml`` and the add-on (``blender_pmwm/``) at its root, and under
``wheels/``: ``pmwm`` itself, ``trimesh`` (pure python) and scipy for that platform and Python
(``pip download --no-deps``; the scipy versions are chosen for the numpy each Blender ships: scipy
1.15.3 accepts numpy 1.23.5 to 2.4, Blender 4.2-5.0's numpy 1.24-1.26; scipy 1.17.1 accepts Blender
5.1+'s numpy 2.x). pykdtree, the library's faster KD-tree where pip installs it, is not bundled: its
macOS wheels carry their own OpenMP runtime, Blender on macOS loads one already, and two LLVM OpenMP
runtimes in one process abort it (OMP Error #15); inside Blender scipy answers every spatial query
(``pmwm.spatial``). The pmwm wheel holds the library only: it is built (``pip wheel --no-deps``) from
a copy of ``core/pmwm`` with a pyproject derived from this checkout's, without the evaluation package
``pmwm_bench``, its ``pmwm.commands`` entry point and the extras; the build checks that. numpy is never
bundled: Blender ships it. The manifest's ``wheels`` list is rewritten to name exactly the bundled
files, and each archive is checked with Blender's own validator (``blender_ext.py validate``, found
inside the installed ``bpy`` wheel). The archives are reproducible: sorted entries, fixed timestamps.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import json
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import tomllib
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

ROOT = Path(__file__).resolve().parent
ADDON = ROOT / "blender_pmwm"
DEFAULT_TRIMESH = "5.2.0"  # pinned for reproducible builds; override with --trimesh
SKIP = ("__pycache__", ".pyc", ".pyo", ".DS_Store")

# Blender's platform names -> the pip platform tags to download for (pip takes older macOS tags by itself,
# not older manylinux ones). Blender itself needs glibc 2.28 on Linux and macOS 11.2 on macOS; the macOS
# arm64 scipy wheels start at macOS 12.
PLATFORMS = {
    "linux-x64": ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"),
    "windows-x64": ("win_amd64",),
    "macos-arm64": ("macosx_12_0_arm64",),
    "macos-x64": ("macosx_11_0_x86_64",),
}


@dataclass(frozen=True)
class BlenderPython:
    """The Python of a range of Blender releases, and the compiled wheels built for it."""

    version: str  # "3.11"
    blender_min: str
    blender_max: Optional[str]  # exclusive, as the manifest's blender_version_max
    scipy: str


PYTHONS = {
    "3.11": BlenderPython("3.11", "4.2.0", "5.1.0", "1.15.3"),
    "3.13": BlenderPython("3.13", "5.1.0", None, "1.17.1"),
}


@dataclass(frozen=True)
class Target:
    platform: str  # a key of PLATFORMS
    python: BlenderPython

    @property
    def tag(self) -> str:
        """The file-name part: py311-linux_x64."""
        return f"py{self.python.version.replace('.', '')}-{self.platform.replace('-', '_')}"


def this_platform() -> str:
    """Blender's name of this machine's platform (a SystemExit when Blender has no build for it)."""
    plat = sysconfig.get_platform()
    machine = platform.machine().lower()
    arm = machine in ("arm64", "aarch64")
    name = (
        "windows"
        if plat.startswith("win")
        else "macos"
        if plat.startswith("macosx")
        else "linux"
        if plat.startswith("linux")
        else plat
    ) + ("-arm64" if arm else "-x64")
    if name not in PLATFORMS:
        raise SystemExit(f"no Blender extension build for this platform ({plat}, {machine})")
    return name


def targets(platforms: list[str], pythons: list[str]) -> list[Target]:
    """The (platform, Python) pairs to build from the command line's choices: a name, "this" (the
    machine at hand) or "all" (the default)."""

    def expand(values: list[str], known: list[str], this, what: str) -> list[str]:
        out: list[str] = []
        for v in values or ["all"]:
            for p in known if v == "all" else [this() if v == "this" else v]:
                if p not in known:
                    raise SystemExit(f"unknown {what} {p!r}: choose from {', '.join(known)}, this or all")
                if p not in out:
                    out.append(p)
        return out

    def this_python() -> str:
        return f"{sys.version_info.major}.{sys.version_info.minor}"

    return [
        Target(pl, PYTHONS[py])
        for py in expand(pythons, list(PYTHONS), this_python, "Python")
        for pl in expand(platforms, list(PLATFORMS), this_platform, "platform")
    ]


def _run(cmd: list[str]) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


LIBRARY = "pmwm"  # the one package the extension carries
PLUGIN_GROUP = "pmwm.commands"  # entry points of the evaluation (pmwm bench): not in the extension


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string: JSON's escapes are TOML's
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def dump_toml(doc: dict) -> str:
    """TOML text of ``doc`` (tables of strings, numbers, booleans, lists and inline tables): enough for
    a pyproject; tomllib reads it back to ``doc``."""
    lines: list[str] = []

    def table(name: str, d: dict) -> None:
        scalars = [(k, v) for k, v in d.items() if not isinstance(v, dict)]
        if name and (scalars or not d):  # a table holding only subtables needs no header of its own
            lines.append(f"[{name}]")
        lines.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in scalars)
        if scalars or (name and not d):
            lines.append("")
        for k, v in d.items():
            if isinstance(v, dict):
                table(f"{name}.{_toml_key(k)}" if name else _toml_key(k), v)

    table("", doc)
    return "\n".join(lines)


def library_pyproject(text: str) -> str:
    """The pyproject of the library alone, from the project's: the same metadata without the extras and
    the ``pmwm.commands`` entry point; setuptools finds ``pmwm`` and its subpackages only."""
    meta = tomllib.loads(text)
    project = {k: v for k, v in meta["project"].items() if k != "optional-dependencies"}
    groups = {g: eps for g, eps in project.pop("entry-points", {}).items() if g != PLUGIN_GROUP}
    if groups:
        project["entry-points"] = groups
    setuptools_cfg = dict(meta.get("tool", {}).get("setuptools", {}))
    setuptools_cfg["packages"] = {"find": {"where": ["core"], "include": [LIBRARY, f"{LIBRARY}.*"]}}
    data = setuptools_cfg.get("package-data", {})
    setuptools_cfg["package-data"] = {k: v for k, v in data.items() if k == LIBRARY or k.startswith(LIBRARY + ".")}
    return dump_toml({"build-system": meta["build-system"], "project": project, "tool": {"setuptools": setuptools_cfg}})


def check_library_wheel(wheel: Path) -> None:
    """Refuse a pmwm wheel that carries anything but the library (another package, the bench plugin)."""
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
        extra = sorted({n.split("/")[0] for n in names if not n.startswith((LIBRARY + "/", f"{LIBRARY}-"))})
        eps = next((zf.read(n).decode() for n in names if n.endswith(".dist-info/entry_points.txt")), "")
    if extra:
        raise SystemExit(f"{wheel.name} holds more than the {LIBRARY} package: {extra}")
    if f"[{PLUGIN_GROUP}]" in eps:
        raise SystemExit(f"{wheel.name} declares the {PLUGIN_GROUP} entry points of the evaluation")


def build_pmwm_wheel(dest: Path) -> Path:
    """Build the library's wheel from a clean copy of ``core/pmwm`` (keeps build/ out of the checkout,
    and pmwm_bench out of the wheel)."""
    with tempfile.TemporaryDirectory(prefix="pmwm-src-") as tmp:
        src = Path(tmp)
        for name in ("README.md", "LICENSE", "LICENSE.txt", "COPYING"):
            if (ROOT / name).is_file():
                shutil.copy2(ROOT / name, src / name)
        (src / "pyproject.toml").write_text(
            library_pyproject((ROOT / "pyproject.toml").read_text(encoding="utf-8")), encoding="utf-8"
        )
        shutil.copytree(
            ROOT / "core" / LIBRARY,
            src / "core" / LIBRARY,
            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info"),
        )
        _run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(dest), str(src)])
    wheel = _one(dest, "pmwm-*.whl")
    check_library_wheel(wheel)
    return wheel


def download_trimesh_wheel(dest: Path, version: str) -> Path:
    """Fetch the pure-python trimesh wheel (no dependencies: Blender provides numpy)."""
    _run(
        [
            sys.executable,
            "-m",
            "pip",
            "download",
            "--quiet",
            "--no-deps",
            "--only-binary=:all:",
            "-d",
            str(dest),
            f"trimesh=={version}",
        ]
    )
    return _one(dest, "trimesh-*.whl")


def download_compiled_wheel(dest: Path, requirement: str, target: Target) -> Path:
    """Fetch the binary wheel of ``requirement`` for the target's platform and Python (no dependencies)."""
    py = target.python.version.replace(".", "")
    _run(
        [
            sys.executable,
            "-m",
            "pip",
            "download",
            "--quiet",
            "--no-deps",
            "--only-binary=:all:",
            *[a for tag in PLATFORMS[target.platform] for a in ("--platform", tag)],
            "--python-version",
            target.python.version,
            "--implementation",
            "cp",
            "--abi",
            f"cp{py}",
            "-d",
            str(dest),
            requirement,
        ]
    )
    return _one(dest, requirement.split("==")[0] + "-*.whl", pure=False)


def _one(folder: Path, pattern: str, pure: bool = True) -> Path:
    found = sorted(folder.glob(pattern))
    if len(found) != 1:
        raise SystemExit(f"expected one {pattern} in {folder}, found {[p.name for p in found]}")
    if pure and not found[0].name.endswith("-py3-none-any.whl"):
        raise SystemExit(f"{found[0].name} is not a pure-python wheel: it cannot be bundled")
    return found[0]


def manifest_for(text: str, wheels: list[str], target: Target) -> str:
    """The manifest text with its ``wheels = [...]`` list naming exactly ``wheels``, and the target's
    platform and Blender range (``platforms``, ``blender_version_min``/``_max``)."""
    listing = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    new, n = re.subn(r"(?ms)^wheels\s*=\s*\[.*?\]", listing, text)
    if n != 1:
        raise SystemExit("blender_manifest.toml must hold exactly one 'wheels = [...]' list")
    new, n = re.subn(r"(?m)^blender_version_min\s*=.*$", f'blender_version_min = "{target.python.blender_min}"', new)
    if n != 1:
        raise SystemExit("blender_manifest.toml must hold exactly one blender_version_min")
    if re.search(r"(?m)^(blender_version_max|platforms)\s*=", new):
        raise SystemExit("blender_manifest.toml must not set blender_version_max or platforms: the build does")
    extra = f'platforms = ["{target.platform}"]\n'
    if target.python.blender_max:
        extra = f'blender_version_max = "{target.python.blender_max}"\n' + extra
    return re.sub(r"(?m)^(blender_version_min = .*\n)", lambda m: m.group(1) + extra, new, count=1)


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


def build(out_dir: Path, trimesh_version: str, check: bool = True, which: Optional[list[Target]] = None) -> list[Path]:
    """Build, write and (optionally) validate one extension zip per target (default: every platform
    and Python); returns their paths."""
    manifest_text = (ADDON / "blender_manifest.toml").read_text(encoding="utf-8")
    meta = tomllib.loads(manifest_text)
    built = []
    with tempfile.TemporaryDirectory(prefix="pmwm-wheels-") as tmp:
        wheel_dir = Path(tmp)
        common = [build_pmwm_wheel(wheel_dir / "pmwm"), download_trimesh_wheel(wheel_dir / "trimesh", trimesh_version)]
        pmwm_version = common[0].name.split("-")[1]
        if pmwm_version != meta["version"]:
            raise SystemExit(f"manifest version {meta['version']} differs from the pmwm wheel's {pmwm_version}")
        for target in which if which is not None else targets([], []):
            scipy = download_compiled_wheel(wheel_dir / target.tag, f"scipy=={target.python.scipy}", target)
            wheels = [*common, scipy]
            manifest = manifest_for(manifest_text, [w.name for w in wheels], target)
            out = out_dir / f"{meta['id']}-{meta['version']}-{target.tag}.zip"
            write_zip(out, manifest, wheels)
            if check:
                validate(out)
            print(f"built {out} ({out.stat().st_size / 2**20:.1f} MiB)")
            built.append(out)
    return built


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out-dir", type=Path, default=ROOT / "dist", help="output folder (default: dist/)")
    ap.add_argument(
        "--trimesh",
        default=None,
        help=f"trimesh version to bundle (default: the installed one, else {DEFAULT_TRIMESH})",
    )
    ap.add_argument(
        "--platform",
        action="append",
        default=[],
        help=f"a Blender platform ({', '.join(PLATFORMS)}), this, or all (default; repeatable)",
    )
    ap.add_argument(
        "--python",
        action="append",
        default=[],
        help=f"a Blender Python ({', '.join(PYTHONS)}), this, or all (default; repeatable)",
    )
    ap.add_argument("--no-validate", action="store_true", help="skip Blender's validator")
    args = ap.parse_args(argv)
    version = args.trimesh
    if version is None:
        try:
            version = importlib.metadata.version("trimesh")
        except importlib.metadata.PackageNotFoundError:
            version = DEFAULT_TRIMESH
    build(args.out_dir, version, check=not args.no_validate, which=targets(args.platform, args.python))
    return 0


if __name__ == "__main__":
    sys.exit(main())
