"""The Watermark tab of the 3D Viewport sidebar (N panel): a parent panel and its sub-panels.

PM Watermark (the active object, and how far a background run on it is) > Mark (payload, scheme, then
the key file or the pass phrase, Watermark, Show Carriers) > Advanced (closed: strength, base ratio,
seed), Progressive Mesh (export, import, publish for the web, level of detail), Verification (its own
key file, Verify, the active object's verdict, Save Report).

Every text is fitted to the sidebar's width with Blender's font metrics (``textfit``): sentences wrap,
a file name breaks, a property's name that would be cut beside its field gets a line above it, a long
button text has a short form. A greyed-out button says why in its tooltip (the operators' poll
messages).
"""

from __future__ import annotations

import os

import bpy
from bpy.types import Panel

from . import prefs, session, textfit, verdictwords


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


def label(layout, room: textfit.Room, text: str, icon: str = "NONE") -> None:
    """``text`` wrapped to the room; the lines after the first are indented like the first."""
    with_icon = icon != "NONE"
    for i, line in enumerate(textfit.wrap(text, room.label(with_icon), room.ui_scale)):
        layout.label(text=line, icon=icon if i == 0 else ("BLANK1" if with_icon else "NONE"))


def field(layout, room: textfit.Room, data, name: str, **kw) -> None:
    """A property with its name beside it (property split) when the name and an enum's choice fit there;
    else a checkbox with its name right of it, or the name on a line above and the field the full width
    below."""
    prop = data.bl_rna.properties[name]
    text = kw.pop("text", prop.name)
    shown = [prop.enum_items[getattr(data, name)].name] if prop.type == "ENUM" else []
    if room.fits(text, room.split_name()) and all(room.fits(t, room.field()) for t in shown):
        layout.prop(data, name, text=text, **kw)
        return
    if prop.type == "BOOLEAN" and room.fits(text, room.label(icon=True)):
        row = layout.row()
        row.use_property_split = False
        row.prop(data, name, text=text, **kw)
        return
    col = layout.column(align=True)
    label(col, room, text)
    row = col.row()
    row.use_property_split = False
    row.prop(data, name, text="", **kw)


def button(layout, room: textfit.Room, idname: str, text: str, short: str, icon: str) -> None:
    """An operator button with ``text``, or ``short`` when the text would be cut (then without its icon
    if that is still too long)."""
    with_icon = room.field(split=False) - textfit.ICON * room.ui_scale
    if room.fits(text, with_icon):
        layout.operator(idname, text=text, icon=icon)
    elif room.fits(short, with_icon):
        layout.operator(idname, text=short, icon=icon)
    else:
        layout.operator(idname, text=short)


def _where(layout, room, path: str, what: str) -> None:
    """The file name and folder of a path, whole (the field shows only its start)."""
    absolute = bpy.path.abspath(path) if path else ""
    label(layout, room, f"{what}: {bpy.path.basename(path)}")
    if path.startswith("//") and os.path.dirname(path[2:]) == "":
        label(layout, room, "beside the .blend")
    else:
        label(layout, room, f"in {os.path.dirname(os.path.abspath(absolute))}")


def _key_field(layout, room, context, settings, name: str) -> None:
    """A key path option, then where the key is: the path given, or the object's default key."""
    ob = _mesh(context)
    default = prefs.default_key_path(context, ob) if ob is not None else ""
    field(layout, room, settings, name, placeholder=bpy.path.basename(default) or "<object>.pmwm-key.json")
    path = getattr(settings, name)
    if path:
        _where(layout, room, path, "Key")
    elif ob is not None:
        _where(layout, room, default, "Key")


def _passphrase_field(layout, room, context, note: str) -> None:
    field(layout, room, context.window_manager.pmwm_secrets, "passphrase")
    label(layout, room, note, icon="INFO")


def _reads_with_passphrase(context) -> bool:
    import pmwm

    return pmwm.SCHEMES[context.scene.pmwm.scheme].keying == pmwm.PASS_PHRASE


class VIEW3D_PT_pmwm(_Sidebar, Panel):
    """Watermark a mesh, ship it as a progressive mesh, verify a copy."""

    bl_idname = "VIEW3D_PT_pmwm"
    bl_label = "PM Watermark"

    def draw(self, context):
        layout = self.layout
        room = textfit.Room.of(context)
        ob = context.active_object
        if ob is None:
            label(layout, room, "Select a mesh object", icon="INFO")
        elif ob.type != "MESH":
            label(layout, room, f"{ob.name}: not a mesh", icon="INFO")
        else:
            label(layout, room, f"{ob.name}: {len(ob.data.vertices)} vertices", icon="MESH_DATA")
            what = session.busy(ob)
            if what:
                doing = {"watermarked": "Watermarking", "verified": "Verifying", "reported": "Saving the report"}
                progress = session.progress(ob)
                label(
                    layout,
                    room,
                    f"{doing.get(what, what)}: {progress}" if progress else doing.get(what, what),
                    icon="TIME",
                )
                label(layout, room, "Esc cancels")


