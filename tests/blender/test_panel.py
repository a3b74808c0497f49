"""Panel.draw with a recording fake layout (panels cannot be drawn headlessly); the operators' poll
messages (why a button is greyed out)."""

from __future__ import annotations

from types import SimpleNamespace

import bpy

ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())


class FakeLayout:
    """Records prop/operator/label calls and checks them as Blender would at draw time."""

    def __init__(self, log, enabled=True):
        self.log = log
        self.enabled = enabled
        self.active = True
        self.use_property_split = False
        self.use_property_decorate = True

    def _child(self):
        child = FakeLayout(self.log, self.enabled)
        child.use_property_split, child.use_property_decorate = self.use_property_split, self.use_property_decorate
        return child

    def row(self, **_):
        return self._child()

    def column(self, **_):
        return self._child()

    def box(self):
        return self._child()

    def separator(self, **_):
        pass

    def _icon(self, icon):
        assert icon in ICONS, f"unknown icon {icon}"

    def prop(self, data, name, icon="NONE", **kw):
        assert name in data.bl_rna.properties, f"{data} has no property {name}"
        self._icon(icon)
        self.log.append(("prop", name, self.enabled, kw))

    def operator(self, idname, icon="NONE", **kw):
        module, func = idname.split(".")
        getattr(getattr(bpy.ops, module), func).get_rna_type()  # KeyError when not registered
        self._icon(icon)
        self.log.append(("operator", idname, self.enabled, kw))
        return SimpleNamespace()

    def label(self, text="", icon="NONE", **_):
        self._icon(icon)
        self.log.append(("label", text, self.enabled, {}))


PANELS = ("VIEW3D_PT_pmwm", "VIEW3D_PT_pmwm_mark", "VIEW3D_PT_pmwm_advanced", "VIEW3D_PT_pmwm_pm",
          "VIEW3D_PT_pmwm_verify")


def draw(addon, only=None):
    """Draw every panel (or the one named) into one log, each with a layout of its own."""
    log = []
    for name in PANELS if only is None else (only,):
        layout = FakeLayout(log)
        getattr(addon.panel, name).draw(SimpleNamespace(layout=layout), bpy.context)
        if name != "VIEW3D_PT_pmwm":  # labels beside their fields: not cut at the default width
            assert layout.use_property_split is True, name
    return log


def _names(log, kind):
    return {entry[1]: entry[2] for entry in log if entry[0] == kind}


def _labels(log):
    return " | ".join(entry[1] for entry in log if entry[0] == "label")


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
    assert parents == {"VIEW3D_PT_pmwm": "", "VIEW3D_PT_pmwm_mark": "VIEW3D_PT_pmwm",
                       "VIEW3D_PT_pmwm_advanced": "VIEW3D_PT_pmwm_mark", "VIEW3D_PT_pmwm_pm": "VIEW3D_PT_pmwm",
                       "VIEW3D_PT_pmwm_verify": "VIEW3D_PT_pmwm"}
    assert "DEFAULT_CLOSED" in addon.panel.VIEW3D_PT_pmwm_advanced.bl_options


def test_advanced_options_are_in_the_advanced_sub_panel_with_a_line_each(scene, addon):
    advanced = draw(addon, "VIEW3D_PT_pmwm_advanced")
    assert [e[1] for e in advanced if e[0] == "prop"] == ["strength", "base_ratio", "seed", "progressive"]
    kinds = [e[0] for e in advanced]
    assert kinds == ["prop", "label"] * 4  # one explaining line under each option
    assert "fresh secret" in _labels(advanced) and "robust" in _labels(advanced)
    assert "nothing to export" in _labels(advanced)
    mark = {e[1] for e in draw(addon, "VIEW3D_PT_pmwm_mark") if e[0] == "prop"}
    assert {"payload", "key_path", "scheme", "overwrite_key", "show_carriers"} == mark


def test_options_and_operators_without_a_mesh(scene, addon):
    log = draw(addon)
    ops = _names(log, "operator")
    assert set(ops) == {"pmwm.watermark", "pmwm.export_pm", "pmwm.import_pm", "pmwm.verify", "pmwm.save_report"}
    assert "Select a mesh object" in _labels(log)
    # greyed out, and saying why (no active object); import needs none
    for op in ("watermark", "verify", "export_pm", "save_report"):
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
    assert "MARKED" in labels and "Panel test" in labels and "p-value" in labels
    assert _poll_reason("export_pm") is None and _poll_reason("save_report") is None
    assert "level" not in _names(log, "prop")
    scene.pmwm.show_carriers = False

    bpy.ops.pmwm.export_pm(filepath=str(pm))
    bpy.ops.pmwm.import_pm(filepath=str(pm), level=1)
    log = draw(addon)
    sliders = [e for e in log if e[0] == "prop" and e[1] == "level"]
    assert sliders and sliders[0][3].get("slider") is True
    assert "m.pmwm" in _labels(log)


def test_buttons_greyed_in_edit_mode_say_why(scene, addon, bl):
    bl.suzanne(levels=0)
    bpy.ops.object.mode_set(mode="EDIT")
    for op in ("watermark", "verify", "export_pm", "save_report"):
        assert "Edit Mode: switch to Object Mode first" in _poll_reason(op), op


def test_key_field_shows_the_default_key_path(scene, addon, bl, key_prefs, tmp_path):
    bl.suzanne(levels=0)
    labels = _labels(draw(addon, "VIEW3D_PT_pmwm_mark"))
    assert f"Key: Suzanne.pmwm-key.json | in {tmp_path / 'key-folder'}" in labels
    key_fields = [e for e in draw(addon, "VIEW3D_PT_pmwm_verify") if e[0] == "prop" and e[1] == "key_path"]
    assert key_fields[0][3]["placeholder"] == "Suzanne.pmwm-key.json"
    # the lines under the Advanced options are short enough for the default sidebar width
    assert all(len(e[1]) <= 36 for e in draw(addon, "VIEW3D_PT_pmwm_advanced") if e[0] == "label")
    scene.pmwm.key_path = str(tmp_path / "chosen.json")
    assert "Key:" not in _labels(draw(addon, "VIEW3D_PT_pmwm_mark"))
