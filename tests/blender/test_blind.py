"""The Blind scheme in the add-on: the Pass Phrase field marks and reads, no key file is written, and
the pass phrase never reaches the .blend."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

PHRASE = "tangerine kettle 42"


def _verdict():
    v = bpy.context.active_object.pmwm_verdict
    return v.marked, v.payload


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
    assert _verdict() == (True, "Acme")
    _secrets().passphrase = PHRASE + "?"
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert bpy.context.active_object.pmwm_verdict.marked is False
    # no mark read: no payload either (never bits or a guess in its place)
    ob = bpy.context.active_object
    assert ob.pmwm_verdict.payload == ""
    rows = dict(addon.verdictwords.box_rows(addon.session.lookup_verified(ob).verdict))
    assert rows["Payload read"] == "none read"


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


def test_a_blind_mark_that_does_not_read_back_is_refused_and_changes_nothing(scene, addon, bl):
    """The library checks that the mark reads back before anything is written; its one-line refusal
    reaches the user as the operator's error, and the mesh is left as it was."""
    bl.bunny()
    scene.pmwm.scheme = "blind-histogram"
    _secrets().passphrase = PHRASE
    before = bl.snapshot()
    with pytest.raises(RuntimeError, match="does not read back"):
        bpy.ops.pmwm.watermark(payload="Acme", scheme="blind-histogram", seed=3, blind_margin=0.002)
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


@pytest.mark.slow
def test_the_margin_sets_the_blind_marks_strength(scene, addon, bl):
    """Margin is the Blind (histogram) scheme's own strength: 0 (the default) leaves it to the library, which chooses
    it per mesh (the same marked mesh as ``pmwm.embed`` without a strength); a larger margin moves the
    surface further, and every mark reads back."""
    import pmwm

    assert scene.pmwm.blind_margin == 0.0
    scene.pmwm.scheme = "blind-histogram"
    _secrets().passphrase = PHRASE
    moved = []
    for margin in (0.0, 0.04, 0.2):
        ob = bl.bunny()
        before = bl.positions(ob)
        assert bpy.ops.pmwm.watermark(payload="Acme", scheme="blind-histogram", seed=3, blind_margin=margin) == {
            "FINISHED"
        }
        after = bl.positions(bpy.context.active_object)
        moved.append(float(np.sqrt(np.mean(np.sum((after - before) ** 2, axis=1)))))
        assert bpy.ops.pmwm.verify() == {"FINISHED"}
        assert _verdict() == (True, "Acme")
        if margin == 0.0:
            lib = pmwm.embed(
                before.astype(np.float64),
                bl.polygons(bpy.context.active_object)[0].reshape(-1, 3),
                pmwm.EmbedOptions(payload="Acme", scheme="blind-histogram", seed=3, passphrase=PHRASE),
            )
            np.testing.assert_array_equal(after, lib.vertices.astype(np.float32))
    assert moved[2] > 2 * moved[1] > 0


_SMALL: dict = {}


