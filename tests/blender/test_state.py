"""What the panel shows follows the active object: its verdict or none, Save Report only for a verdict
that can be reported, file names for it; files are never replaced unless asked; the sequence that once
crashed Blender; separate key paths for marking and verifying; Save Report and the progress lines of
the background runs; Publish for Web."""

from __future__ import annotations

import time

import bpy
import pytest

from .test_modal import Reports, _run_to_end
from .test_panel import _poll_reason, _squeeze, _text, draw

PHRASE = "tangerine kettle 42"


@pytest.fixture
def ops(addon):
    return addon.operators


def _verdict_text(addon) -> str:
    return _text(draw(addon, "VIEW3D_PT_pmwm_verify"))


def _marked_pair(bl, tmp_path):
    """Two marked objects, each with its own key: (a, key_a, b, key_b); b is active."""
    a = bl.suzanne(levels=2)
    a.name = "Alpha"
    key_a = tmp_path / "alpha.key.json"
    assert bpy.ops.pmwm.watermark(payload="Alpha owner", key_path=str(key_a), seed=1) == {"FINISHED"}
    b = bl.suzanne(levels=2)
    b.name = "Beta"
    key_b = tmp_path / "beta.key.json"
    assert bpy.ops.pmwm.watermark(payload="Beta owner", key_path=str(key_b), seed=2) == {"FINISHED"}
    return a, key_a, b, key_b


def test_the_verdict_shown_is_the_active_objects_or_none(scene, addon, bl, tmp_path):
    a, key_a, b, key_b = _marked_pair(bl, tmp_path)
    bl.activate(a)
    assert bpy.ops.pmwm.verify(key_path=str(key_a)) == {"FINISHED"}
    assert _squeeze("Alpha: MARKED") in _verdict_text(addon)
    bl.activate(b)  # not verified yet: no verdict at all, not Alpha's
    text = _verdict_text(addon)
    assert "MARKED" not in text and "Alpha" not in text and "Payload" not in text
    assert "was not verified" in _poll_reason("save_report")
    assert bpy.ops.pmwm.verify(key_path=str(key_a)) == {"FINISHED"}  # Beta with Alpha's key: not marked
    assert _squeeze("Beta: not marked") in _verdict_text(addon)
    assert _squeeze("Payload read: none read") in _verdict_text(addon)  # no bits in its place
    bl.activate(a)
    assert _squeeze("Payload read: 'Alpha owner'") in _verdict_text(addon)
    a.data.vertices[0].co.x += 0.25  # edited since: the verdict says so, the report is refused
    assert _squeeze("Changed since this verdict: verify again") in _verdict_text(addon)
    assert "changed since it was verified: verify it again" in _poll_reason("save_report")
    # a large mesh is checked on samples at each redraw (every vertex before anything is written)
    addon.session.WHOLE = 10
    try:
        assert _squeeze("Changed since this verdict") in _verdict_text(addon)
        a.data.vertices[0].co.x -= 0.25
        assert _squeeze("Changed since this verdict") not in _verdict_text(addon)
        assert _poll_reason("save_report") is None
    finally:
        addon.session.WHOLE = 50_000
    a.data.vertices[0].co.x += 0.25
    # the scripting record is per object too
    assert (a.pmwm_verdict.marked, a.pmwm_verdict.payload) == (True, "Alpha owner")
    assert (b.pmwm_verdict.marked, b.pmwm_verdict.payload) == (False, "")


def test_save_report_only_for_a_verdict_that_can_be_reported(scene, addon, bl, tmp_path, window_manager_phrase):
    ob = bl.bunny()
    assert "was not verified in this session" in _poll_reason("save_report")
    scene.pmwm.scheme = "blind"
    assert bpy.ops.pmwm.watermark(payload="Acme", scheme="blind", seed=3) == {"FINISHED"}
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert ob.pmwm_verdict.marked
    assert "read with the pass phrase: a report needs a key file" in _poll_reason("save_report")
    # a key verdict can be reported until the object changes
    ob2 = bl.suzanne(levels=2)
    key = tmp_path / "k.json"
    scene.pmwm.scheme = "robust"
    assert bpy.ops.pmwm.watermark(payload="Key", key_path=str(key), seed=1) == {"FINISHED"}
    assert bpy.ops.pmwm.verify(key_path=str(key)) == {"FINISHED"}
    assert _poll_reason("save_report") is None
    ob2.data.vertices[5].co.z -= 0.5
    assert "changed since it was verified" in _poll_reason("save_report")


