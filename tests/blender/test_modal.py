"""The interface path of Watermark and Verify: the core in a worker thread under a modal operator.

Blender's event loop does not run headless, so the modal steps are driven here as the window manager
would drive them: ``ModalRun.start`` (what invoke does after reading the mesh), then ``step`` with
timer ticks and Esc (what modal receives). Also: the default key path on a saved and an unsaved
.blend, and Save Report.
"""

from __future__ import annotations

import time

import bpy
import numpy as np
import pytest


class Reports:
    """Stands in for Operator.report."""

    def __init__(self):
        self.items = []

    def __call__(self, kind, message):
        self.items.append((next(iter(kind)), message))

    def text(self):
        return " | ".join(m for _, m in self.items)


def _run_to_end(run, context, timeout=300):
    """Timer ticks until the run ends; returns (final status, the fractions seen in the status bar)."""
    seen = []
    deadline = time.monotonic() + timeout
    while True:
        status = run.step(context, "TIMER")
        if status != {"RUNNING_MODAL"}:
            return status, seen
        seen.append(run.status_text)
        assert time.monotonic() < deadline, "the worker did not finish"
        time.sleep(0.02)


@pytest.fixture
def ops(addon):
    return addon.operators


def test_modal_watermark_progress_then_one_write_back(scene, bl, tmp_path, ops, monkeypatch):
    ob = bl.suzanne(levels=2)
    before = bl.positions(ob).copy()
    key = tmp_path / "modal.key.json"
    writes = []
    real_write = ops.meshdata.write_base_positions
    monkeypatch.setattr(
        ops.meshdata, "write_base_positions", lambda mesh, V: (writes.append(len(V)), real_write(mesh, V))
    )

    reports = Reports()
    task = ops.WatermarkTask(bpy.context, payload="Modal", key_path=str(key), seed=4)
    run = ops.ModalRun(task, reports)
    run.start(bpy.context)
    assert run.status_text.startswith("Watermarking 'Suzanne': ") and "Esc to cancel" in run.status_text
    assert addon_busy(ops, ob) == "watermarked"
    # other events pass through while the worker runs: the interface stays usable
    status, seen = run.step(bpy.context, "MOUSEMOVE"), []
    assert status in ({"PASS_THROUGH"}, {"FINISHED"})  # FINISHED only if the worker was already done
    if status == {"PASS_THROUGH"}:
        status, seen = _run_to_end(run, bpy.context)
    assert status == {"FINISHED"}
    assert writes == [len(before)]  # written back once, at the end, on this thread
    assert key.is_file() and not np.array_equal(bl.positions(ob), before)
    assert "Watermarked 'Suzanne'" in reports.text()
    assert run.status_text is None and addon_busy(ops, ob) is None  # status bar cleared
    percents = [int(t.split(": ")[1].split("%")[0]) for t in seen if "%" in t]
    assert percents == sorted(percents)  # the status bar follows the core's progress

    # the result is the one execute gives for the same options
    other = bl.suzanne(levels=2)
    assert bpy.ops.pmwm.watermark(payload="Modal", key_path=str(tmp_path / "sync.key.json"), seed=4) == {"FINISHED"}
    assert np.array_equal(bl.positions(other), bl.positions(ob))


def addon_busy(ops, ob):
    return ops.session.busy(ob)


def test_escape_cancels_the_core_and_leaves_the_object_as_it_was(scene, bl, tmp_path, ops):
    bl.suzanne(levels=2)
    ob = bpy.context.active_object
    key = tmp_path / "cancelled.key.json"
    snap = bl.snapshot(tmp_path)
    reports = Reports()
    run = ops.ModalRun(ops.WatermarkTask(bpy.context, payload="Esc", key_path=str(key), seed=2), reports)
    run.start(bpy.context)
    deadline = time.monotonic() + 60
    while run.job.fraction == 0.0 and not run.job.done:  # wait until the core is under way
        assert time.monotonic() < deadline
        time.sleep(0.005)
    assert run.step(bpy.context, "ESC") == {"CANCELLED"}
    assert run.job.wait(60)
    assert run.job.cancelled and run.job.result is None  # the core unwound at its next progress call
    assert "cancelled: nothing was changed" in reports.text()
    assert bl.snapshot(tmp_path) == snap and not key.exists()
    assert run.status_text is None and ops.session.busy(ob) is None
    with pytest.raises(RuntimeError, match="watermark this object first"):
        bpy.ops.pmwm.export_pm(filepath=str(tmp_path / "x.pmwm"))


