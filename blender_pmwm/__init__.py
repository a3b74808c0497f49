"""PM Watermark: blind mesh watermarking carried by a progressive mesh (Blender extension).

A thin front end to the ``pmwm`` library (bundled as a wheel): the operators move mesh data with
foreach_get/foreach_set and call ``pmwm``; no algorithm lives here.

Scripting API (also usable with ``blender --background --python script.py``)::

    bpy.ops.pmwm.watermark(payload="ACME 2026", key_path="//suzanne.key.json",
                           scheme="robust", strength=2.0, base_ratio=0.03, seed=-1,
                           overwrite_key=False)
    bpy.ops.pmwm.watermark(payload="ACME", scheme="blind", blind_margin=0.0)  # 0: per mesh; the panel's Pass Phrase
    bpy.ops.pmwm.export_pm(filepath="//suzanne.pmwm")
    bpy.ops.pmwm.import_pm(filepath="//suzanne.pmwm", level=-1)   # -1: full resolution
    bpy.ops.pmwm.verify(key_path="//suzanne.key.json")  # the verdict: object.pmwm_verdict (marked, p_value, payload)
    bpy.ops.pmwm.save_report(filepath="//suzanne-report.html")   # after verify: an HTML report
    bpy.ops.pmwm.publish_web(filepath="//suzanne-web")   # a folder with a web page streaming the progressive mesh

The file operators never replace an existing file or folder unless overwrite=True.

An empty key_path is <object name>.pmwm-key.json beside the saved .blend, or in the key folder of the
add-on's preferences. Watermark writes the Mark panel's Key File, Verify reads the Verification panel's.
Clicked in the interface, watermark, verify and save_report run in the background (status bar progress,
Esc cancels); from scripts they run synchronously.

watermark/export_pm/verify act on the active mesh object in Object Mode. Arguments left out of
watermark and verify take the Scene options (``scene.pmwm``). A failure raises RuntimeError with
the error message and leaves the scene unchanged. See examples/watermark_all.py.
"""

import bpy

from . import operators, panel, prefs, props, selection, session


@bpy.app.handlers.persistent
def _forget_session(_dummy=None) -> None:
    # A newly loaded file starts a new session: drop the in-memory watermarks and PM cache.
    session.clear()


_modules = (props, prefs, operators, selection, panel)


def register() -> None:
    for module in _modules:
        module.register()
    bpy.app.handlers.load_pre.append(_forget_session)


def unregister() -> None:
    if _forget_session in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_forget_session)
    for module in reversed(_modules):
        module.unregister()
    session.clear()
