"""The README's headless example (blender_pmwm/examples/watermark_all.py) run in this process."""

from __future__ import annotations

import importlib.util
import os

import bpy
import pytest


@pytest.fixture(scope="module")
def example(addon):
    path = addon.__path__[0] + "/examples/watermark_all.py"
    spec = importlib.util.spec_from_file_location("pmwm_example_watermark_all", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # __name__ is not "__main__": nothing runs
    return module


def test_arguments_after_the_double_dash(example):
    args = example.parse_args(
        ["blender", "-b", "x.blend", "--python", "w.py", "--", "--key-dir", "keys", "--payload", "ACME", "--export-pm"]
    )
    assert (args.key_dir, args.payload, args.export_pm, args.save, args.strength) == ("keys", "ACME", True, False, 2.0)
    with pytest.raises(SystemExit):
        example.parse_args(["blender", "--python", "w.py"])  # no "--": the required options are missing


@pytest.mark.slow
def test_watermarks_every_mesh_object_once(scene, bl, example, tmp_path, capfd):
    a = bl.suzanne(levels=2)
    b = bl.suzanne(levels=2)
    b.name = "Suzanne / copy"  # a name that is not a safe file name
    twin = bpy.data.objects.new("Twin", a.data)  # shares a's mesh
    bpy.context.collection.objects.link(twin)
    bl.new_object("Empty mesh", [], [])
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.collection.objects.link(cam)

    key_dir = tmp_path / "keys"
    code = example.main(["blender", "--", "--key-dir", str(key_dir), "--payload", "ACME 2026", "--export-pm"])
    out = capfd.readouterr().out
    assert code == 1  # the empty mesh cannot be marked
    assert "Empty mesh: failed" in out and "Twin: skipped" in out and "Camera" not in out

    for ob in (a, b):
        stem = str(key_dir / example._file_stem(ob.name))
        key = stem + ".key.json"
        assert os.path.isfile(key) and os.path.isfile(stem + ".pmwm")
        bl.activate(ob)
        bpy.ops.pmwm.verify(key_path=key)
        assert (ob.pmwm_verdict.marked, ob.pmwm_verdict.payload) == (True, "ACME 2026")
    assert sorted(p.name for p in key_dir.iterdir()) == sorted(
        [f"{example._file_stem(n)}{ext}" for n in (a.name, b.name) for ext in (".key.json", ".pmwm")]
    )
