"""End to end through the real operators: watermark, export PM, import at LoDs, verify, re-export."""

from __future__ import annotations

import json

import bpy
import numpy as np
import pytest

PAYLOAD = "ACME 2026"


def _verdict(scene):
    v = bpy.context.active_object.pmwm_verdict
    return v.marked, v.payload


@pytest.mark.parametrize("model", ["suzanne", "bunny"])
@pytest.mark.slow
def test_watermark_pm_lods_and_blender_exporters(scene, bl, tmp_path, capfd, model):
    """Suzanne: subdivided twice (7,958 vertices, quads); bunny: 34,835 vertices, triangles."""
    import pmwm

    ob = bl.suzanne(levels=2) if model == "suzanne" else bl.bunny()
    loops0, sizes0 = bl.polygons(ob)
    before = bl.positions(ob).copy()
    key = tmp_path / "owner.key.json"

    assert bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=11) == {"FINISHED"}
    out = capfd.readouterr().out
    assert "bits" in out and "carriers" in out and "VSNR" in out and "dB" in out
    assert key.is_file()

    # Topology kept (quads and n-gons too); positions moved by a small fraction of the size (the
    # robust scheme's bumps are a fraction of an edge high).
    loops, sizes = bl.polygons(ob)
    assert np.array_equal(loops, loops0) and np.array_equal(sizes, sizes0)
    moved = np.linalg.norm(bl.positions(ob).astype(np.float64) - before, axis=1)
    diag = np.linalg.norm(before.max(axis=0) - before.min(axis=0))
    assert 0 < moved.max() < 0.005 * diag and np.sqrt(np.mean(moved**2)) < 0.002 * diag
    assert pmwm.read_key(key).scheme == "robust"
    if model == "suzanne":
        assert np.any(sizes == 4)

    # The object itself verifies, with the payload.
    assert bpy.ops.pmwm.verify(key_path=str(key)) == {"FINISHED"}
    assert _verdict(scene) == (True, PAYLOAD)

    # Progressive mesh: every LoD is marked, the finest quarter of the levels gives the exact payload.
    pm_path = tmp_path / "owner.pmwm"
    assert bpy.ops.pmwm.export_pm(filepath=str(pm_path)) == {"FINISHED"}
    pm = pmwm.read_pm(pm_path)
    n_levels = len(pm.level_records)
    for level in sorted({0, n_levels // 2, (3 * n_levels) // 4, n_levels}):
        assert bpy.ops.pmwm.import_pm(filepath=str(pm_path), level=level) == {"FINISHED"}
        imported = bpy.context.active_object
        expected = pm.n_base_vertices + (0 if level == 0 else int(pm.level_records[level - 1]))
        assert len(imported.data.vertices) == expected
        assert imported.pmwm_lod.level == level and imported.pmwm_lod.n_levels == n_levels
        bpy.ops.pmwm.verify(key_path=str(key))
        marked, payload = _verdict(scene)
        assert marked, f"level {level} of {n_levels} not marked"
        if level >= (3 * n_levels) // 4:
            assert payload == PAYLOAD

    # The LoD slider coarsens and refines that object in place (same object, same mesh datablock).
    mesh = imported.data
    imported.pmwm_lod.level = 0
    assert imported.data == mesh and len(mesh.vertices) == pm.n_base_vertices
    imported.pmwm_lod.level = n_levels + 5  # clamped to the finest level
    assert imported.pmwm_lod.level == n_levels and len(mesh.vertices) == pm.n_vertices
    bpy.ops.pmwm.verify(key_path=str(key))
    assert _verdict(scene) == (True, PAYLOAD)

    # Blender's own exporters (axes kept as in Blender), then the pmwm command line: still marked.
    bl.activate(ob)
    obj = tmp_path / "shipped.obj"
    bpy.ops.wm.obj_export(
        filepath=str(obj),
        export_selected_objects=True,
        forward_axis="Y",
        up_axis="Z",
        export_materials=False,
        export_uv=False,
        export_normals=False,
    )
    ply = tmp_path / "shipped.ply"
    bpy.ops.wm.ply_export(
        filepath=str(ply),
        export_selected_objects=True,
        forward_axis="Y",
        up_axis="Z",
        export_normals=False,
        export_uv=False,
        export_colors="NONE",
        ascii_format=False,
    )
    for path in (obj, ply):
        code, data = bl.cli_verify(path, key)
        assert code == 0, f"{path.name}: exit {code}"
        assert data["marked"] and data["payload"] == PAYLOAD


def test_verify_unmarked_object(scene, bl, tmp_path):
    key = tmp_path / "k.json"
    marked = bl.suzanne(levels=2)
    bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=5)
    clean = bl.suzanne(levels=2)  # the same shape, never watermarked
    clean.location.x = 3.0
    assert bpy.context.active_object == clean
    assert bpy.ops.pmwm.verify(key_path=str(key)) == {"FINISHED"}
    v = clean.pmwm_verdict
    assert v.verified and not v.marked and v.payload == "" and v.p_value > 1e-6
    assert not marked.pmwm_verdict.verified  # the verdict is the verified object's only

    ply = tmp_path / "clean.ply"
    bpy.ops.wm.ply_export(
        filepath=str(ply),
        export_selected_objects=True,
        forward_axis="Y",
        up_axis="Z",
        export_normals=False,
        export_uv=False,
        export_colors="NONE",
    )
    code, data = bl.cli_verify(ply, key)
    assert code == 1 and data["marked"] is False
    assert marked.name in bpy.data.objects


def test_modifiers_and_shape_keys_mark_the_base_mesh(scene, bl, tmp_path, capfd):
    ob = bl.suzanne(levels=2)
    ob.modifiers.new("Subdivision", "SUBSURF")
    ob.shape_key_add(name="Basis")
    smile = ob.shape_key_add(name="Smile")
    n = len(ob.data.vertices)
    smile_before = np.empty(3 * n, np.float32)
    smile.data.foreach_get("co", smile_before)
    smile_before = smile_before.reshape(-1, 3) + np.float32(0.01)
    smile.data.foreach_set("co", smile_before.ravel())
    base_before = bl.positions(ob).copy()
    capfd.readouterr()

    key = tmp_path / "k.json"
    assert bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=2) == {"FINISHED"}
    out = capfd.readouterr().out
    assert "Warning" in out and "base mesh" in out
    assert [m.type for m in ob.modifiers] == ["SUBSURF"] and len(ob.data.shape_keys.key_blocks) == 2

    base = bl.positions(ob)
    delta = base - base_before
    basis = np.empty(3 * n, np.float32)
    ob.data.shape_keys.key_blocks["Basis"].data.foreach_get("co", basis)
    assert np.array_equal(basis.reshape(-1, 3), base)
    smile_after = np.empty(3 * n, np.float32)
    smile.data.foreach_get("co", smile_after)
    assert np.allclose(smile_after.reshape(-1, 3) - smile_before, delta, atol=1e-6)
    assert np.any(delta != 0)
    bpy.ops.pmwm.verify(key_path=str(key))
    assert bpy.context.active_object.pmwm_verdict.marked


