"""Every text of the panels fits the sidebar, measured with Blender's font metrics (blf, the interface
font at the interface scale) against the room Blender's layout leaves at a region width.

Headless bpy has no window, so the panels draw into the recording layout of test_panel.py with a
region of the width under test; each label, property name, drop-down choice and button text is then
measured with blf.dimensions. The room left by Blender's margins (``textfit.Room``) is checked first
against what a real Blender 4.2 window at the default sidebar width showed whole and what it cut.
"""

from __future__ import annotations

import bpy
import pytest

from .test_panel import draw

# Widths in pixels at scale 1: Blender 4.2's default sidebar (UI_SIDEBAR_PANEL_WIDTH 220), the wider
# default of later versions (280), a compact width (160) and a narrow one (120). Blender lets the
# sidebar shrink to one widget unit (20 px) before hiding it: no word fits there.
WIDTHS = (220, 280, 160, 120)


@pytest.fixture
def textfit(addon):
    return addon.textfit


def test_the_room_model_cuts_where_a_real_window_cut(textfit):
    """At the default width a Blender 4.2 window showed these texts whole or cut them ("..." marks
    the cut, as Blender draws it)."""
    room = textfit.Room(220)
    boxed = room.boxed()
    whole = [
        (room.label(), "Higher: more robust, more vis..."),
        (room.label(icon=True), "Key: bunny.pmwm-key.js..."),
        (room.split_name(), "Progressive ..."),
        (boxed.split_name(), "Level of ..."),
        (boxed.label(icon=True), "Stream preview: bunny..."),
        (room.label(icon=True), "Being watermarked: Esc ..."),
    ]
    cut = [
        (room.label(), "Higher: more robust, more visible"),
        (room.label(icon=True), "Key: bunny.pmwm-key.json"),
        (room.split_name(), "Progressive Mesh"),
        (boxed.split_name(), "Level of Detail"),
        (boxed.label(icon=True), "Stream preview: bunny.pmwm"),
        (room.label(icon=True), "No key file: the pass phrase reads the mark"),
    ]
    assert all(textfit.text_width(t) <= r for r, t in whole), [(r, t, textfit.text_width(t)) for r, t in whole]
    assert all(textfit.text_width(t) > r for r, t in cut), [(r, t, textfit.text_width(t)) for r, t in cut]


def test_wrap_keeps_every_word_and_fits(textfit):
    text = "No key file: the pass phrase reads the mark in /a/very/long/folder/name/that/cannot/fit/anywhere.json"
    for room in (60.0, 100.0, 170.0):
        lines = textfit.wrap(text, room)
        assert all(textfit.text_width(line) <= room for line in lines)
        assert "".join(lines).replace(" ", "") == text.replace(" ", "")
    assert textfit.wrap("short", 170.0) == ["short"]


def _too_wide(log, textfit, width):
    """The drawn texts that do not fit their room: (what, text, its width, the room)."""
    bad = []
    for kind, _name, _enabled, kw, (boxes, split) in log:
        room = textfit.Room(width)
        for _ in range(boxes):
            room = room.boxed()
        checks = []
        if kind == "label":
            checks.append((_name, room.label(kw["icon"] != "NONE")))
        elif kind == "prop":
            if split:
                checks.append((kw["text"], room.split_name()))
                checks.append((kw["value"], room.field()))
            elif kw["boolean"]:  # a checkbox, its name right of it
                checks.append((kw["text"], room.label(icon=True)))
            else:  # a field the full width, its name on the line above
                assert kw["text"] == "", (kw["text"], "a name inside a full-width field")
                checks.append((kw["value"], room.field(split=False)))
        elif kind == "operator":
            icon = kw["icon"] != "NONE"
            checks.append((kw["text"], room.field(split=False) - (textfit.ICON if icon else 0)))
        for text, limit in checks:
            if text and textfit.text_width(text) > limit:
                bad.append((kind, text, textfit.text_width(text), round(limit, 1)))
    return bad


def _states(scene, bl, addon, tmp_path):
    """The panel in each state a user meets: yields a description once the state is set up."""
    yield "no object"
    ob = bl.suzanne(levels=2)
    ob.name = "Suzanne with a rather long name.001"
    yield "a mesh, Robust, the default key in a long key folder"
    scene.pmwm.key_path = str(tmp_path / "keys for the client project" / "suzanne-final-version-2.pmwm-key.json")
    yield "a key path chosen"
    scene.pmwm.scheme = "blind"
    yield "Blind"
    scene.pmwm.scheme = "robust"
    key = tmp_path / "k.json"
    bpy.ops.pmwm.watermark(payload="ACME Studio 2026", key_path=str(key), seed=3)
    bpy.ops.pmwm.verify(key_path=str(key))
    scene.pmwm.show_carriers = True
    yield "marked, verified, carriers shown"
    scene.pmwm.show_carriers = False
    ob.data.vertices[0].co.x += 0.01
    yield "changed since verified"
    pm = tmp_path / "a progressive mesh with a long file name.pmwm"
    ob.data.vertices[0].co.x -= 0.01
    bpy.ops.pmwm.export_pm(filepath=str(pm))
    bpy.ops.pmwm.import_pm(filepath=str(pm), level=1)
    yield "an imported progressive mesh"
    addon.session.set_busy(bpy.context.active_object.as_pointer(), "watermarked")
    addon.session.set_progress(bpy.context.active_object.as_pointer(), "35%, building the progressive mesh, 12 s")
    yield "being watermarked"
    addon.session.set_busy(bpy.context.active_object.as_pointer(), None)


def test_every_text_fits_the_sidebar(scene, addon, bl, key_prefs, tmp_path, textfit):
    key_prefs.key_folder = str(tmp_path / "a key folder with a long name" / "pmwm keys")
    bad = {}
    for state in _states(scene, bl, addon, tmp_path):
        for width in WIDTHS:
            too_wide = _too_wide(draw(addon, width=width), textfit, width)
            if too_wide:
                bad[(state, width)] = too_wide
    assert not bad, bad


def test_the_texts_follow_the_interface_scale(scene, addon, bl, textfit):
    """At twice the scale the text is about twice as wide (hinting aside) and so is the region: the same
    words in about as many lines; the same region at twice the scale takes more lines."""
    bl.suzanne(levels=0)
    at1 = [e[1] for e in draw(addon, width=220) if e[0] == "label"]
    prefs = bpy.context.preferences.view
    before = prefs.ui_scale
    prefs.ui_scale = 2.0
    try:
        if textfit.scale(bpy.context) != pytest.approx(2.0):
            pytest.fail(f"the interface scale did not follow the preference: {textfit.scale(bpy.context)}")
        at2 = [e[1] for e in draw(addon, width=440) if e[0] == "label"]
        narrow = [e[1] for e in draw(addon, width=220) if e[0] == "label"]
    finally:
        prefs.ui_scale = before
    assert " ".join(at2).split() == " ".join(at1).split() and abs(len(at2) - len(at1)) <= 2
    assert len(narrow) > len(at1) + 2  # the same region at twice the scale: more lines
