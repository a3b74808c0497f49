"""Operators on a selection: pmwm.watermark_selected marks every selected mesh object as one asset (one key
file, or the Pass Phrase, for all of them; one undo step) and pmwm.verify_selected reads the selected objects
against the key of an asset, the key of one object, or the Pass Phrase.

The work is ``pmwm.scene``'s (``embed_objects``: one master secret, the same payload in every object;
``verify_objects``: every object against every object key, the union bound paid, the objects read named in
the verdict). As for one object, the tasks read the meshes first, compute without bpy, and change the scene
only at the end, after checking that no selected object changed meanwhile: all of them or none.
"""

from __future__ import annotations

import os

import bpy
from bpy.types import Operator

from . import meshdata, props, session, verdictwords
from .operators import (
    apply_marked,
    VerifyOptions,
    VerifyTask,
    WatermarkOptions,
    WatermarkTask,
    _BackgroundOperator,
    _Failed,
    _key_path,
    _mesh_problem,
    _poll_mesh,
    _read_mesh,
    _uses_passphrase,
    still_there,
)


def _selected_meshes(context) -> tuple[list, dict]:
    """The selected mesh objects, by name, one per mesh datablock (objects sharing a mesh are one object of
    the asset, marked once), and {name of each: names of the other selected objects sharing its mesh};
    _Failed naming the way out when there is none or one cannot be used now."""
    obs = sorted((ob for ob in context.selected_objects if ob.type == "MESH"), key=lambda ob: ob.name)
    if not obs:
        raise _Failed("no mesh object selected: select the mesh objects of the asset")
    for ob in obs:
        problem = _mesh_problem(ob)
        if problem:
            raise _Failed(problem)
    one_per_mesh, sharing = {}, {}
    for ob in obs:
        first = one_per_mesh.setdefault(ob.data.as_pointer(), ob)
        sharing.setdefault(first.name, []).extend([ob.name] if ob is not first else [])
    return list(one_per_mesh.values()), sharing


class _Selection:
    """What a selection task read: per object (name, pointer, vertices (n, 3) float64, triangles (m, 3),
    positions (n, 3) float32 as stored)."""

    def _remember_selection(self, context) -> None:
        obs, self.sharing = _selected_meshes(context)
        self.items = [(ob.name, ob.as_pointer(), *_read_mesh(ob), meshdata.read_positions32(ob.data)) for ob in obs]
        self.name = f"{len(obs)} selected objects"  # (the status bar's and the busy marker's words)
        active = context.active_object
        self.pointer = (active if active in obs else obs[0]).as_pointer()

    def objects(self) -> list:
        return [(name, V, F) for name, _, V, F, _ in self.items]

    def current_objects(self) -> list:
        """Every object read, each checked unchanged before any is written (_Failed otherwise)."""
        return [still_there(name, pointer, p32, F, self.verb) for name, pointer, _, F, p32 in self.items]


class WatermarkSelectedTask(_Selection, WatermarkTask):
    """pmwm.watermark_selected: every selected mesh object marked as one asset."""

    def __init__(self, context, **options):
        super().__init__(context, **options)  # the options, the key path (named for the active object)
        self._remember_selection(context)

    def compute(self, progress):
        from pmwm.scene import embed_objects

        return embed_objects(self.objects(), self.opts, progress=progress)

    def finish(self, context, marking, report):
        from pmwm.scene import write_keys

        obs = self.current_objects()
        if marking.key is not None:
            if self.make_folder:
                os.makedirs(os.path.dirname(self.key_path), exist_ok=True)
            write_keys(self.key_path, marking.key, overwrite=self.overwrite)
        for ob, res in zip(obs, marking.results):
            apply_marked(ob, res)
        where = "no key file (the pass phrase reads it)" if self.blind else f"key written to {self.key_path}"
        vsnr = ", ".join(f"{ob.name} {res.vsnr_db:.1f} dB" for ob, res in zip(obs, marking.results))
        report(
            {"INFO"},
            f"Watermarked {len(obs)} objects as one asset: {len(marking.results[0].bits)} bits in "
            f"each (VSNR {vsnr}); {where}",
        )
        for ob, res in zip(obs, marking.results):
            for note in res.notes:
                report({"WARNING"}, f"'{ob.name}': {note}")