@pytest.fixture
def window_manager_phrase():
    secrets = bpy.context.window_manager.pmwm_secrets
    secrets.passphrase = PHRASE
    yield PHRASE
    secrets.passphrase = ""


def test_the_sequence_that_crashed(scene, addon, bl, tmp_path, ops, window_manager_phrase):
    """Verify Robust; mark and verify Blind; Save Report twice: refused twice with the reason, nothing
    written, Blender alive; the modal path refuses the same way."""
    ob = bl.bunny()
    key = tmp_path / "robust.key.json"
    assert bpy.ops.pmwm.watermark(payload="First", key_path=str(key), seed=4) == {"FINISHED"}
    assert bpy.ops.pmwm.verify(key_path=str(key)) == {"FINISHED"}
    assert _poll_reason("save_report") is None
    scene.pmwm.scheme = "blind"
    assert bpy.ops.pmwm.watermark(payload="Second", scheme="blind", seed=5) == {"FINISHED"}
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    report = tmp_path / "bunny.pmwm-report.html"
    for _ in range(2):
        assert not bpy.ops.pmwm.save_report.poll()
        with pytest.raises(RuntimeError, match="read with the pass phrase: a report needs a key file"):
            bpy.ops.pmwm.save_report(filepath=str(report))
        with pytest.raises(ops._Failed, match="read with the pass phrase"):
            ops.ReportTask(bpy.context, str(report))
    assert not report.exists()
    assert ob.pmwm_verdict.marked and _squeeze(f"{ob.name}: MARKED") in _verdict_text(addon)


def test_an_existing_report_is_never_replaced_unless_asked(scene, addon, bl, tmp_path, ops):
    ob = bl.suzanne(levels=2)
    key = tmp_path / "k.json"
    bpy.ops.pmwm.watermark(payload="Owner", key_path=str(key), seed=1)
    bpy.ops.pmwm.verify(key_path=str(key))
    report = tmp_path / "other object.pmwm-report.html"
    report.write_text("another object's report")
    with pytest.raises(RuntimeError, match="exists: tick Replace Existing in the file browser"):
        bpy.ops.pmwm.save_report(filepath=str(report))
    assert report.read_text() == "another object's report"
    # the background path refuses too, before drawing anything
    with pytest.raises(ops._Failed, match="exists: tick Replace Existing"):
        ops.ReportTask(bpy.context, str(report))
    assert bpy.ops.pmwm.save_report(filepath=str(report), overwrite=True) == {"FINISHED"}
    assert "MARKED" in report.read_text() and ob.name in report.read_text()
    # as after the file browser (no window here: it runs at once, as from a script)
    again = tmp_path / "again.html"
    assert bpy.ops.pmwm.save_report(filepath=str(again), chosen=True) == {"FINISHED"} and again.is_file()
    # the same for Export Progressive Mesh
    pm = tmp_path / "m.pmwm"
    pm.write_bytes(b"keep")
    with pytest.raises(RuntimeError, match="exists: tick Replace Existing"):
        bpy.ops.pmwm.export_pm(filepath=str(pm))
    assert pm.read_bytes() == b"keep"
    assert bpy.ops.pmwm.export_pm(filepath=str(pm), overwrite=True) == {"FINISHED"}
    assert pm.read_bytes() != b"keep"


