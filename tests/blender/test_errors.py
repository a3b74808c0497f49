"""Every operator's error paths: an ERROR report (RuntimeError for a script) and an unchanged scene."""

from __future__ import annotations

import bpy
import pytest

KEY_PREFS = "blender_pmwm"  # the add-on's preferences, registered by the key_prefs fixture


def _camera():
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.collection.objects.link(cam)
    return cam


def _setup(case, bl, tmp_path):
    """Build the scene for one case; returns the operator keyword arguments."""
    key = tmp_path / "owner.key.json"
    pm = tmp_path / "owner.pmwm"
    bl.suzanne(levels=1)
    if case == "no_active":
        bpy.context.view_layer.objects.active = None
    elif case == "non_mesh":
        bl.activate(_camera())
    elif case == "edit_mode":
        bpy.ops.object.mode_set(mode="EDIT")
    elif case == "empty_mesh":
        bl.activate(bl.new_object("Empty mesh", [], []))
    elif case in ("existing_key", "invalid_key"):
        key.write_text('{"format": "not a pmwm key"}\n' if case == "invalid_key" else "keep me\n")
    elif case == "invalid_pm":
        pm.write_bytes(b"PMWM" + bytes(range(200)))
    elif case == "marked":
        bpy.ops.pmwm.watermark(payload="Hi", key_path=str(key), seed=1)
    elif case == "marked_without_pm":
        bpy.ops.pmwm.watermark(payload="Hi", key_path=str(key), seed=1, progressive=False)
    elif case == "pm_level":
        bpy.ops.pmwm.watermark(payload="Hi", key_path=str(key), seed=1)
        bpy.ops.pmwm.export_pm(filepath=str(pm))
    elif case == "key_folder_is_a_file":  # unsaved .blend, default key path, the folder is a file
        folder = tmp_path / "keys"
        folder.write_text("not a folder\n")
        bpy.context.preferences.addons[KEY_PREFS].preferences.key_folder = str(folder)
    elif case == "payload_too_big":
        return {"payload": "x" * 2000}
    return {}


CASES = {
    # operator: [(case, extra kwargs, message fragment)]
    "watermark": [
        ("no_active", {}, "no active object"),
        ("non_mesh", {}, "not a mesh"),
        ("edit_mode", {}, "Object Mode"),
        ("empty_mesh", {}, "no faces"),
        ("existing_key", {}, "exists"),
        ("key_folder_is_a_file", {"key_path": ""}, "is a file"),
        ("payload_too_big", {}, "can carry"),
        ("missing_folder", {"key_path": "MISSING_DIR"}, "folder does not exist"),
    ],
    "export_pm": [
        ("no_active", {}, "no active object"),
        ("non_mesh", {}, "not a mesh"),
        ("edit_mode", {}, "Object Mode"),
        ("empty_mesh", {}, "watermark this object first"),
        ("not_marked", {}, "watermark this object first"),
        ("marked", {"filepath": "MISSING_DIR"}, "missing"),
        ("marked_without_pm", {}, "without its progressive mesh"),
    ],
    "import_pm": [
        ("missing_pm", {}, "no such file"),
        ("invalid_pm", {}, "not a .pmwm"),
        ("pm_level", {"level": 10_000}, "out of range"),
        ("edit_mode", {}, "Object Mode"),
    ],
    "verify": [
        ("no_active", {}, "no active object"),
        ("non_mesh", {}, "not a mesh"),
        ("edit_mode", {}, "Object Mode"),
        ("empty_mesh", {"key_path": "VALID"}, "no faces"),
        ("missing_key", {}, "not found"),
        ("invalid_key", {}, "not a pmwm key"),
    ],
}


def _kwargs(op, tmp_path, extra):
    key = str(tmp_path / "owner.key.json")
    pm = str(tmp_path / "owner.pmwm")
    base = {
        "watermark": {"payload": "Hi", "key_path": key, "seed": 1},
        "export_pm": {"filepath": pm},
        "import_pm": {"filepath": pm},
        "verify": {"key_path": key},
    }[op]
    return {**base, **extra}


@pytest.mark.parametrize(
    "op,case,extra,message",
    [(op, *c) for op, cases in CASES.items() for c in cases],
    ids=[f"{op}-{c[0]}" for op, cases in CASES.items() for c in cases],
)
@pytest.mark.slow
def test_error_reports_and_leaves_scene_unchanged(scene, bl, tmp_path, key_prefs, op, case, extra, message):
    kwargs = {**_kwargs(op, tmp_path, extra), **_setup(case, bl, tmp_path)}
    for name, value in kwargs.items():
        if value == "MISSING_DIR":
            kwargs[name] = str(tmp_path / "missing" / "file")
    if kwargs.get("key_path") == "VALID":  # a real key, so that the mesh is what fails
        kwargs["key_path"] = str(_real_key(bl, tmp_path))
    before = bl.snapshot(tmp_path)
    with pytest.raises(RuntimeError, match=message) as err:
        getattr(bpy.ops.pmwm, op)(**kwargs)
    # the operator's ERROR report, or its poll message (the reason a greyed-out button gives)
    text = str(err.value).strip()
    assert text.startswith(("Error:", f"Operator bpy.ops.pmwm.{op}.poll()")) and "\n" not in text, text
    assert bl.snapshot(tmp_path) == before


def _real_key(bl, tmp_path):
    active = bpy.context.view_layer.objects.active
    bl.suzanne(levels=1)
    key = tmp_path / "valid.key.json"
    bpy.ops.pmwm.watermark(payload="Hi", key_path=str(key), seed=1)
    bl.activate(active)
    return key


def test_existing_key_file_is_kept_and_overwrite_replaces_it(scene, bl, tmp_path):
    key = tmp_path / "k.json"
    key.write_text("keep me\n")
    bl.suzanne(levels=1)
    with pytest.raises(RuntimeError, match="Overwrite Key"):
        bpy.ops.pmwm.watermark(payload="Hi", key_path=str(key), seed=1)
    assert key.read_text() == "keep me\n"
    assert bpy.ops.pmwm.watermark(payload="Hi", key_path=str(key), seed=1, overwrite_key=True) == {"FINISHED"}
    assert key.read_text().startswith("{")