class VerifySelectedTask(_Selection, VerifyTask):
    """pmwm.verify_selected: the selected objects read against the key's object keys (or the Pass Phrase);
    the verdict, which names the objects where the mark was read, goes to every selected object."""

    def __init__(self, context, key_path: str = ""):
        from pmwm.atomic import file_sha256
        from pmwm.scene import read_keys

        self.passphrase, self.keys, self.key_path, self.key_sha256 = None, None, "", ""
        if _uses_passphrase(context.scene.pmwm.scheme):
            self.passphrase = props.passphrase(context)
            if not self.passphrase:
                raise _Failed("the Blind scheme needs a Pass Phrase: type it in the Mark panel")
        else:
            active = context.active_object
            self.key_path, _ = _key_path(context, active, key_path)
            if not os.path.isfile(self.key_path):
                raise _Failed(
                    f"key file not found: {self.key_path}: set Key File (Verification) to the key "
                    "written when the objects were watermarked"
                )
            self.keys = read_keys(self.key_path)
            self.key_sha256 = file_sha256(self.key_path)
        self._remember_selection(context)

    def compute(self, progress):
        from pmwm.scene import verify_objects

        progress(0.0, f"reading {len(self.items)} objects")
        return verify_objects(self.objects(), self.keys, passphrase=self.passphrase)

    def finish(self, context, verdict, report):
        obs = self.current_objects()
        read = {s: p for s, _, p in getattr(verdict.detail, "found", ())}
        # one object read with one key: a report can cite that key, as for Verify
        key = self.keys[0][1] if self.keys is not None and len(self.keys) == 1 and len(obs) == 1 else None
        for first, (_, _, _, F, p32) in zip(obs, self.items):
            mine = first.name in read if read else verdict.marked
            for ob in [first, *(bpy.data.objects[n] for n in self.sharing[first.name])]:  # (one mesh)
                session.remember_verified(
                    ob,
                    session.Verified(
                        name=ob.name,
                        verdict=verdict,
                        key=key,
                        key_path=self.key_path,
                        key_sha256=self.key_sha256,
                        positions=p32,
                        faces=F,
                    ),
                )
                record = ob.pmwm_verdict
                record.verified, record.marked = True, bool(mine)
                record.p_value = min(max(float(read.get(first.name, verdict.p_value)), 0.0), 1.0)
                record.payload = verdictwords.confirmed_payload(verdict) if mine else ""
        report({"INFO"}, f"{len(obs)} selected objects read: {verdictwords.report_line(verdict)}")


def _poll_selection(cls, context) -> bool:
    if not _poll_mesh(cls, context):
        return False
    if not any(ob.type == "MESH" for ob in context.selected_objects):
        cls.poll_message_set("no mesh object selected: select the mesh objects of the asset")
        return False
    return True


class PMWM_OT_watermark_selected(WatermarkOptions, _BackgroundOperator, Operator):
    """Watermark every selected mesh object as one asset: one key file (or the pass phrase) for all, one undo
    step"""

    bl_idname = "pmwm.watermark_selected"
    bl_label = "Watermark Selected"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _poll_selection(cls, context)

    def make_task(self, context):
        return WatermarkSelectedTask(context, **self.run_options(context))


class PMWM_OT_verify_selected(VerifyOptions, _BackgroundOperator, Operator):
    """Verify the selected mesh objects against the key of an asset (or of one object), or the pass
    phrase: the verdict names the objects where the mark was read"""

    bl_idname = "pmwm.verify_selected"
    bl_label = "Verify Selected"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return _poll_selection(cls, context)

    def make_task(self, context):
        if _uses_passphrase(context.scene.pmwm.scheme):
            return VerifySelectedTask(context)
        return VerifySelectedTask(context, key_path=self.option(context, "key_path", "verify_key_path"))


classes = (PMWM_OT_watermark_selected, PMWM_OT_verify_selected)

register, unregister = bpy.utils.register_classes_factory(classes)
