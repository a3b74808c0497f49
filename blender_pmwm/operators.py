"""Operators: pmwm.watermark, pmwm.export_pm, pmwm.import_pm, pmwm.verify.

Each one reads its options, moves mesh data with foreach_get/foreach_set, calls ``pmwm`` and turns
``pmwm.PmwmError`` into ``self.report({'ERROR'}, ...)`` + ``{'CANCELLED'}``. Everything is computed
first and written back only on success, so a failure leaves the object and the scene as they were.
``pmwm`` is imported inside the operators to keep Blender's start-up fast.

Scripting API (``blender --background --python script.py``): the keyword arguments of watermark
and verify override the Scene options (``scene.pmwm``); arguments left out take the Scene's values.
watermark and verify work on the base mesh in object space (``object.data``: modifiers and the
object transform are not applied), the data an exporter writes when both are neutral.
"""

from __future__ import annotations

import os
import traceback
from contextlib import contextmanager

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ExportHelper, ImportHelper

from . import meshdata, session
from .props import SCHEME_ITEMS, records_at_level


class _Failed(Exception):
    """A user-facing failure detected by the add-on itself (message is the report)."""


@contextmanager
def _progress(context):
    """Yield a ``progress(fraction, message)`` callback driving the window manager's progress bar."""
    wm = context.window_manager
    wm.progress_begin(0, 1000)

    def update(fraction: float, message: str = "") -> None:
        wm.progress_update(int(1000 * min(max(float(fraction), 0.0), 1.0)))

    try:
        yield update
    finally:
        wm.progress_end()


def _active_mesh(context):
    """The active object if it is a mesh in Object Mode; else raise _Failed naming the way out."""
    ob = context.active_object
    if ob is None:
        raise _Failed("no active object: select a mesh object")
    if ob.type != "MESH":
        raise _Failed(f"'{ob.name}' is a {ob.type.lower()} object, not a mesh: select a mesh object")
    if ob.mode != "OBJECT":
        raise _Failed(f"'{ob.name}' is in {ob.mode.replace('_', ' ').title()} Mode: switch to Object Mode first")
    return ob


def _read_mesh(ob):
    """(vertices, triangles) of the object's base mesh; _Failed when it has no faces."""
    V = meshdata.read_positions(ob.data)
    F = meshdata.read_triangles(ob.data)
    if len(V) == 0 or len(F) == 0:
        raise _Failed(f"'{ob.name}' has no faces: nothing to watermark or verify")
    return V, F


def _file_path(raw: str, what: str) -> str:
    if not raw:
        raise _Failed(f"no {what} path given: set one in the Watermark panel or pass it to the operator")
    return os.path.abspath(bpy.path.abspath(raw))


class _PmwmOperator:
    """Shared execute wrapper: every failure becomes an ERROR report and CANCELLED."""

    def execute(self, context):
        import pmwm

        try:
            return self.run(context)
        except (_Failed, pmwm.PmwmError) as exc:
            self.report({"ERROR"}, str(exc))
        except OSError as exc:
            self.report({"ERROR"}, f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": "))
        except Exception as exc:  # a bug: keep Blender alive, leave the scene as it was
            traceback.print_exc()
            self.report({"ERROR"}, f"pmwm internal error ({type(exc).__name__}: {exc}); see the system console")
        return {"CANCELLED"}

    def option(self, context, name):
        """The operator argument when given, else the Scene option of the same name.

        The value used is stored back in the operator, so the redo panel shows what ran.
        """
        if self.properties.is_property_set(name):
            return getattr(self, name)
        value = getattr(context.scene.pmwm, name)
        setattr(self, name, value)
        return value


