"""Panel.draw with a recording fake layout (panels cannot be drawn headlessly)."""

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

    def _child(self):
        return FakeLayout(self.log, self.enabled)

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


def draw(addon):
    log = []
    panel = addon.panel.VIEW3D_PT_pmwm
    panel.draw(SimpleNamespace(layout=FakeLayout(log)), bpy.context)
    return log


def _names(log, kind):
    return {entry[1]: entry[2] for entry in log if entry[0] == kind}


def _labels(log):
    return " | ".join(entry[1] for entry in log if entry[0] == "label")


def test_panel_is_in_the_watermark_tab(addon):
    panel = addon.panel.VIEW3D_PT_pmwm
    assert (panel.bl_space_type, panel.bl_region_type, panel.bl_category) == ("VIEW_3D", "UI", "Watermark")
    assert hasattr(bpy.types, "VIEW3D_PT_pmwm")


def test_options_and_operators_without_a_mesh(scene, addon):
    log = draw(addon)
    props = _names(log, "prop")
    assert {"payload", "key_path", "scheme", "strength", "base_ratio", "seed", "overwrite_key",
            "show_carriers"} <= set(props)
    ops = _names(log, "operator")
    assert set(ops) == {"pmwm.watermark", "pmwm.export_pm", "pmwm.import_pm", "pmwm.verify"}
    assert not ops["pmwm.watermark"] and not ops["pmwm.verify"]  # greyed out: no active mesh
    assert ops["pmwm.import_pm"]
    assert "reveal" not in _labels(log)


def test_carrier_warning_verdict_and_lod_slider(scene, addon, bl, tmp_path):
    bl.suzanne(levels=2)
    log = draw(addon)
    ops = _names(log, "operator")
    assert ops["pmwm.watermark"] and ops["pmwm.verify"] and not ops["pmwm.export_pm"]

    key, pm = tmp_path / "k.json", tmp_path / "m.pmwm"
    bpy.ops.pmwm.watermark(payload="Panel test", key_path=str(key), seed=3)
    scene.pmwm.show_carriers = True
    bpy.ops.pmwm.verify(key_path=str(key))
    log = draw(addon)
    labels = _labels(log)
    assert "reveal" in labels  # the warning about a shared .blend
    assert "MARKED" in labels and "Panel test" in labels and "p-value" in labels
    assert _names(log, "operator")["pmwm.export_pm"]
    assert "level" not in _names(log, "prop")
    scene.pmwm.show_carriers = False

    bpy.ops.pmwm.export_pm(filepath=str(pm))
    bpy.ops.pmwm.import_pm(filepath=str(pm), level=1)
    log = draw(addon)
    sliders = [e for e in log if e[0] == "prop" and e[1] == "level"]
    assert sliders and sliders[0][3].get("slider") is True
    assert "m.pmwm" in _labels(log)


def test_buttons_greyed_in_edit_mode(scene, addon, bl):
    bl.suzanne(levels=0)
    bpy.ops.object.mode_set(mode="EDIT")
    ops = _names(draw(addon), "operator")
    assert not ops["pmwm.watermark"] and not ops["pmwm.verify"] and not ops["pmwm.export_pm"]
