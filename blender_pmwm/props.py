"""Properties: watermark options on the Scene; on the Object, the progressive-mesh level of detail and
the last verdict (for scripts).

Nothing of the key is stored here: only the key file *paths*, the options and the verdict.
"""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

from . import meshdata, session

SCHEME_ITEMS = [
    (
        "robust",
        "Robust",
        "Bumps spread over the surface, read after registration: survives noise, smoothing, "
        "cropping, simplification, re-export and posing (the default)",
    ),
    ("paper", "Paper", "The paper's scheme: one carrier vertex per bit against its 1-ring (for comparison)"),
    (
        "blind",
        "Blind",
        "Read with the Pass Phrase alone: no key file, the payload is read, not known "
        "(keyed waves in the solid's shape)",
    ),
    (
        "blind-histogram",
        "Blind (histogram)",
        "The Blind scheme's baseline carrier, read with the Pass Phrase alone (the distribution of vertex norms): "
        "longer payloads, less robust",
    ),
]


def records_at_level(pm, level: int) -> int:
    """Vertex splits applied at a LoD level: 0 is the base mesh, len(pm.level_records) the full mesh."""
    return 0 if level <= 0 else int(pm.level_records[min(level, len(pm.level_records)) - 1])


def _show_carriers_update(self, context) -> None:
    # On: mark the carriers of the active object's last watermark. Off: remove every such group.
    if self.show_carriers:
        ob = context.active_object
        marked = session.lookup(ob) if ob is not None and ob.type == "MESH" else None
        if marked is not None and ob.mode == "OBJECT":
            meshdata.mark_carriers(ob, marked.carriers)
            print(
                "pmwm: WARNING: the 'pmwm_carriers' vertex group reveals the carriers; "
                "turn 'Show carriers' off before sharing the .blend"
            )
    else:
        for ob in bpy.data.objects:
            if ob.type == "MESH" and ob.mode == "OBJECT":
                meshdata.clear_carriers(ob)


def _lod_update(self, context) -> None:
    # Decode the stored .pmwm at the level and replace the mesh data in place; the Detail slider follows.
    if not self.pm_path:
        return
    if self.level > self.n_levels:
        self.level = self.n_levels  # re-enters this callback once with a valid level
        return
    if self.n_levels and abs(self.detail - 100.0 * self.level / self.n_levels) > 1e-6:
        self["detail"] = 100.0 * self.level / self.n_levels  # (an item write: no update callback)
    ob = self.id_data
    if ob.type != "MESH" or ob.mode != "OBJECT":
        self.status = "leave Edit Mode to change the level of detail"
        return
    try:
        pm = session.load_pm(bpy.path.abspath(self.pm_path))
        V, F = pm.decode(records=records_at_level(pm, self.level))
    except Exception as exc:  # an update callback cannot report: show it in the panel
        self.status = f"cannot read {self.pm_path}: {exc}"
        print(f"pmwm: {self.status}")
        return
    meshdata.set_geometry(ob.data, V, F)
    self.status = ""


def _detail_update(self, context) -> None:
    # The slider (0-100 %) picks the nearest level; the level's update decodes it.
    level = round(self.detail / 100.0 * self.n_levels)
    if level != self.level:
        self.level = level


class PMWM_SceneSettings(PropertyGroup):
    """Options of the Watermark panel (scene.pmwm)."""

    payload: StringProperty(
        name="Payload",
        description="Text to embed (UTF-8), e.g. an owner id; empty embeds 64 random bits from the seed",
        default="",
    )
    key_path: StringProperty(
        name="Key File",
        description="Where Watermark writes the key file; keep it secret. Empty: <object name>.pmwm-key.json "
        "beside the saved .blend, or in the key folder of the add-on's preferences",
        subtype="FILE_PATH",
        default="",
    )
    verify_key_path: StringProperty(
        name="Key File",
        description="The key file Verify reads (not the one Watermark writes). Empty: the active object's "
        "own key, <object name>.pmwm-key.json beside the saved .blend or in the key folder",
        subtype="FILE_PATH",
        default="",
    )
    scheme: EnumProperty(
        name="Scheme",
        description="How the mark is carried",
        items=SCHEME_ITEMS,
        default="robust",
    )
    strength: FloatProperty(
        name="Strength",
        description="How far the mark moves the surface: bump height (robust) or carrier displacement in "
        "neighbour standard deviations (paper). Higher survives more damage and shows more; 2 is "
        "the default",
        default=2.0,
        min=0.01,
        max=100.0,
        soft_min=0.5,
        soft_max=5.0,
    )
    blind_margin: FloatProperty(
        name="Margin",
        description="The Blind (histogram) scheme's strength: how far each bin of vertex distances is pushed from its "
        "middle (Cho's alpha, a fraction of the bin). Higher survives more damage and shows "
        "more; 0 (the default): chosen per mesh to spend a distortion of 0.019 % of the size",
        default=0.0,
        min=0.0,
        max=0.45,
        soft_max=0.2,
        precision=3,
    )
    base_ratio: FloatProperty(
        name="Base Ratio",
        description="Vertices of the progressive mesh's base mesh (its coarsest level, streamed first) "
        "as a fraction of the input",
        default=0.03,
        min=0.0001,
        max=1.0,
        soft_max=0.5,
        precision=3,
    )
    seed: IntProperty(
        name="Seed",
        description="Secret seed for the carrier choice; -1 draws a fresh random one (recorded in the key)",
        default=-1,
        min=-1,
    )
    progressive: BoolProperty(
        name="Progressive Mesh",
        description="Build the progressive mesh while watermarking (Export Progressive Mesh needs it); off: "
        "the same watermark in a fraction of the time, without one",
        default=True,
    )
    overwrite_key: BoolProperty(
        name="Overwrite Key",
        description="Replace an existing key file (the old key can no longer verify anything marked with it)",
        default=False,
    )
    show_carriers: BoolProperty(
        name="Show Carriers",
        description="Mark the carriers of the active object in a temporary vertex group 'pmwm_carriers'. "
        "A .blend saved with it on reveals them",
        default=False,
        update=_show_carriers_update,
    )