class PMWM_OT_watermark(_PmwmOperator, Operator):
    """Watermark the active mesh object and write its key file"""

    bl_idname = "pmwm.watermark"
    bl_label = "Watermark"
    bl_options = {"REGISTER", "UNDO"}

    payload: StringProperty(name="Payload", description="Text to embed; empty: 64 random bits",
                            options={"SKIP_SAVE"})
    key_path: StringProperty(name="Key File", subtype="FILE_PATH", options={"SKIP_SAVE"})
    scheme: EnumProperty(name="Scheme", items=SCHEME_ITEMS, default="robust", options={"SKIP_SAVE"})
    strength: FloatProperty(name="Strength", default=2.0, min=0.01, max=100.0, options={"SKIP_SAVE"})
    base_ratio: FloatProperty(name="Base Ratio", default=0.03, min=0.0001, max=1.0, options={"SKIP_SAVE"})
    seed: IntProperty(name="Seed", description="-1: a fresh random secret", default=-1, min=-1,
                      options={"SKIP_SAVE"})
    overwrite_key: BoolProperty(name="Overwrite Key", default=False, options={"SKIP_SAVE"})

    def run(self, context):
        import pmwm

        ob = _active_mesh(context)
        key_path = _file_path(self.option(context, "key_path"), "key file")
        overwrite = self.option(context, "overwrite_key")
        if os.path.isdir(key_path):
            raise _Failed(f"key file path is a folder: {key_path}")
        if os.path.exists(key_path) and not overwrite:
            raise _Failed(f"key file exists: {key_path}: choose another path or enable Overwrite Key")
        if not os.path.isdir(os.path.dirname(key_path)):
            raise _Failed(f"folder does not exist: {os.path.dirname(key_path)}")
        V, F = _read_mesh(ob)
        seed = self.option(context, "seed")
        opts = pmwm.EmbedOptions(
            payload=self.option(context, "payload") or None,
            strength=float(self.option(context, "strength")),
            base_ratio=float(self.option(context, "base_ratio")),
            seed=None if seed < 0 else int(seed),
            scheme=self.option(context, "scheme"),
        )
        with _progress(context) as progress:
            res = pmwm.embed(V, F, opts, progress=progress)
        pmwm.write_key(key_path, res.key, overwrite=overwrite)

        # Success: write back (nothing above touched the scene).
        mesh = ob.data
        meshdata.write_base_positions(mesh, res.vertices)
        session.remember(ob, session.Marked(
            name=ob.name, pm=res.pm, carriers=res.carriers, positions=meshdata.read_positions32(mesh),
            n_bits=len(res.bits), vsnr_db=float(res.vsnr_db)))
        if ob.modifiers or mesh.shape_keys is not None:
            self.report({"WARNING"}, f"'{ob.name}' has modifiers or shape keys: the base mesh was watermarked; "
                                     "apply topology-changing modifiers before watermarking to mark what you ship")
        if context.scene.pmwm.show_carriers:
            meshdata.mark_carriers(ob, res.carriers)
            self.report({"WARNING"}, "carriers are in vertex group 'pmwm_carriers': "
                                     "turn Show Carriers off before sharing the .blend")
        self.report({"INFO"}, f"Watermarked '{ob.name}': {len(res.bits)} bits, {len(res.carriers)} carriers, "
                              f"VSNR {res.vsnr_db:.1f} dB; key written to {key_path}")
        return {"FINISHED"}


class PMWM_OT_export_pm(_PmwmOperator, Operator, ExportHelper):
    """Write the progressive mesh of the active object's last watermark (this session) to a .pmwm file"""

    bl_idname = "pmwm.export_pm"
    bl_label = "Export Progressive Mesh"
    bl_options = {"REGISTER"}

    filename_ext = ".pmwm"
    filter_glob: StringProperty(default="*.pmwm", options={"HIDDEN"})

    def run(self, context):
        import pmwm

        ob = _active_mesh(context)
        marked = session.lookup(ob)
        if marked is None:
            raise _Failed(f"'{ob.name}' was not watermarked in this session: watermark this object first")
        if not session.is_current(marked, meshdata.read_positions32(ob.data)):
            raise _Failed(f"'{ob.name}' changed since it was watermarked (edit or undo): "
                          "watermark this object first")
        path = _file_path(self.filepath, "progressive mesh")
        pmwm.write_pm(path, marked.pm, force=True)
        pm = marked.pm
        self.report({"INFO"}, f"Wrote progressive mesh of '{ob.name}' to {path}: {pm.n_base_vertices} base "
                              f"vertices, {pm.n_records} vertex splits in {len(pm.level_records)} levels")
        return {"FINISHED"}