def _small_marked():
    """The bundled bunny coarsened to 14,000 vertices, marked (Blind (histogram), "Acme"): a mesh small enough that one
    step of subdivision smooths the mark out of its own reading."""
    import pmwm
    from pmwm.progressive import build_progressive_mesh

    if "res" not in _SMALL:
        src = pmwm.read_mesh(str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
        pm, _ = build_progressive_mesh(src.vertices, src.faces, base_vertices=3000)
        _SMALL["res"] = pmwm.embed(
            *pm.decode(vertices=14000),
            pmwm.EmbedOptions(scheme="blind-histogram", payload="Acme", passphrase=PHRASE, seed=3, progressive=False),
        )
    return _SMALL["res"]


def _verify_report(addon, scene) -> str:
    """Run Verify's task on the active object (Blind, PHRASE) and return its report text."""
    from .test_modal import Reports

    scene.pmwm.scheme = "blind"
    _secrets().passphrase = PHRASE
    task = addon.operators.VerifyTask(bpy.context)
    reports = Reports()
    task.finish(bpy.context, task.compute(lambda fraction, message: None), reports)
    return reports.text()


def test_verify_reads_a_subdivided_copy_and_says_so(scene, addon, bl):
    """A copy subdivided once by Loop's scheme (the bunny coarsened to 14,000 vertices, marked): Verify
    reads the payload on the mesh it was subdivided from and the report says so."""
    from pmwm import attacks

    res = _small_marked()
    bl.new_object("copy", *attacks.subdivide(res.vertices, res.faces, "loop"))
    text = _verify_report(addon, scene)
    assert _verdict() == (True, "Acme")
    assert "subdivided from: loop undone" in text


@pytest.mark.parametrize("limit", [True, False], ids=["limit-surface", "plain"])
@pytest.mark.slow
def test_verify_reads_a_copy_given_blenders_subdivision_surface(scene, addon, bl, limit):
    """Blender's own subdivision: the Subdivision Surface modifier (Catmull-Clark, one level; its default
    places the vertices on the limit surface) applied to the marked bundled bunny turns every triangle
    into three quads, and Blender's triangulation splits a few of them the other way (concave ones).
    Verify reads the payload on the mesh it was made from, and says so."""
    import pmwm

    src = pmwm.read_mesh(str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
    res = pmwm.embed(
        src.vertices,
        src.faces,
        pmwm.EmbedOptions(scheme="blind-histogram", payload="Acme", passphrase=PHRASE, seed=3, progressive=False),
    )
    ob = bl.new_object("copy", res.vertices, res.faces)
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.use_limit_surface = 1, limit
    assert bpy.ops.object.modifier_apply(modifier=mod.name) == {"FINISHED"}
    assert len(ob.data.polygons) == 3 * len(res.faces)
    tris = addon.meshdata.read_triangles(ob.data)
    assert np.any(np.bincount(tris.ravel()) % 2 == 1)  # some quads split (e, e'), not from their corner
    text = _verify_report(addon, scene)
    assert _verdict() == (True, "Acme")
    assert "subdivided from: catmull-clark undone" in text


@pytest.mark.parametrize("kind,levels", [("SIMPLE", 1), ("CATMULL_CLARK", 2)], ids=["simple", "two-levels"])
@pytest.mark.slow
def test_verify_reads_a_copy_given_simple_or_two_levels_of_subdivision_surface(scene, addon, bl, kind, levels):
    """The Subdivision Surface modifier's other uses: Simple (the Catmull-Clark quads, the new vertices
    left on the flat faces) and two levels (Ctrl+2: the second level splits every quad in four). Two
    levels take the payload out of a 14,000-vertex mesh's own reading (9 check bits wrong, measured);
    Verify reads it on the mesh under it, each level undone in turn, and says so (Simple's copy still
    holds it in its own reading, and is read on the mesh under it as well)."""
    res = _small_marked()
    ob = bl.new_object("copy", res.vertices, res.faces)
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.subdivision_type, mod.levels = kind, levels
    assert bpy.ops.object.modifier_apply(modifier=mod.name) == {"FINISHED"}
    assert len(ob.data.polygons) == 3 * 4 ** (levels - 1) * len(res.faces)
    text = _verify_report(addon, scene)
    assert _verdict() == (True, "Acme")
    assert "subdivided from: catmull-clark" in text


def test_verify_reads_a_copy_given_blenders_smooth_modifier(scene, addon, bl):
    """Blender's Smooth modifier (factor 0.5, repeated 6 times: each a step of lambda 0.25 towards the
    neighbours' mean) blurs the mark out of the copy's own reading; Verify takes the steps back (the
    reader's ``unsmoothing``) and reads the payload, and says so."""
    from pmwm.schemes import blind

    res = _small_marked()
    ob = bl.new_object("copy", res.vertices, res.faces)
    mod = ob.modifiers.new("Smooth", "SMOOTH")
    mod.factor, mod.iterations = 0.5, 6
    assert bpy.ops.object.modifier_apply(modifier=mod.name) == {"FINISHED"}
    text = _verify_report(addon, scene)
    assert _verdict() == (True, "Acme")
    assert "steps of Laplacian smoothing (0.1 each) undone" in text
    V, F = addon.meshdata.read_positions(ob.data), addon.meshdata.read_triangles(ob.data)
    plain = blind.verify(V, F, PHRASE, config=blind.READER.without("unsmoothed"))
    assert not (plain.marked and plain.payload == "Acme")


@pytest.mark.slow
def test_the_catmull_clark_attack_is_blenders_subdivision_surface(scene, bl):
    """``attacks.subdivide(..., "catmull-clark")``, which the benchmarks and the library's tests use, makes
    what the modifier makes (one level, no limit surface), boundary included: the same positions (to
    float32) and the same triangles once Blender's quads are split from their corner, up to the order of
    the edge points."""
    import pmwm
    from pmwm import attacks
    from scipy.spatial import cKDTree

    src = pmwm.read_mesh(str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
    V, F = attacks.crop_plane(src.vertices, src.faces, fraction=0.2, seed=1)  # with a boundary
    ob = bl.new_object("cut", V, F)
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.use_limit_surface = 1, False
    assert bpy.ops.object.modifier_apply(modifier=mod.name) == {"FINISHED"}
    loops, sizes = bl.polygons(ob)
    assert np.all(sizes == 4)
    quads = loops.reshape(-1, 4)
    got_v = bl.positions(ob).astype(np.float64)
    want_v, want_f = attacks.subdivide(V, F, "catmull-clark")
    assert len(got_v) == len(want_v)
    dist, index = cKDTree(want_v).query(got_v)  # Blender's vertex -> ours
    assert dist.max() < 1e-5 * np.ptp(V, axis=0).max() and len(np.unique(index)) == len(want_v)
    got_f = index[np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])]

    def oriented(T):
        k = np.argmin(T, axis=1)[:, None]
        return set(map(tuple, np.take_along_axis(T, (k + np.arange(3)) % 3, axis=1).tolist()))

    assert oriented(got_f) == oriented(want_f)


def test_blind_reads_a_copy_smoothed_and_the_report_says_so(scene, addon, bl):
    """Keyed waves (the Blind scheme's default): a copy smoothed by 5 uniform Laplacian steps reads, and
    Verify's report says the smoothing was undone."""
    import pmwm
    from pmwm import attacks

    src = pmwm.read_mesh(str(Path(pmwm.__file__).parent / "data" / "bunny.off"))
    res = pmwm.embed(
        src.vertices,
        src.faces,
        pmwm.EmbedOptions(scheme="blind", payload="Acme", passphrase=PHRASE, seed=3, progressive=False),
    )
    bl.new_object("copy", *attacks.smooth_laplacian(res.vertices, res.faces, lam=0.5, iterations=5))
    text = _verify_report(addon, scene)
    assert _verdict() == (True, "Acme")
    assert "uniform Laplacian smoothing" in text and "undone" in text


def test_a_mesh_keyed_waves_cannot_mark_is_marked_by_the_baseline_with_a_warning(scene, addon, bl):
    """A flat sheet bounds no solid: the Blind scheme marks it with its baseline carrier and says so."""
    from .test_modal import Reports

    n = 60
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    bl.new_object("sheet", np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1), faces)
    scene.pmwm.scheme = "blind"
    _secrets().passphrase = PHRASE
    task = addon.operators.WatermarkTask(bpy.context, payload="CAP", scheme="blind", seed=3)
    reports = Reports()
    task.finish(bpy.context, task.compute(lambda fraction, message: None), reports)
    assert "baseline histogram carrier" in reports.text() and "bounds no volume" in reports.text()
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert _verdict() == (True, "CAP")
