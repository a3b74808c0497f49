"""Panel.draw with a recording fake layout (panels cannot be drawn headlessly); the operators' poll
messages (why a button is greyed out)."""

from __future__ import annotations

import re
from types import SimpleNamespace

import bpy
import pytest

ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())


class FakeLayout:
    """Records prop/operator/label calls and checks them as Blender would at draw time. Each entry is
    (kind, name or text, enabled, keywords, where): where = (boxes around it, property split on)."""

    def __init__(self, log, enabled=True, boxes=0):
        self.log = log
        self.enabled = enabled
        self.boxes = boxes
        self.active = True
        self.use_property_split = False
        self.use_property_decorate = True

    def _child(self, boxes=None):
        child = FakeLayout(self.log, self.enabled, self.boxes if boxes is None else boxes)
        child.use_property_split, child.use_property_decorate = self.use_property_split, self.use_property_decorate
        return child

    def row(self, **_):
        return self._child()

    def column(self, **_):
        return self._child()

    def box(self):
        return self._child(self.boxes + 1)

    def panel(self, idname, default_closed=False):
        """A collapsible section (Blender 4.1+): drawn open here, so that its contents are checked too."""
        return self._child(), self._child()

    def separator(self, **_):
        pass

    def _icon(self, icon):
        assert icon in ICONS, f"unknown icon {icon}"

    def prop(self, data, name, icon="NONE", **kw):
        assert name in data.bl_rna.properties, f"{data} has no property {name}"
        self._icon(icon)
        kw.setdefault("text", data.bl_rna.properties[name].name)
        prop = data.bl_rna.properties[name]
        kw["value"] = prop.enum_items[getattr(data, name)].name if prop.type == "ENUM" else ""
        kw["boolean"] = prop.type == "BOOLEAN"
        self.log.append(("prop", name, self.enabled, kw, (self.boxes, self.use_property_split)))

    def operator(self, idname, icon="NONE", **kw):
        module, func = idname.split(".")
        op = getattr(getattr(bpy.ops, module), func)
        kw.setdefault("text", op.get_rna_type().name)  # KeyError when not registered
        self._icon(icon)
        kw["icon"] = icon
        self.log.append(("operator", idname, self.enabled, kw, (self.boxes, False)))
        return SimpleNamespace()

    def label(self, text="", icon="NONE", **_):
        self._icon(icon)
        self.log.append(("label", text, self.enabled, {"icon": icon}, (self.boxes, False)))


PANELS = (
    "VIEW3D_PT_pmwm",
    "VIEW3D_PT_pmwm_mark",
    "VIEW3D_PT_pmwm_advanced",
    "VIEW3D_PT_pmwm_pm",
    "VIEW3D_PT_pmwm_verify",
)


class Context:
    """bpy.context with a sidebar region of a given width (panels read context.region.width)."""

    def __init__(self, width=None):
        self.region = SimpleNamespace(width=width) if width else None

    def __getattr__(self, name):
        return getattr(bpy.context, name)


def draw(addon, only=None, width=None):
    """Draw every panel (or the one named) into one log, each with a layout of its own, in a sidebar
    ``width`` pixels wide (default: the add-on's default width)."""
    log = []
    for name in PANELS if only is None else (only,):
        layout = FakeLayout(log)
        getattr(addon.panel, name).draw(SimpleNamespace(layout=layout), Context(width))
        if name != "VIEW3D_PT_pmwm":  # labels beside their fields
            assert layout.use_property_split is True, name
    return log


def _names(log, kind):
    return {entry[1]: entry[2] for entry in log if entry[0] == kind}


def _labels(log):
    return " | ".join(entry[1] for entry in log if entry[0] == "label")


def _text(log) -> str:
    """The labels' text with the wrapping undone (lines joined, spaces dropped): compare with _squeeze."""
    return "".join(entry[1] for entry in log if entry[0] == "label").replace(" ", "")


def _squeeze(text: str) -> str:
    return text.replace(" ", "")


def _poll_reason(op: str) -> str | None:
    """None when the operator can run here, else the reason its greyed-out button gives (its poll
    message, which Blender puts in the tooltip and in the error of a script that calls it)."""
    if getattr(bpy.ops.pmwm, op).poll():
        return None
    try:
        getattr(bpy.ops.pmwm, op)()
    except RuntimeError as exc:
        return str(exc)
    raise AssertionError(f"{op}: poll() is False but the call ran")


def test_sub_panels_in_the_watermark_tab(addon):
    classes = [getattr(addon.panel, n) for n in PANELS]
    for cls in classes:
        assert (cls.bl_space_type, cls.bl_region_type, cls.bl_category) == ("VIEW_3D", "UI", "Watermark")
        assert hasattr(bpy.types, cls.__name__)
    parents = {cls.__name__: getattr(cls, "bl_parent_id", "") for cls in classes}
    assert parents == {
        "VIEW3D_PT_pmwm": "",
        "VIEW3D_PT_pmwm_mark": "VIEW3D_PT_pmwm",
        "VIEW3D_PT_pmwm_advanced": "VIEW3D_PT_pmwm_mark",
        "VIEW3D_PT_pmwm_pm": "VIEW3D_PT_pmwm",
        "VIEW3D_PT_pmwm_verify": "VIEW3D_PT_pmwm",
    }
    assert "DEFAULT_CLOSED" in addon.panel.VIEW3D_PT_pmwm_advanced.bl_options


