"""The add-on's preferences (Edit > Preferences > Add-ons > PM Watermark) and the default key path.

Watermark and Verify work on the first click: with the Key File option empty, the key of an object
is ``//<object name>.pmwm-key.json`` beside a saved .blend, and ``<key folder>/<object name>.pmwm-key.json``
in an unsaved one; the key folder is set here (default ``~/pmwm-keys``, created when a key is written).
"""

from __future__ import annotations

import os
import re

import bpy
from bpy.props import StringProperty
from bpy.types import AddonPreferences

KEY_SUFFIX = ".pmwm-key.json"
DEFAULT_FOLDER = os.path.join("~", "pmwm-keys")


class PMWM_Preferences(AddonPreferences):
    """Where keys go when the .blend is not saved."""

    bl_idname = __package__

    key_folder: StringProperty(
        name="Key Folder",
        description="Folder for the key files of objects in unsaved .blend files (a saved .blend keeps each "
        "key beside it); empty: ~/pmwm-keys",
        subtype="DIR_PATH",
        default="",
    )

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "key_folder", placeholder=DEFAULT_FOLDER)
        layout.label(text=f"Keys of unsaved files go to {key_folder(context)}", icon="INFO")
        layout.label(text="Keep key files secret: whoever holds one can find and remove the mark", icon="LOCKED")


def key_folder(context) -> str:
    """The key folder of the preferences (absolute), or ~/pmwm-keys when none is set."""
    addon = context.preferences.addons.get(__package__)
    folder = getattr(getattr(addon, "preferences", None), "key_folder", "") if addon is not None else ""
    return os.path.abspath(os.path.expanduser(bpy.path.abspath(folder) if folder else DEFAULT_FOLDER))


def file_stem(name: str) -> str:
    """An object name as a safe file name."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "object"


def default_key_path(context, ob) -> str:
    """The key path used when the Key File option is empty: beside the saved .blend (a relative
    ``//`` path), else in the key folder of the preferences."""
    name = file_stem(ob.name) + KEY_SUFFIX
    if bpy.data.filepath:
        return "//" + name
    return os.path.join(key_folder(context), name)


classes = (PMWM_Preferences,)

register, unregister = bpy.utils.register_classes_factory(classes)
