"""Watermark Selected and Verify Selected: the selected mesh objects marked as one asset (one key file or the
pass phrase, one undo step) and read together or alone."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from meshes import blob, cad_part

PAYLOAD = "ACME"


def _asset(bl):
    """Two mesh objects and a linked duplicate of the second (the same mesh datablock), all selected, the
    first active, each moved and turned (object transforms are not applied: the base meshes are marked)."""
    a = bl.new_object("Horse", *blob())
    b = bl.new_object("Part", *cad_part())
    b.location = (2.0, 0.5, -1.0)
    b.rotation_euler = (0.0, 0.0, 0.5)
    c = b.copy()  # shares b's mesh
    c.name = "PartCopy"
    bpy.context.collection.objects.link(c)
    for ob in (a, b, c):
        ob.select_set(True)
    bpy.context.view_layer.objects.active = a
    return a, b, c


def test_watermark_selected_marks_the_asset_with_one_key_in_one_undo_step(scene, bl, tmp_path):
    from pmwm.scene import read_keys, verify_objects

    a, b, c = _asset(bl)
    before = {ob.name: bl.positions(ob).copy() for ob in (a, b)}
    key = tmp_path / "asset.key.json"
    bpy.ops.ed.undo_push(message="before watermark")
    assert bpy.ops.pmwm.watermark_selected("EXEC_DEFAULT", True, payload=PAYLOAD, key_path=str(key), seed=4) == {
        "FINISHED"
    }
    keys = read_keys(key)
    assert [name for name, _ in keys] == ["Horse", "Part"]  # the shared mesh once
    for ob in (a, b):
        assert not np.array_equal(bl.positions(ob), before[ob.name])
    assert np.array_equal(bl.positions(b), bl.positions(c))
    for ob in (a, b):  # each object alone, as an exporter writes it, reads with the asset's key
        v = verify_objects(
            [
                (
                    ob.name,
                    bl.positions(ob).astype(np.float64),
                    np.asarray([list(t.vertices) for t in ob.data.loop_triangles], np.int64),
                )
            ],
            keys,
        )
        assert v.marked and v.payload == PAYLOAD and [f[1] for f in v.detail.found] == [ob.name]

    assert bpy.ops.pmwm.verify_selected(key_path=str(key)) == {"FINISHED"}
    for ob in (a, b, c):
        assert ob.pmwm_verdict.verified and ob.pmwm_verdict.marked and ob.pmwm_verdict.payload == PAYLOAD

    names = [ob.name for ob in (a, b)]
    bpy.ops.ed.undo()  # one step undoes every object
    for name in names:
        assert np.array_equal(bl.positions(bpy.data.objects[name]), before[name])


def test_verify_selected_of_unmarked_objects_says_not_marked(scene, bl, tmp_path):
    a, b, _ = _asset(bl)
    key = tmp_path / "asset.key.json"
    assert bpy.ops.pmwm.watermark_selected(payload=PAYLOAD, key_path=str(key), seed=4) == {"FINISHED"}
    fresh = bl.new_object("Other", *cad_part())
    assert bpy.ops.pmwm.verify_selected(key_path=str(key)) == {"FINISHED"}
    assert fresh.pmwm_verdict.verified and not fresh.pmwm_verdict.marked


def test_watermark_selected_refuses_with_one_line_and_changes_nothing(scene, bl, tmp_path):
    a, b, c = _asset(bl)
    bl.activate(b)  # Part alone in Edit Mode, then the whole asset selected again around it
    bpy.ops.object.mode_set(mode="EDIT")
    for ob in (a, c):
        ob.select_set(True)
    bpy.context.view_layer.objects.active = a
    snap = bl.snapshot(tmp_path)
    with pytest.raises(RuntimeError, match="'Part' is in Edit Mode: switch to Object Mode first"):
        bpy.ops.pmwm.watermark_selected(payload=PAYLOAD, key_path=str(tmp_path / "k.json"))
    assert bl.snapshot(tmp_path) == snap


def test_modal_run_writes_every_object_or_none(scene, bl, tmp_path, addon):
    """In the interface (the core in a worker thread): a selected object edited meanwhile stops the whole
    write-back: no object changed, no key written."""
    import time

    sel = addon.selection
    a, b, _ = _asset(bl)
    key = tmp_path / "k.json"
    run = addon.operators.ModalRun(
        sel.WatermarkSelectedTask(bpy.context, payload=PAYLOAD, key_path=str(key), seed=1), lambda kind, msg: None
    )
    run.start(bpy.context)
    assert run.status_text.startswith("Watermarking '2 selected objects': ")
    b.data.vertices[0].co.x += 0.5  # the user moves a vertex of the second object meanwhile
    before_a, edited_b = bl.positions(a).copy(), bl.positions(b).copy()
    deadline = time.monotonic() + 120
    with pytest.raises(addon.operators._Failed, match="'Part' changed while it was being watermarked"):
        while run.step(bpy.context, "TIMER") == {"RUNNING_MODAL"}:
            assert time.monotonic() < deadline
            time.sleep(0.02)
    assert np.array_equal(bl.positions(a), before_a) and np.array_equal(bl.positions(b), edited_b)
    assert not key.exists()