def test_advanced_options_are_in_the_advanced_sub_panel_with_a_line_each(scene, addon):
    advanced = draw(addon, "VIEW3D_PT_pmwm_advanced")
    assert [e[1] for e in advanced if e[0] == "prop"] == ["strength", "base_ratio", "seed", "progressive"]
    # under each option what it does (wrapped to the sidebar's width)
    kinds = "".join("p" if e[0] == "prop" else "l" for e in advanced)
    assert re.fullmatch(r"(pl+){4}", kinds), kinds
    assert "freshsecret" in _text(advanced) and "robust" in _text(advanced)
    assert "nothingtoexport" in _text(advanced)
    mark = [e[1] for e in draw(addon, "VIEW3D_PT_pmwm_mark") if e[0] == "prop"]
    assert mark == ["payload", "scheme", "key_path", "overwrite_key", "show_carriers"]


def test_options_and_operators_without_a_mesh(scene, addon):
    log = draw(addon)
    ops = _names(log, "operator")
    assert set(ops) == {
        "pmwm.watermark",
        "pmwm.watermark_selected",
        "pmwm.export_pm",
        "pmwm.import_pm",
        "pmwm.verify",
        "pmwm.verify_selected",
        "pmwm.save_report",
        "pmwm.publish_web",
    }
    assert "Select a mesh object" in _labels(log)
    # greyed out, and saying why (no active object); import needs none
    for op in ("watermark", "verify", "export_pm", "save_report", "publish_web"):
        assert "no active object: select a mesh object" in _poll_reason(op), op
    assert _poll_reason("import_pm") is None
    assert "reveal" not in _labels(log)


def test_carrier_warning_verdict_report_and_lod_slider(scene, addon, bl, tmp_path):
    ob = bl.suzanne(levels=2)
    log = draw(addon)
    assert _poll_reason("watermark") is None and _poll_reason("verify") is None
    assert "was not watermarked in this session: watermark this object first" in _poll_reason("export_pm")
    assert "was not verified in this session: verify this object first" in _poll_reason("save_report")
    assert f"{ob.name}: {len(ob.data.vertices)} vertices" in _labels(log)

    key, pm = tmp_path / "k.json", tmp_path / "m.pmwm"
    bpy.ops.pmwm.watermark(payload="Panel test", key_path=str(key), seed=3)
    scene.pmwm.show_carriers = True
    bpy.ops.pmwm.verify(key_path=str(key))
    log = draw(addon)
    labels = _labels(log)
    assert "reveal" in labels  # the warning about a shared .blend
    assert _squeeze("Suzanne: MARKED") in _text(log) and _squeeze("Payload read: 'Panel test'") in _text(log)
    assert _poll_reason("export_pm") is None and _poll_reason("save_report") is None
    assert "detail" not in _names(log, "prop")
    scene.pmwm.show_carriers = False

    bpy.ops.pmwm.export_pm(filepath=str(pm))
    bpy.ops.pmwm.import_pm(filepath=str(pm), level=1)
    log = draw(addon)
    sliders = [e for e in log if e[0] == "prop" and e[1] == "detail"]
    assert sliders and sliders[0][3].get("slider") is True
    assert "m.pmwm" in _labels(log)
    lod = bpy.context.active_object.pmwm_lod
    rna = lod.bl_rna.properties["detail"]
    assert (rna.hard_min, rna.hard_max, rna.subtype) == (0.0, 100.0, "PERCENTAGE")  # a slider with its fill
    assert lod.detail == pytest.approx(100.0 / lod.n_levels)  # level 1 imported
    n_before = len(bpy.context.active_object.data.vertices)
    lod.detail = 100.0  # dragged to the end: the full mesh
    assert lod.level == lod.n_levels and len(bpy.context.active_object.data.vertices) > n_before
    lod.level = 0  # scripts set the level: the slider follows
    assert lod.detail == 0.0
    assert f"Level 0 of {lod.n_levels}" in _labels(draw(addon, "VIEW3D_PT_pmwm_pm"))


def test_buttons_greyed_in_edit_mode_say_why(scene, addon, bl):
    bl.suzanne(levels=0)
    bpy.ops.object.mode_set(mode="EDIT")
    for op in ("watermark", "verify", "export_pm", "save_report", "publish_web"):
        assert "Edit Mode: switch to Object Mode first" in _poll_reason(op), op


def test_key_fields_show_the_default_key_whole(scene, addon, bl, key_prefs, tmp_path):
    bl.suzanne(levels=0)
    for panel, name in (("VIEW3D_PT_pmwm_mark", "key_path"), ("VIEW3D_PT_pmwm_verify", "verify_key_path")):
        log = draw(addon, panel)
        labels = _text(log)
        assert _squeeze(f"Key: Suzanne.pmwm-key.json in {tmp_path / 'key-folder'}") in labels, panel
        fields = [e for e in log if e[0] == "prop" and e[1] == name]
        assert fields[0][3]["placeholder"] == "Suzanne.pmwm-key.json"
    # a chosen key is shown whole (the field shows only its start)
    scene.pmwm.key_path = str(tmp_path / "a folder" / "chosen.pmwm-key.json")
    labels = _text(draw(addon, "VIEW3D_PT_pmwm_mark"))
    assert _squeeze(f"Key: chosen.pmwm-key.json in {tmp_path / 'a folder'}") in labels
    # the Verification panel's key is another option: still the object's own key
    assert "Key:Suzanne.pmwm-key.json" in _text(draw(addon, "VIEW3D_PT_pmwm_verify"))


def test_pass_phrase_comes_below_the_scheme(scene, addon, bl):
    bl.suzanne(levels=0)
    scene.pmwm.scheme = "blind"
    mark = [e[1] for e in draw(addon, "VIEW3D_PT_pmwm_mark") if e[0] == "prop"]
    assert mark == ["payload", "scheme", "passphrase", "show_carriers"]
    verify = [e[1] for e in draw(addon, "VIEW3D_PT_pmwm_verify") if e[0] == "prop"]
    assert verify == ["passphrase"]