def test_show_carriers_group_is_temporary(scene, bl, tmp_path, capfd, addon):
    ob = bl.suzanne(levels=2)
    key = tmp_path / "k.json"
    bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=4)
    assert len(ob.vertex_groups) == 0  # off by default: nothing of the key in the object

    carriers = addon.session.lookup(ob).carriers
    scene.pmwm.show_carriers = True
    group = ob.vertex_groups["pmwm_carriers"]
    members = [v.index for v in ob.data.vertices if any(g.group == group.index for g in v.groups)]
    assert sorted(members) == sorted(carriers.tolist())
    assert len(ob.data.vertices) > len(members) > 0
    assert "shar" in capfd.readouterr().out  # the warning about sharing the .blend

    scene.pmwm.show_carriers = False
    assert len(ob.vertex_groups) == 0

    # With the toggle on, watermarking marks the new carriers and warns.
    scene.pmwm.show_carriers = True
    capfd.readouterr()
    bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=9, overwrite_key=True)
    assert "pmwm_carriers" in ob.vertex_groups and "Warning" in capfd.readouterr().out
    scene.pmwm.show_carriers = False
    assert "pmwm_carriers" not in ob.vertex_groups


def test_saved_blend_holds_nothing_of_the_key(scene, bl, tmp_path):
    ob = bl.suzanne(levels=2)
    key = tmp_path / "k.json"
    bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=8)
    secret = json.loads(key.read_text())["secret"]
    blend = tmp_path / "shared.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=False)
    assert secret.encode() not in blend.read_bytes()

    name = ob.name
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    ob = bpy.data.objects[name]
    assert len(ob.vertex_groups) == 0 and not ob.keys() and not ob.data.keys()
    bl.activate(ob)
    # The session memory is gone with the reload: exporting the PM asks for a new watermark.
    with pytest.raises(RuntimeError, match="watermark this object first"):
        bpy.ops.pmwm.export_pm(filepath=str(tmp_path / "x.pmwm"))