def test_an_object_edited_while_the_worker_runs_is_not_overwritten(scene, bl, tmp_path, ops):
    ob = bl.suzanne(levels=1)
    key = tmp_path / "k.json"
    run = ops.ModalRun(ops.WatermarkTask(bpy.context, payload="X", key_path=str(key), seed=1), Reports())
    run.start(bpy.context)
    assert not bpy.ops.pmwm.watermark.poll()  # a second run on the same object waits
    ob.data.vertices[0].co.x += 0.5  # the user moves a vertex meanwhile
    edited = bl.positions(ob).copy()
    with pytest.raises(ops._Failed, match="changed while it was being watermarked: nothing was written"):
        _run_to_end(run, bpy.context)
    assert np.array_equal(bl.positions(ob), edited) and not key.exists()


@pytest.mark.slow
def test_modal_verify_fills_the_verdict_and_a_report_can_be_saved(scene, bl, tmp_path, ops):
    ob = bl.suzanne(levels=2)
    key = tmp_path / "v.key.json"
    bpy.ops.pmwm.watermark(payload="Verified", key_path=str(key), seed=6)
    reports = Reports()
    run = ops.ModalRun(ops.VerifyTask(bpy.context, key_path=str(key)), reports)
    run.start(bpy.context)
    assert run.status_text.startswith("Verifying 'Suzanne': ")
    status, _ = _run_to_end(run, bpy.context)
    assert status == {"FINISHED"} and "'Suzanne' read: MARKED" in reports.text()
    assert (ob.pmwm_verdict.marked, ob.pmwm_verdict.payload) == (True, "Verified")

    report = tmp_path / "suzanne-report.html"
    assert bpy.ops.pmwm.save_report(filepath=str(report)) == {"FINISHED"}
    html = report.read_text()
    assert "MARKED" in html and "Verified" in html and "Blender object &#x27;Suzanne&#x27;" in html
    assert html.count("data:image/png;base64,") == 3
    # the report is refused once the object or the key changed since the verification
    ob.data.vertices[0].co.x += 0.1
    with pytest.raises(RuntimeError, match="changed since it was verified: verify it again"):
        bpy.ops.pmwm.save_report(filepath=str(tmp_path / "again.html"))
    assert not (tmp_path / "again.html").exists()


def test_default_key_path_unsaved_blend_uses_the_key_folder(scene, bl, key_prefs, tmp_path):
    ob = bl.suzanne(levels=1)
    folder = tmp_path / "key-folder"
    assert not bpy.data.filepath and not folder.exists()
    assert scene.pmwm.key_path == ""
    assert bpy.ops.pmwm.watermark(payload="1st", seed=4) == {"FINISHED"}  # no key path set anywhere
    key = folder / "Suzanne.pmwm-key.json"
    assert key.is_file()  # the folder was created for it
    assert bpy.ops.pmwm.verify() == {"FINISHED"}
    assert bpy.context.active_object.pmwm_verdict.marked and bpy.context.active_object.pmwm_verdict.payload == "1st"
    # a second click does not lose the first key
    with pytest.raises(RuntimeError, match="key file exists"):
        bpy.ops.pmwm.watermark(payload="Again", seed=4)
    assert ob.name == "Suzanne"


def test_default_key_folder_without_preferences_is_in_home(scene, bl, addon, tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    bl.suzanne(levels=1)
    assert addon.prefs.key_folder(bpy.context) == str(tmp_path / "pmwm-keys")
    assert bpy.ops.pmwm.watermark(payload="Home", seed=4) == {"FINISHED"}
    assert (tmp_path / "pmwm-keys" / "Suzanne.pmwm-key.json").is_file()


def test_default_key_path_saved_blend_is_beside_it(scene, bl, key_prefs, tmp_path):
    ob = bl.suzanne(levels=1)
    ob.name = "Head / v2"  # not a safe file name
    blend = tmp_path / "project" / "scene.blend"
    blend.parent.mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert bpy.ops.pmwm.watermark(payload="Beside", seed=4) == {"FINISHED"}
    key = blend.parent / "Head_v2.pmwm-key.json"
    assert key.is_file() and not (tmp_path / "key-folder").exists()
    assert bpy.ops.pmwm.verify() == {"FINISHED"} and bpy.context.active_object.pmwm_verdict.payload == "Beside"


def test_invoked_without_an_interface_it_runs_synchronously(scene, bl, tmp_path):
    """A script that invokes the operators in --background gets the result at once, as with execute."""
    assert bpy.app.background
    ob = bl.suzanne(levels=1)
    before = bl.positions(ob).copy()
    key = tmp_path / "invoked.key.json"
    assert bpy.ops.pmwm.watermark("INVOKE_DEFAULT", payload="Inv", key_path=str(key), seed=3) == {"FINISHED"}
    assert key.is_file() and not np.array_equal(bl.positions(ob), before)
    assert bpy.ops.pmwm.verify("INVOKE_DEFAULT", key_path=str(key)) == {"FINISHED"}
    assert bpy.context.active_object.pmwm_verdict.marked and bpy.context.active_object.pmwm_verdict.payload == "Inv"
