"""Run in fresh processes: install the built extension zip into an isolated BLENDER_USER_RESOURCES.

    BLENDER_USER_RESOURCES=DIR python install_check.py install ZIP
    BLENDER_USER_RESOURCES=DIR python install_check.py use WORKDIR

``install`` installs and enables the zip. ``use`` is a restarted Blender: it enables the installed
extension, imports pmwm, trimesh and scipy, and runs watermark + verify with the installed operators,
with pykdtree out of reach as in a real Blender (the zip does not bundle it; this test's Python has it
installed beside bpy), so that scipy's KD-tree answers, as it does there.
Each prints one line ``RESULT:{json}`` that test_install.py checks. BLENDER_USER_RESOURCES must be
set before ``import bpy`` and a process imports bpy once, hence subprocesses. Blender puts the
wheels' site-packages in front of Python's own only at start-up (an install appends it), so which
``pmwm`` resolves is checked after the restart, as a user would see it.
"""

import json
import os
import sys

MODULE = "bl_ext.user_default.pmwm"


def _common(bpy, addon_utils) -> dict:
    addon_utils._is_first_reset()
    warnings = {k: list(v) for k, v in addon_utils._extensions_warnings_get().items()}
    module = sys.modules.get(MODULE)
    return {
        "enabled": MODULE in bpy.context.preferences.addons,
        "addon_file": getattr(module, "__file__", None),
        "warnings": warnings,
        "has_operators": all(
            hasattr(bpy.types, c)
            for c in (
                "PMWM_OT_watermark",
                "PMWM_OT_export_pm",
                "PMWM_OT_import_pm",
                "PMWM_OT_verify",
                "PMWM_OT_save_report",
            )
        ),
        # the add-on's preferences (the key folder) under the extension's own module name
        "key_folder_pref": hasattr(
            getattr(bpy.context.preferences.addons.get(MODULE), "preferences", None), "key_folder"
        ),
    }


def install(zip_path: str) -> dict:
    import bpy
    import addon_utils  # importable once bpy is

    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    return _common(bpy, addon_utils)


class _NoPykdtree:
    """A meta path finder that refuses pykdtree, as a Blender without it in its Python."""

    def find_spec(self, name, path=None, target=None):
        if name == "pykdtree" or name.startswith("pykdtree."):
            raise ImportError(f"No module named {name!r} (out of reach, as in Blender)")
        return None


def use(workdir: str) -> dict:
    sys.meta_path.insert(0, _NoPykdtree())
    import bpy
    import addon_utils

    bpy.ops.preferences.addon_enable(module=MODULE)
    import numpy
    import pmwm
    import scipy.spatial
    import trimesh

    result = _common(bpy, addon_utils)
    from pmwm import spatial

    result.update(
        pmwm_file=pmwm.__file__,
        trimesh_file=trimesh.__file__,
        numpy_file=numpy.__file__,
        scipy_file=scipy.spatial.__file__,
        kdtree_engine=spatial.engine(),
    )

    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_monkey_add()
    ob = bpy.context.active_object
    mod = ob.modifiers.new("sub", "SUBSURF")
    mod.levels = 2
    bpy.ops.object.modifier_apply(modifier=mod.name)
    key = os.path.join(workdir, "suzanne.key.json")
    try:
        bpy.ops.pmwm.watermark(payload="Hi", key_path=key, seed=7)
        bpy.ops.pmwm.verify(key_path=key)
        v = bpy.context.active_object.pmwm_verdict
        result["verdict"] = {"marked": v.marked, "payload": v.payload}
    except RuntimeError as exc:  # reported by the test
        result["operator_error"] = str(exc)
    return result


if __name__ == "__main__":
    assert os.environ.get("BLENDER_USER_RESOURCES"), "set BLENDER_USER_RESOURCES first"
    out = {"install": install, "use": use}[sys.argv[1]](sys.argv[2])
    print("RESULT:" + json.dumps(out))