def test_undo_restores_positions(scene, bl, tmp_path):
    ob = bl.suzanne(levels=1)
    bpy.ops.ed.undo_push(message="before watermark")
    before = bl.positions(ob).copy()
    # ("EXEC_DEFAULT", True): execute with an undo push, as a click in the panel does.
    bpy.ops.pmwm.watermark("EXEC_DEFAULT", True, payload="Hi", key_path=str(tmp_path / "k.json"), seed=1)
    assert not np.array_equal(bl.positions(ob), before)
    name = ob.name
    bpy.ops.ed.undo()
    ob = bpy.data.objects[name]
    assert np.array_equal(bl.positions(ob), before)
    bl.activate(ob)
    with pytest.raises(RuntimeError, match="watermark this object first"):
        bpy.ops.pmwm.export_pm(filepath=str(tmp_path / "x.pmwm"))


def test_progress_callback_reaches_the_core(scene, bl, tmp_path, monkeypatch):
    import pmwm

    seen = []
    real = pmwm.embed

    def spy(vertices, faces, options=None, progress=None):
        assert callable(progress)

        def record(fraction, message=""):
            seen.append(fraction)
            progress(fraction, message)

        return real(vertices, faces, options, progress=record)

    monkeypatch.setattr(pmwm, "embed", spy)
    bl.suzanne(levels=1)
    bpy.ops.pmwm.watermark(payload="Hi", key_path=str(tmp_path / "k.json"), seed=1)
    assert seen and min(seen) >= 0.0 and max(seen) == 1.0


def test_scene_options_are_the_defaults_of_the_operators(scene, bl, tmp_path):
    """Arguments left out take the panel's Scene options."""
    ob = bl.suzanne(levels=2)
    key = tmp_path / "panel.key.json"
    s = scene.pmwm
    s.payload, s.key_path, s.verify_key_path, s.seed = "Panel owner", str(key), str(key), 3
    assert bpy.ops.pmwm.watermark() == {"FINISHED"}
    assert key.is_file()
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert (ob.pmwm_verdict.marked, ob.pmwm_verdict.payload) == (True, "Panel owner")


def test_scheme_option_selects_the_paper_scheme(scene, bl, tmp_path):
    """Scheme: robust by default; the panel's Scheme (or the operator's argument) selects the paper's."""
    import pmwm

    bl.suzanne(levels=2)
    assert scene.pmwm.scheme == "robust"
    scene.pmwm.scheme = "paper"
    key = tmp_path / "paper.key.json"
    assert bpy.ops.pmwm.watermark(payload="P", key_path=str(key), seed=2) == {"FINISHED"}
    assert pmwm.read_key(key).scheme == "paper"
    assert bpy.ops.pmwm.verify(key_path=str(key)) == {"FINISHED"}
    assert bpy.context.active_object.pmwm_verdict.marked
    key2 = tmp_path / "robust.key.json"
    bl.suzanne(levels=2)
    assert bpy.ops.pmwm.watermark(payload="R", key_path=str(key2), seed=2, scheme="robust") == {"FINISHED"}
    assert pmwm.read_key(key2).scheme == "robust"


def test_watermark_without_the_progressive_mesh_is_the_same_mark(scene, bl, tmp_path):
    """Progressive Mesh off: the very positions of a watermark with it (same seed), read back by Verify;
    only Export Progressive Mesh has nothing to write (its error: test_errors)."""
    with_pm, without = bl.suzanne(levels=1), bl.suzanne(levels=1)
    for ob, flag in ((with_pm, True), (without, False)):
        bl.activate(ob)
        key = tmp_path / f"{ob.name}.key.json"
        assert bpy.ops.pmwm.watermark(payload=PAYLOAD, key_path=str(key), seed=5, progressive=flag) == {"FINISHED"}
    assert np.array_equal(bl.positions(with_pm), bl.positions(without))
    assert bpy.ops.pmwm.verify(key_path=str(tmp_path / f"{without.name}.key.json")) == {"FINISHED"}
    assert _verdict(scene) == (True, PAYLOAD)