def test_default_file_names_follow_the_active_object(scene, addon, bl, tmp_path, ops):
    a = bl.suzanne(levels=0)
    a.name = "Head / v2"
    ctx = bpy.context
    # unsaved .blend: the bare name, in the file browser's current folder
    assert ops.default_file(ctx, a, ".pmwm") == "Head_v2.pmwm"
    blend = tmp_path / "project" / "scene.blend"
    blend.parent.mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    a = bpy.data.objects["Head / v2"]
    folder = blend.parent
    assert ops.default_file(ctx, a, ".pmwm") == str(folder / "Head_v2.pmwm")
    assert ops.default_file(ctx, a, ".pmwm-report.html") == str(folder / "Head_v2.pmwm-report.html")
    assert ops.default_file(ctx, a, "-web") == str(folder / "Head_v2-web")
    (folder / "Head_v2.pmwm-report.html").write_text("taken")
    assert ops.default_file(ctx, a, ".pmwm-report.html") == str(folder / "Head_v2-2.pmwm-report.html")
    b = bl.suzanne(levels=0)
    b.name = "Tail"
    assert ops.default_file(ctx, b, ".pmwm-report.html") == str(folder / "Tail.pmwm-report.html")
    # the path is not kept from one use to the next (it would name the previous object)
    for op in ("save_report", "export_pm", "publish_web"):
        rna = getattr(bpy.ops.pmwm, op).get_rna_type()
        assert rna.properties["filepath"].is_skip_save, op
        assert rna.properties["overwrite"].is_skip_save and not rna.properties["overwrite"].default, op


def test_separate_key_paths_for_marking_and_verifying(scene, addon, bl, key_prefs, tmp_path):
    s = scene.pmwm
    ob = bl.suzanne(levels=2)
    mark_key = tmp_path / "new.key.json"
    s.key_path = str(mark_key)
    assert bpy.ops.pmwm.watermark(payload="Mine", seed=1) == {"FINISHED"}
    assert mark_key.is_file()
    # verifying another object with a key typed in Verification leaves the Mark key alone
    other = bl.suzanne(levels=2)
    s.verify_key_path = str(mark_key)
    assert bpy.ops.pmwm.verify() == {"FINISHED"} and not other.pmwm_verdict.marked
    assert s.key_path == str(mark_key)
    # an empty Verification key is the object's own key (the default of its watermark)
    s.verify_key_path = ""
    s.key_path = ""
    bl.activate(ob)
    with pytest.raises(RuntimeError, match=r"key file not found: .*Suzanne.pmwm-key.json"):
        bpy.ops.pmwm.verify()
    third = bl.suzanne(levels=2)
    assert bpy.ops.pmwm.watermark(payload="Default", seed=1) == {"FINISHED"}
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert (third.pmwm_verdict.marked, third.pmwm_verdict.payload) == (True, "Default")
    assert s.key_path == "" and s.verify_key_path == ""


def test_the_blind_runs_read_no_key_path(addon, ops):
    """The redo panel and the run read only the options of the scheme that runs."""
    blind = ops.PMWM_OT_watermark.options_for("blind")
    robust = ops.PMWM_OT_watermark.options_for("robust")
    assert "key_path" not in blind and "overwrite_key" not in blind and "blind_margin" in blind
    assert "key_path" in robust and "blind_margin" not in robust


def test_blind_mark_reports_no_carrier_count(scene, addon, bl, ops, window_manager_phrase):
    bl.bunny()
    scene.pmwm.scheme = "blind"
    reports = Reports()
    run = ops.ModalRun(ops.WatermarkTask(bpy.context, payload="Acme", scheme="blind", seed=3), reports)
    run.start(bpy.context)
    status, _ = _run_to_end(run, bpy.context)
    assert status == {"FINISHED"}
    assert "Watermarked 'bunny': " in reports.text() and "carriers" not in reports.text()


