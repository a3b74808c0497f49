"""The Watermark tab of the 3D Viewport sidebar (N panel): a parent panel and its sub-panels.

PM Watermark (the active object) > Mark (payload, key file, scheme, Watermark, Show Carriers)
> Advanced (closed: strength, base ratio, seed), Progressive Mesh (export, import, level of detail),
Verification (key file, Verify, the verdict, Save Report). Labels sit left of their fields (property
split), so they are not cut at the default sidebar width. A greyed-out button says why in its tooltip
(the operators' poll messages).
"""

from __future__ import annotations

import bpy
from bpy.types import Panel

from . import prefs, session


class _Sidebar:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Watermark"


def _split(layout):
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


def _mesh(context):
    ob = context.active_object
    return ob if ob is not None and ob.type == "MESH" else None


def _secret_field(layout, context) -> None:
    """What reads the mark: the Pass Phrase for the Blind scheme, else the Key File option."""
    if context.scene.pmwm.scheme == "blind":
        layout.prop(context.window_manager.pmwm_secrets, "passphrase")
        layout.label(text="No key file: the pass phrase reads the mark", icon="INFO")
        return
    s = context.scene.pmwm
    ob = _mesh(context)
    default = prefs.default_key_path(context, ob) if ob is not None else ""
    layout.prop(s, "key_path", placeholder=bpy.path.basename(default) if default else "<object>.pmwm-key.json")
    if not s.key_path and ob is not None:
        layout.label(text=f"Key: {bpy.path.basename(default)}", icon="INFO")
        layout.label(text="beside the .blend" if default.startswith("//") else f"in {prefs.key_folder(context)}")


class VIEW3D_PT_pmwm(_Sidebar, Panel):
    """Watermark a mesh, ship it as a progressive mesh, verify a copy."""

    bl_idname = "VIEW3D_PT_pmwm"
    bl_label = "PM Watermark"

    def draw(self, context):
        layout = self.layout
        ob = context.active_object
        if ob is None:
            layout.label(text="Select a mesh object", icon="INFO")
        elif ob.type != "MESH":
            layout.label(text=f"{ob.name}: not a mesh", icon="INFO")
        else:
            layout.label(text=f"{ob.name}: {len(ob.data.vertices)} vertices", icon="MESH_DATA")
            what = session.busy(ob)
            if what:
                layout.label(text=f"Being {what}: Esc cancels", icon="TIME")


class VIEW3D_PT_pmwm_mark(_Sidebar, Panel):
    """Mark the active object: payload, key file, scheme."""

    bl_idname = "VIEW3D_PT_pmwm_mark"
    bl_label = "Mark"
    bl_parent_id = "VIEW3D_PT_pmwm"

    def draw(self, context):
        layout = _split(self.layout)
        s = context.scene.pmwm
        ob = _mesh(context)
        col = layout.column()
        col.prop(s, "payload")
        _secret_field(col, context)
        col.prop(s, "scheme")
        if s.scheme != "blind":
            col.prop(s, "overwrite_key")
        layout.operator("pmwm.watermark", icon="LOCKED")

        col = layout.column()
        col.prop(s, "show_carriers")
        if s.show_carriers:
            box = col.box()
            box.label(text="Carriers are in vertex group 'pmwm_carriers':", icon="ERROR")
            box.label(text="a .blend saved now reveals them to anyone")
            if ob is not None and session.lookup(ob) is None:
                box.label(text="(no watermark of this object in this session)")


class VIEW3D_PT_pmwm_advanced(_Sidebar, Panel):
    """Strength, base ratio, seed and whether to build the progressive mesh, each with what it does."""

    bl_idname = "VIEW3D_PT_pmwm_advanced"
    bl_label = "Advanced"
    bl_parent_id = "VIEW3D_PT_pmwm_mark"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = _split(self.layout)
        s = context.scene.pmwm
        col = layout.column()
        col.prop(s, "blind_margin" if s.scheme == "blind" else "strength")
        col.label(text="Higher: more robust, more visible")
        col.prop(s, "base_ratio")
        col.label(text="Size of the first streamed level")
        col.prop(s, "seed")
        col.label(text="-1: fresh secret, kept in the key")
        col.prop(s, "progressive")
        col.label(text="Off: faster, nothing to export")


class VIEW3D_PT_pmwm_pm(_Sidebar, Panel):
    """Export the marked mesh as a progressive mesh, import one, change its level of detail."""

    bl_idname = "VIEW3D_PT_pmwm_pm"
    bl_label = "Progressive Mesh"
    bl_parent_id = "VIEW3D_PT_pmwm"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = _split(self.layout)
        ob = _mesh(context)
        col = layout.column()
        col.operator("pmwm.export_pm", icon="EXPORT")
        col.operator("pmwm.import_pm", icon="IMPORT")
        if ob is not None and ob.pmwm_lod.pm_path:
            lod = ob.pmwm_lod
            box = layout.box()
            box.label(text=f"Stream preview: {bpy.path.basename(lod.pm_path)}", icon="MOD_DECIM")
            box.prop(lod, "level", slider=True)
            box.label(text=f"Level {lod.level} of {lod.n_levels}: {len(ob.data.vertices)} vertices")
            if lod.status:
                box.label(text=lod.status, icon="ERROR")


class VIEW3D_PT_pmwm_verify(_Sidebar, Panel):
    """Verify the active object against a key file; the verdict; save it as a report."""

    bl_idname = "VIEW3D_PT_pmwm_verify"
    bl_label = "Verification"
    bl_parent_id = "VIEW3D_PT_pmwm"

    def draw(self, context):
        layout = _split(self.layout)
        s = context.scene.pmwm
        _secret_field(layout.column(), context)
        layout.operator("pmwm.verify", icon="VIEWZOOM")
        if s.verdict_object:
            box = layout.box()
            box.label(text=f"{s.verdict_object}: {'MARKED' if s.verdict_marked else 'not marked'}",
                      icon="CHECKMARK" if s.verdict_marked else "CANCEL")
            box.label(text=f"p-value: {s.verdict_p_value}")
            box.label(text=f"Matching bits: {s.verdict_matches}")
            box.label(text=f"Payload: {s.verdict_payload}")
        layout.operator("pmwm.save_report", icon="FILE")


classes = (VIEW3D_PT_pmwm, VIEW3D_PT_pmwm_mark, VIEW3D_PT_pmwm_advanced, VIEW3D_PT_pmwm_pm, VIEW3D_PT_pmwm_verify)


register, unregister = bpy.utils.register_classes_factory(classes)