class PMWM_OT_import_pm(_PmwmOperator, Operator, ImportHelper):
    """Import a .pmwm progressive mesh as a new object at a level of detail"""

    bl_idname = "pmwm.import_pm"
    bl_label = "Import Progressive Mesh"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".pmwm"
    filter_glob: StringProperty(default="*.pmwm", options={"HIDDEN"})
    level: IntProperty(name="Level of Detail", description="0: base mesh; -1: full resolution",
                       default=-1, min=-1, options={"SKIP_SAVE"})

    def run(self, context):
        if context.mode != "OBJECT":
            raise _Failed("switch to Object Mode before importing")
        path = _file_path(self.filepath, "progressive mesh")
        if not os.path.isfile(path):
            raise _Failed(f"no such file: {path}")
        pm = session.load_pm(path)
        n_levels = len(pm.level_records)
        level = n_levels if self.level < 0 else self.level
        if level > n_levels:
            raise _Failed(f"level {level} is out of range: {os.path.basename(path)} has levels 0..{n_levels}")
        V, F = pm.decode(records=records_at_level(pm, level))

        name = os.path.splitext(os.path.basename(path))[0]
        mesh = bpy.data.meshes.new(name)
        meshdata.set_geometry(mesh, V, F)
        ob = bpy.data.objects.new(name, mesh)
        context.collection.objects.link(ob)
        for other in context.view_layer.objects:
            other.select_set(False)
        ob.select_set(True)
        context.view_layer.objects.active = ob
        lod = ob.pmwm_lod
        lod.n_levels = n_levels
        lod.level = level  # no decode yet: pm_path is still empty
        lod.pm_path = path
        self.report({"INFO"}, f"Imported '{ob.name}' at level {level}/{n_levels}: {len(V)} of "
                              f"{pm.n_vertices} vertices")
        return {"FINISHED"}


class PMWM_OT_verify(_PmwmOperator, Operator):
    """Verify whether the active mesh object carries the watermark of a key file"""

    bl_idname = "pmwm.verify"
    bl_label = "Verify"
    bl_options = {"REGISTER"}

    key_path: StringProperty(name="Key File", subtype="FILE_PATH", options={"SKIP_SAVE"})

    def run(self, context):
        import pmwm

        ob = _active_mesh(context)
        key_path = _file_path(self.option(context, "key_path"), "key file")
        if not os.path.isfile(key_path):
            raise _Failed(f"key file not found: {key_path}")
        key = pmwm.read_key(key_path)
        V, F = _read_mesh(ob)
        verdict = pmwm.verify(V, F, key)

        s = context.scene.pmwm
        s.verdict_object = ob.name
        s.verdict_marked = bool(verdict.marked)
        s.verdict_p_value = f"{verdict.p_value:.3g}"
        s.verdict_payload = verdict.payload if verdict.payload is not None else verdict.bits
        s.verdict_matches = f"{verdict.matches}/{len(verdict.bits)}"
        state = "MARKED" if verdict.marked else "not marked"
        found = f"payload '{verdict.payload}'" if verdict.payload is not None else f"bits {verdict.bits}"
        self.report({"INFO"}, f"'{ob.name}' is {state}: p-value {verdict.p_value:.3g}, "
                              f"{verdict.matches}/{len(verdict.bits)} bits match, {found}")
        return {"FINISHED"}


classes = (PMWM_OT_watermark, PMWM_OT_export_pm, PMWM_OT_import_pm, PMWM_OT_verify)


register, unregister = bpy.utils.register_classes_factory(classes)