class PMWM_ObjectLoD(PropertyGroup):
    """Level-of-detail slider of an object imported from a .pmwm progressive mesh (object.pmwm_lod)."""

    pm_path: StringProperty(name="Progressive Mesh", subtype="FILE_PATH", default="")
    n_levels: IntProperty(name="Levels", default=0, min=0)
    level: IntProperty(
        name="Level",
        description="0 is the base mesh, the highest level the full mesh: refines or coarsens in place",
        default=0,
        min=0,
        update=_lod_update,
    )
    detail: FloatProperty(
        name="Detail",
        description="The level of detail from the base mesh (0 %) to the full mesh (100 %): refines or "
        "coarsens in place, to the nearest level",
        default=100.0,
        min=0.0,
        max=100.0,
        precision=0,
        subtype="PERCENTAGE",
        update=_detail_update,
    )
    status: StringProperty(name="Status", default="")


class PMWM_ObjectVerdict(PropertyGroup):
    """The last verification of an object in this session, for scripts (object.pmwm_verdict); the
    panel shows it in words."""

    verified: BoolProperty(name="Verified", description="Verify ran on this object", default=False)
    marked: BoolProperty(name="Marked", default=False)
    p_value: FloatProperty(name="p-value", default=1.0, min=0.0, max=1.0)
    payload: StringProperty(
        name="Payload", description="The payload read, only when the verdict confirms it", default=""
    )


class PMWM_Secrets(PropertyGroup):
    """What must never reach the .blend (window_manager.pmwm_secrets): the blind scheme's pass phrase.
    Window-manager properties are not saved with the file, and ``_forget_on_save`` empties it before
    any save anyway."""

    passphrase: StringProperty(
        name="Pass Phrase",
        description="Blind scheme: the secret that marks and reads; the same phrase may mark many meshes. "
        "Never saved in the .blend",
        subtype="PASSWORD",
        default="",
        options={"SKIP_SAVE"},
    )


def passphrase(context) -> str:
    """The pass phrase typed in this session ("" if none)."""
    secrets = getattr(context.window_manager, "pmwm_secrets", None)
    return secrets.passphrase if secrets is not None else ""


_kept: list[str] = []


@bpy.app.handlers.persistent
def _forget_on_save(*_args) -> None:
    for wm in bpy.data.window_managers:
        _kept.append(wm.pmwm_secrets.passphrase)
        wm.pmwm_secrets.passphrase = ""


@bpy.app.handlers.persistent
def _restore_after_save(*_args) -> None:
    for wm, phrase in zip(bpy.data.window_managers, list(_kept)):
        wm.pmwm_secrets.passphrase = phrase
    _kept.clear()


classes = (PMWM_SceneSettings, PMWM_ObjectLoD, PMWM_ObjectVerdict, PMWM_Secrets)


def register() -> None:
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.pmwm = PointerProperty(type=PMWM_SceneSettings)
    bpy.types.Object.pmwm_lod = PointerProperty(type=PMWM_ObjectLoD)
    bpy.types.Object.pmwm_verdict = PointerProperty(type=PMWM_ObjectVerdict)
    bpy.types.WindowManager.pmwm_secrets = PointerProperty(type=PMWM_Secrets)
    bpy.app.handlers.save_pre.append(_forget_on_save)
    bpy.app.handlers.save_post.append(_restore_after_save)


def unregister() -> None:
    for handlers, fn in (
        (bpy.app.handlers.save_pre, _forget_on_save),
        (bpy.app.handlers.save_post, _restore_after_save),
    ):
        if fn in handlers:
            handlers.remove(fn)
    del bpy.types.WindowManager.pmwm_secrets
    del bpy.types.Object.pmwm_verdict
    del bpy.types.Object.pmwm_lod
    del bpy.types.Scene.pmwm
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
