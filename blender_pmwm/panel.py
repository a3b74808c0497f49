"""The Watermark tab of the 3D Viewport sidebar (N panel)."""

from __future__ import annotations

import bpy
from bpy.types import Panel

from . import session


class VIEW3D_PT_pmwm(Panel):
    """Watermark options and operators, the last verdict, and the LoD slider of an imported PM."""

    bl_idname = "VIEW3D_PT_pmwm"
    bl_label = "PM Watermark"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Watermark"

    def draw(self, context):
        layout = self.layout
        s = context.scene.pmwm
        ob = context.active_object
        is_mesh = ob is not None and ob.type == "MESH" and ob.mode == "OBJECT"

        col = layout.column()
        col.prop(s, "payload")
        col.prop(s, "key_path")
        col.prop(s, "scheme")
        col.prop(s, "strength")
        col.prop(s, "base_ratio")
        col.prop(s, "seed")
        col.prop(s, "overwrite_key")
        row = col.row()
        row.enabled = is_mesh
        row.operator("pmwm.watermark", icon="LOCKED")

        col.prop(s, "show_carriers")
        if s.show_carriers:
            box = col.box()
            box.label(text="Carriers are in vertex group 'pmwm_carriers':", icon="ERROR")
            box.label(text="a .blend saved now reveals them to anyone")
            if is_mesh and session.lookup(ob) is None:
                box.label(text="(no watermark of this object in this session)")

        col.separator()
        row = col.row()
        row.enabled = is_mesh and session.lookup(ob) is not None
        row.operator("pmwm.export_pm", icon="EXPORT")
        col.operator("pmwm.import_pm", icon="IMPORT")

        col.separator()
        row = col.row()
        row.enabled = is_mesh
        row.operator("pmwm.verify", icon="VIEWZOOM")
        if s.verdict_object:
            box = col.box()
            box.label(text=f"{s.verdict_object}: {'MARKED' if s.verdict_marked else 'not marked'}",
                      icon="CHECKMARK" if s.verdict_marked else "CANCEL")
            box.label(text=f"p-value: {s.verdict_p_value}")
            box.label(text=f"Matching bits: {s.verdict_matches}")
            box.label(text=f"Payload: {s.verdict_payload}")

        if ob is not None and ob.type == "MESH" and ob.pmwm_lod.pm_path:
            lod = ob.pmwm_lod
            box = col.box()
            box.label(text=f"Stream preview: {bpy.path.basename(lod.pm_path)}", icon="MOD_DECIM")
            box.prop(lod, "level", slider=True)
            box.label(text=f"Level {lod.level} of {lod.n_levels}: {len(ob.data.vertices)} vertices")
            if lod.status:
                box.label(text=lod.status, icon="ERROR")


classes = (VIEW3D_PT_pmwm,)


register, unregister = bpy.utils.register_classes_factory(classes)