def test_save_report_runs_in_the_background_with_moving_progress(scene, addon, bl, tmp_path, ops, monkeypatch):
    import threading

    from pmwm import verify_report

    ob = bl.bunny()
    key = tmp_path / "k.json"
    bpy.ops.pmwm.watermark(payload="Owner", key_path=str(key), seed=1)
    bpy.ops.pmwm.verify(key_path=str(key))
    # the report's drawing waits for the test's go, so that the run is caught under way
    go = threading.Event()
    real = verify_report.build_report
    monkeypatch.setattr(verify_report, "build_report", lambda *a, **k: (go.wait(120), real(*a, **k))[1])
    report = tmp_path / "bunny.pmwm-report.html"
    reports = Reports()
    run = ops.ModalRun(ops.ReportTask(bpy.context, str(report)), reports)
    run.start(bpy.context)
    assert run.status_text.startswith("Saving the report of 'bunny': ") and "Esc to cancel" in run.status_text
    assert not bpy.ops.pmwm.watermark.poll()  # the object is busy meanwhile
    run.job.started_at -= 7.0  # the seconds shown move while the stage reports nothing
    assert run.step(bpy.context, "TIMER") == {"RUNNING_MODAL"}
    assert run.status_text.endswith(", 7 s (Esc to cancel)"), run.status_text
    assert addon.session.progress(ob) == "0%, drawing the pictures, 7 s"
    assert _squeeze("Saving the report: 0%, drawing the pictures, 7 s") in _text(draw(addon, "VIEW3D_PT_pmwm"))
    go.set()
    status, seen = _run_to_end(run, bpy.context)
    assert status == {"FINISHED"} and report.is_file() and "MARKED" in report.read_text()
    # the percentage moves while the pictures are drawn, view by view, and never goes back
    percents = [int(t.split(": ")[1].split("%")[0]) for t in seen]
    assert percents == sorted(percents) and len(set(percents)) >= 4 and max(percents) > 50, seen
    assert any("drawing the front view" in t for t in seen) and any("drawing the oblique view" in t for t in seen)
    assert f"Report on 'bunny' written to {report}" in reports.text()
    assert addon.session.busy(ob) is None and addon.session.progress(ob) == ""
    # Esc: nothing written
    go.clear()
    other = tmp_path / "cancelled.html"
    run = ops.ModalRun(ops.ReportTask(bpy.context, str(other)), Reports())
    run.start(bpy.context)
    assert run.step(bpy.context, "ESC") == {"CANCELLED"}
    go.set()
    assert run.job.wait(120)
    assert run.step(bpy.context, "TIMER") == {"CANCELLED"}
    assert not other.exists() and addon.session.busy(ob) is None


def test_watermark_progress_shows_the_stage_and_the_seconds(scene, addon, bl, tmp_path, ops):
    ob = bl.suzanne(levels=2)
    run = ops.ModalRun(
        ops.WatermarkTask(bpy.context, payload="P", key_path=str(tmp_path / "k.json"), seed=1), Reports()
    )
    run.job.fraction, run.job.message = 0.35, "building the progressive mesh"
    run.job.started_at = time.monotonic() - 12.2
    assert run.progress_text() == "35%, building the progressive mesh, 12 s"
    run.start(bpy.context)
    assert "%" in addon.session.progress(ob) and addon.session.progress(ob).endswith(" s")
    status, seen = _run_to_end(run, bpy.context)
    assert status == {"FINISHED"} and addon.session.progress(ob) == ""
    assert all(t.endswith(" s (Esc to cancel)") for t in seen)


def test_publish_for_web_writes_the_active_objects_site(scene, addon, bl, tmp_path):
    """Publish for Web writes pmwm.viewer's page of the active object's last progressive mesh, named for the
    object, and never replaces a folder in use unless asked."""
    import pmwm
    from pmwm.progressive import to_bytes

    ob = bl.suzanne(levels=2)
    assert "was not watermarked in this session" in _poll_reason("publish_web")
    bpy.ops.pmwm.watermark(payload="Web", key_path=str(tmp_path / "k.json"), seed=1)
    site = tmp_path / "Suzanne-web"
    assert bpy.ops.pmwm.publish_web(filepath=str(site)) == {"FINISHED"}
    assert {"index.html", "viewer.js", "model.pmwm"} <= {f.name for f in site.iterdir()}
    assert "Suzanne" in (site / "index.html").read_text(encoding="utf-8")
    assert (site / "model.pmwm").read_bytes() == to_bytes(addon.session.lookup(ob).pm)
    assert pmwm.read_pm(site / "model.pmwm").n_vertices == len(ob.data.vertices)
    # a folder with something in it is not replaced unless asked
    before = (site / "index.html").stat().st_mtime_ns
    with pytest.raises(RuntimeError, match="exists and is not empty: tick Replace Existing"):
        bpy.ops.pmwm.publish_web(filepath=str(site))
    assert (site / "index.html").stat().st_mtime_ns == before
    assert bpy.ops.pmwm.publish_web(filepath=str(site) + "/", overwrite=True) == {"FINISHED"}