class VIEW3D_PT_pmwm_mark(_Sidebar, Panel):
    """Mark the active object: payload, scheme, key file or pass phrase."""

    bl_idname = "VIEW3D_PT_pmwm_mark"
    bl_label = "Mark"
    bl_parent_id = "VIEW3D_PT_pmwm"

    def draw(self, context):
        layout = _split(self.layout)
        room = textfit.Room.of(context)
        s = context.scene.pmwm
        ob = _mesh(context)
        col = layout.column()
        field(col, room, s, "payload")
        field(col, room, s, "scheme")
        if _reads_with_passphrase(context):
            _passphrase_field(col, room, context, "No key file: the pass phrase reads the mark")
        else:
            _key_field(col, room, context, s, "key_path")
            field(col, room, s, "overwrite_key")
        button(layout, room, "pmwm.watermark", "Watermark", "Mark", "LOCKED")
        button(layout, room, "pmwm.watermark_selected", "Watermark Selected", "Mark All", "LOCKED")

        col = layout.column()
        field(col, room, s, "show_carriers")
        if s.show_carriers:
            box = col.box()
            inner = room.boxed()
            label(box, inner, "Carriers are in vertex group 'pmwm_carriers':", icon="ERROR")
            label(box, inner, "a .blend saved now reveals them to anyone")
            if ob is not None and session.lookup(ob) is None:
                label(box, inner, "(no watermark of this object in this session)")


class VIEW3D_PT_pmwm_advanced(_Sidebar, Panel):
    """Strength, base ratio, seed and whether to build the progressive mesh, each with what it does."""

    bl_idname = "VIEW3D_PT_pmwm_advanced"
    bl_label = "Advanced"
    bl_parent_id = "VIEW3D_PT_pmwm_mark"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = _split(self.layout)
        room = textfit.Room.of(context)
        s = context.scene.pmwm
        col = layout.column()
        blind = _reads_with_passphrase(context)
        if s.scheme != "blind":  # (keyed waves spend a fixed distortion budget: no strength to choose)
            field(col, room, s, "blind_margin" if blind else "strength")
            label(col, room, "Higher: more robust, more visible")
        field(col, room, s, "base_ratio")
        label(col, room, "Size of the first streamed level")
        field(col, room, s, "seed")
        label(col, room, "-1: fresh random choices" if blind else "-1: fresh secret, kept in the key")
        field(col, room, s, "progressive")
        label(col, room, "Off: faster, nothing to export")


class VIEW3D_PT_pmwm_pm(_Sidebar, Panel):
    """Export the marked mesh as a progressive mesh, publish it for the web, import one, change its
    level of detail."""

    bl_idname = "VIEW3D_PT_pmwm_pm"
    bl_label = "Progressive Mesh"
    bl_parent_id = "VIEW3D_PT_pmwm"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = _split(self.layout)
        room = textfit.Room.of(context)
        ob = _mesh(context)
        col = layout.column()
        button(col, room, "pmwm.export_pm", "Export Progressive Mesh", "Export", "EXPORT")
        button(col, room, "pmwm.publish_web", "Publish for Web", "Publish", "WORLD")
        button(col, room, "pmwm.import_pm", "Import Progressive Mesh", "Import", "IMPORT")
        if ob is not None and ob.pmwm_lod.pm_path:
            lod = ob.pmwm_lod
            box = layout.box()
            inner = room.boxed()
            label(box, inner, f"Stream preview of {bpy.path.basename(lod.pm_path)}", icon="MOD_DECIM")
            field(box, inner, lod, "detail", slider=True)
            label(box, inner, f"Level {lod.level} of {lod.n_levels}: {len(ob.data.vertices)} vertices")
            if lod.status:
                label(box, inner, lod.status, icon="ERROR")


def verdict_box(layout, room: textfit.Room, ob) -> None:
    """The active object's last verdict in words, its numbers in a closed section; nothing when the
    object was not verified in this session."""
    rec = session.lookup_verified(ob)
    if rec is None:
        return
    v = rec.verdict
    box = layout.box()
    inner = room.boxed()
    label(
        box, inner, f"{ob.name}: {'MARKED' if v.marked else 'not marked'}", icon="CHECKMARK" if v.marked else "CANCEL"
    )
    if not session.looks_unchanged(ob.data, rec.positions):
        label(box, inner, "Changed since this verdict: verify again", icon="ERROR")
    for name, value in verdictwords.box_rows(v):
        label(box, inner, f"{name}: {value}")
    header, body = box.panel("pmwm_numbers", default_closed=True)
    header.label(text="Numbers")
    if body is not None:
        for name, value in verdictwords.numbers(v):
            label(body, inner, f"{name}: {value}")


class VIEW3D_PT_pmwm_verify(_Sidebar, Panel):
    """Verify the active object against a key file or the pass phrase; its verdict; save it as a report."""

    bl_idname = "VIEW3D_PT_pmwm_verify"
    bl_label = "Verification"
    bl_parent_id = "VIEW3D_PT_pmwm"

    def draw(self, context):
        layout = _split(self.layout)
        room = textfit.Room.of(context)
        col = layout.column()
        if _reads_with_passphrase(context):
            _passphrase_field(col, room, context, "Reads with the pass phrase (Scheme: Blind, in Mark)")
        else:
            _key_field(col, room, context, context.scene.pmwm, "verify_key_path")
        button(layout, room, "pmwm.verify", "Verify", "Verify", "VIEWZOOM")
        button(layout, room, "pmwm.verify_selected", "Verify Selected", "Verify All", "VIEWZOOM")
        ob = _mesh(context)
        if ob is not None:
            verdict_box(layout, room, ob)
        button(layout, room, "pmwm.save_report", "Save Report", "Report", "FILE")


classes = (VIEW3D_PT_pmwm, VIEW3D_PT_pmwm_mark, VIEW3D_PT_pmwm_advanced, VIEW3D_PT_pmwm_pm, VIEW3D_PT_pmwm_verify)


register, unregister = bpy.utils.register_classes_factory(classes)
