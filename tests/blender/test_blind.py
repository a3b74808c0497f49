"""The Blind scheme in the add-on: the Pass Phrase field marks and reads, no key file is written, and
the pass phrase never reaches the .blend."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

PHRASE = "tangerine kettle 42"


def _secrets():
    return bpy.context.window_manager.pmwm_secrets


def test_blind_watermark_and_verify_with_the_pass_phrase(scene, addon, bl, key_prefs, tmp_path):
    bl.bunny()
    scene.pmwm.scheme = "blind"
    _secrets().passphrase = PHRASE
    assert bpy.ops.pmwm.watermark(payload="Acme", scheme="blind", seed=3) == {"FINISHED"}
    folder = tmp_path / "key-folder"
    assert not folder.exists() or not any(folder.iterdir())  # no key file anywhere
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert (scene.pmwm.verdict_marked, scene.pmwm.verdict_payload) == (True, "Acme")
    _secrets().passphrase = PHRASE + "?"
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert scene.pmwm.verdict_marked is False


def test_blind_without_a_pass_phrase_is_a_clear_error(scene, addon, bl):
    bl.new_object("tet", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])
    scene.pmwm.scheme = "blind"
    _secrets().passphrase = ""
    before = bl.snapshot()
    with pytest.raises(RuntimeError, match="needs a Pass Phrase"):
        bpy.ops.pmwm.watermark(scheme="blind")
    with pytest.raises(RuntimeError, match="needs a Pass Phrase"):
        bpy.ops.pmwm.verify()
    assert bl.snapshot() == before


def test_the_pass_phrase_is_never_saved_in_the_blend(scene, addon, bl, tmp_path):
    scene.pmwm.scheme = "blind"
    _secrets().passphrase = PHRASE
    path = tmp_path / "scene.blend"
    assert bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False) == {"FINISHED"}
    assert PHRASE.encode() not in path.read_bytes()
    assert _secrets().passphrase == PHRASE  # still there in this session
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert _secrets().passphrase == ""
    assert bpy.context.scene.pmwm.scheme == "blind"


def test_the_margin_sets_the_blind_marks_strength(scene, addon, bl):
    """Margin is the Blind scheme's own strength: 0 (the default) leaves it to the library, which chooses
    it per mesh (the same marked mesh as ``pmwm.embed`` without a strength); a larger margin moves the
    surface further, and every mark reads back."""
    import pmwm

    assert scene.pmwm.blind_margin == 0.0
    scene.pmwm.scheme = "blind"
    _secrets().passphrase = PHRASE
    moved = []
    for margin in (0.0, 0.04, 0.2):
        ob = bl.bunny()
        before = bl.positions(ob)
        assert bpy.ops.pmwm.watermark(payload="Acme", scheme="blind", seed=3, blind_margin=margin) == {"FINISHED"}
        after = bl.positions(bpy.context.active_object)
        moved.append(float(np.sqrt(np.mean(np.sum((after - before) ** 2, axis=1)))))
        assert bpy.ops.pmwm.verify() == {"FINISHED"}
        assert (scene.pmwm.verdict_marked, scene.pmwm.verdict_payload) == (True, "Acme")
        if margin == 0.0:
            lib = pmwm.embed(before.astype(np.float64), bl.polygons(bpy.context.active_object)[0].reshape(-1, 3),
                             pmwm.EmbedOptions(payload="Acme", scheme="blind", seed=3, passphrase=PHRASE))
            np.testing.assert_array_equal(after, lib.vertices.astype(np.float32))
    assert moved[2] > 2 * moved[1] > 0


def test_verify_reads_a_subdivided_copy_and_says_so(scene, addon, bl):
    """A copy subdivided once by Loop's scheme (the bunny coarsened to 14,000 vertices, marked): Verify
    reads the payload on the mesh it was subdivided from and the report says so."""
    import pmwm
    from pmwm import attacks
    from pmwm.progressive import build_progressive_mesh

    from .test_modal import Reports

    src = pmwm.read_mesh(str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
    pm, _ = build_progressive_mesh(src.vertices, src.faces, base_vertices=3000)
    res = pmwm.embed(*pm.decode(vertices=14000), pmwm.EmbedOptions(scheme="blind", payload="Acme", passphrase=PHRASE,
                                                                    seed=3, progressive=False))
    bl.new_object("copy", *attacks.subdivide(res.vertices, res.faces, "loop"))
    scene.pmwm.scheme = "blind"
    _secrets().passphrase = PHRASE
    task = addon.operators.VerifyTask(bpy.context)
    reports = Reports()
    task.finish(bpy.context, task.compute(lambda fraction, message: None), reports)
    assert (scene.pmwm.verdict_marked, scene.pmwm.verdict_payload) == (True, "Acme")
    assert "subdivided from: loop undone" in reports.text()
