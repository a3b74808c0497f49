"""The built extension zip: contents, Blender's validator, an isolated install, the bundled wheels."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


@pytest.fixture(scope="module")
def built_zip(extension_zip):
    """dist/pmwm-<version>-<python>-<platform>.zip built by build_addon.py for this machine (pip wheel of
    this checkout, trimesh, scipy)."""
    return extension_zip


@pytest.mark.slow
def test_zip_holds_manifest_addon_and_the_wheels_for_this_platform(built_zip, build_addon):
    manifest_src = tomllib.loads((ROOT / "blender_pmwm" / "blender_manifest.toml").read_text())
    with zipfile.ZipFile(built_zip) as zf:
        names = set(zf.namelist())
        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode())
    py = f"{sys.version_info.major}{sys.version_info.minor}"
    platform = build_addon.this_platform()
    assert built_zip.name == f"{manifest['id']}-{manifest['version']}-py{py}-{platform.replace('-', '_')}.zip"
    assert {"__init__.py", "operators.py", "panel.py", "props.py", "examples/watermark_all.py"} <= names
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)
    wheels = sorted(n for n in names if n.startswith("wheels/"))
    # (no pykdtree: its macOS OpenMP runtime would abort Blender; scipy answers there, pmwm.spatial)
    assert [w.split("/")[1].split("-")[0] for w in wheels] == ["pmwm", "scipy", "trimesh"]
    pure = [w for w in wheels if "scipy" not in w]
    assert all(w.endswith("-py3-none-any.whl") for w in pure)
    (scipy,) = [w for w in wheels if "scipy" in w]
    assert f"-cp{py}-cp{py}-" in scipy  # compiled for this Blender's Python, one wheel only
    assert not any("numpy" in w for w in wheels)  # Blender ships numpy
    assert sorted(manifest["wheels"]) == sorted("./" + w for w in wheels)
    for field in ("schema_version", "id", "type", "license", "permissions", "tagline"):
        assert manifest[field] == manifest_src[field]
    assert manifest["platforms"] == [platform]
    # the Blender releases that run this Python: 4.2 to 5.0 on 3.11, 5.1 and later on 3.13
    span = {"311": ("4.2.0", "5.1.0"), "313": ("5.1.0", None)}[py]
    assert (manifest["blender_version_min"], manifest.get("blender_version_max")) == span
    assert (manifest["id"], manifest["type"]) == ("pmwm", "add-on")
    assert manifest["license"] == ["SPDX:GPL-3.0-or-later"] and "files" in manifest["permissions"]


def test_every_platform_and_python_is_a_build_target(build_addon):
    built = build_addon.targets([], [])
    assert {(t.platform, t.python.version) for t in built} == {
        (p, v) for p in ("linux-x64", "windows-x64", "macos-arm64", "macos-x64") for v in ("3.11", "3.13")
    }
    assert len({t.tag for t in built}) == 8
    with pytest.raises(SystemExit, match="unknown platform"):
        build_addon.targets(["linux-arm"], [])


@pytest.mark.slow
def test_blenders_validator_accepts_the_zip(built_zip, build_addon):
    tool = build_addon.find_blender_ext()
    assert tool is not None and tool.is_file()
    proc = subprocess.run(
        [sys.executable, str(tool), "validate", str(built_zip)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_addon_sources_never_touch_sys_path_and_import_relatively():
    for path in (ROOT / "blender_pmwm").rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr == "path":
                assert not (isinstance(node.value, ast.Name) and node.value.id == "sys"), f"sys.path in {path}"
            if isinstance(node, (ast.Import, ast.ImportFrom)) and path.parent.name == "blender_pmwm":
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                assert not any(n.startswith("blender_pmwm") for n in names), f"absolute self-import in {path}"


def _run(mode: str, arg: Path, resources: Path) -> dict:
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(resources)}
    proc = subprocess.run(
        [sys.executable, str(HERE / "install_check.py"), mode, str(arg)],
        env=env,
        cwd=str(resources),
        capture_output=True,
        text=True,
        timeout=300,
    )
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT:")]
    assert proc.returncode == 0 and lines, proc.stdout[-3000:] + proc.stderr[-3000:]
    return json.loads(lines[-1][len("RESULT:") :])


@pytest.mark.slow
def test_install_into_isolated_user_resources(built_zip, tmp_path):
    resources = tmp_path / "blender_user"
    resources.mkdir()
    installed = _run("install", built_zip, resources)
    assert installed["enabled"] and installed["has_operators"] and installed["key_folder_pref"]
    assert installed["addon_file"].startswith(str(resources))
    assert installed["warnings"] == {}  # Blender's extension policy check

    # A restarted Blender: the bundled wheels are what `import pmwm` / `import trimesh` resolve to.
    work = tmp_path / "work"
    work.mkdir()
    used = _run("use", work, resources)
    site = resources / "extensions" / ".local"
    assert used["enabled"] and used["warnings"] == {} and used["key_folder_pref"]
    assert used["pmwm_file"].startswith(str(site)), used["pmwm_file"]
    assert used["trimesh_file"].startswith(str(site)), used["trimesh_file"]
    assert used["scipy_file"].startswith(str(site)), used["scipy_file"]  # the bundled platform wheel
    assert used["kdtree_engine"] == "scipy"  # pykdtree is not bundled: scipy's KD-tree answers in Blender
    assert not used["numpy_file"].startswith(str(resources))  # numpy is Blender's own
    assert "operator_error" not in used, used.get("operator_error")
    assert used["verdict"] == {"marked": True, "payload": "Hi"}
