"""Operators: pmwm.watermark, pmwm.export_pm, pmwm.import_pm, pmwm.verify, pmwm.save_report, pmwm.publish_web.

Each one reads its options, moves mesh data with foreach_get/foreach_set, calls ``pmwm`` and turns
``pmwm.PmwmError`` into ``self.report({'ERROR'}, ...)`` + ``{'CANCELLED'}``. Everything is computed
first and written back only on success, so a failure leaves the object and the scene as they were.
``pmwm`` is imported inside the operators to keep Blender's start-up fast.

Watermark, Verify and Save Report run in three steps (a *task*): prepare (main thread: options, checks,
mesh data read with foreach_get), compute (``pmwm.embed`` / ``pmwm.verify`` / the report's HTML on numpy
arrays, no bpy), finish (main thread: key file, write-back, verdict, report file). ``execute`` (scripts,
``--background``) runs them in a row. Invoked from the interface, the compute step runs in a worker
thread (``jobs.BackgroundJob``) driven by a modal operator with a timer (``ModalRun``): progress in the
status bar and the panel, Esc cancels (the core unwinds at its next progress call; the object is
untouched: nothing is written before finish), and finish, the only step that changes the scene or
writes a file, runs on the main thread at the end, as one undo step.

Scripting API (``blender --background --python script.py``): the keyword arguments of watermark
and verify override the Scene options (``scene.pmwm``); arguments left out take the Scene's values;
an empty key path is the default key path (``prefs.default_key_path``). The file operators never
replace an existing file unless ``overwrite`` is on (*Replace Existing* in the file browser). watermark
and verify work on the base mesh in object space (``object.data``: modifiers and the object transform are not applied),
the data an exporter writes when both are neutral.
"""

from __future__ import annotations

import os
import traceback
from contextlib import contextmanager

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ExportHelper, ImportHelper

from . import meshdata, prefs, props, session, verdictwords
from .jobs import BackgroundJob
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


def _mesh_problem(ob) -> str | None:
    """Why ``ob`` cannot be watermarked or verified now (a one-line reason with the way out), or None."""
    if ob is None:
        return "no active object: select a mesh object"
    if ob.type != "MESH":
        return f"'{ob.name}' is a {ob.type.lower()} object, not a mesh: select a mesh object"
    if ob.mode != "OBJECT":
        return f"'{ob.name}' is in {ob.mode.replace('_', ' ').title()} Mode: switch to Object Mode first"
    what = session.busy(ob)
    if what:
        return f"'{ob.name}' is being {what}: wait for it to finish, or press Esc to cancel it"
    return None


def _active_mesh(context):
    """The active object if it is a mesh in Object Mode; else raise _Failed naming the way out."""
    ob = context.active_object
    problem = _mesh_problem(ob)
    if problem:
        raise _Failed(problem)
    return ob


def _poll_mesh(cls, context) -> bool:
    problem = _mesh_problem(context.active_object)
    if problem:
        cls.poll_message_set(problem)
        return False
    return True


NOT_WATERMARKED = "'{}' was not watermarked in this session: watermark this object first"
NOT_VERIFIED = "'{}' was not verified in this session: verify this object first"
NOT_REPORTABLE = (
    "'{}' was read with the pass phrase: a report needs a key file to cite; verify it with a Robust or Paper key"
)
CHANGED_SINCE_VERIFIED = "'{}' changed since it was verified: verify it again"


def _poll_remembered(cls, context, lookup, message: str) -> bool:
    """Poll of an operator that needs what this session remembers of the active mesh (``lookup``);
    a greyed-out button says ``message`` (formatted with the object's name) when there is none."""
    if not _poll_mesh(cls, context):
        return False
    if lookup(context.active_object) is None:
        cls.poll_message_set(message.format(context.active_object.name))
        return False
    return True


def _poll_reportable(cls, context) -> bool:
    """Save Report: the active object's last verification, with a key file, of the mesh it holds now."""
    if not _poll_remembered(cls, context, session.lookup_verified, NOT_VERIFIED):
        return False
    ob = context.active_object
    rec = session.lookup_verified(ob)
    if not rec.reportable:
        cls.poll_message_set(NOT_REPORTABLE.format(ob.name))
        return False
    if not session.looks_unchanged(ob.data, rec.positions):
        cls.poll_message_set(CHANGED_SINCE_VERIFIED.format(ob.name))
        return False
    return True


def _remembered(ob, lookup, message: str):
    """What this session remembers of ``ob`` (``lookup``), or _Failed with ``message``."""
    found = lookup(ob)
    if found is None:
        raise _Failed(message.format(ob.name))
    return found


def _read_mesh(ob):
    """(vertices, triangles) of the object's base mesh; _Failed when it has no faces."""
    V = meshdata.read_positions(ob.data)
    F = meshdata.read_triangles(ob.data)
    if len(V) == 0 or len(F) == 0:
        raise _Failed(f"'{ob.name}' has no faces: nothing to watermark or verify")
    return V, F


def _file_path(raw: str, what: str) -> str:
    if not raw:
        raise _Failed(f"no {what} path given: choose a file")
    return os.path.abspath(bpy.path.abspath(raw))


def _key_path(context, ob, raw: str) -> tuple[str, bool]:
    """(absolute key path, True when it is the default path in the preferences' key folder)."""
    if raw:
        return os.path.abspath(bpy.path.abspath(raw)), False
    path = prefs.default_key_path(context, ob)
    return os.path.abspath(bpy.path.abspath(path)), not path.startswith("//")


def apply_marked(ob, res) -> None:
    """Write a marked result's positions into the object's base mesh and remember the watermark for this
    session (Export, Publish for Web, Show Carriers)."""
    meshdata.write_base_positions(ob.data, res.vertices)
    session.remember(
        ob,
        session.Marked(
            name=ob.name,
            pm=res.pm,
            carriers=res.carriers,
            positions=meshdata.read_positions32(ob.data),
            n_bits=len(res.bits),
            vsnr_db=float(res.vsnr_db),
        ),
    )


def _uses_passphrase(scheme: str) -> bool:
    """True for a scheme marked and read with the Pass Phrase alone (no key file)."""
    import pmwm

    return pmwm.SCHEMES[scheme].keying == pmwm.PASS_PHRASE


def default_file(context, ob, suffix: str) -> str:
    """A new file's suggested path, named for ``ob``: beside the saved .blend, or the bare name (the file
    browser's current folder) in an unsaved one; "-2", "-3", ... before the suffix while the name is taken."""
    folder = os.path.dirname(bpy.data.filepath) if bpy.data.filepath else ""
    stem = prefs.file_stem(ob.name) if ob is not None else "untitled"
    for n in range(1, 1000):
        path = os.path.join(folder, stem + ("" if n == 1 else f"-{n}") + suffix)
        if not folder or not os.path.exists(path):
            return path
    return path


def _check_new(path: str, overwrite: bool) -> None:
    """_Failed when ``path`` exists and Replace Existing is off."""
    if os.path.exists(path) and not overwrite:
        raise _Failed(
            f"{path} exists: tick Replace Existing in the file browser (overwrite=True in scripts), "
            "or choose another name"
        )


REPLACE = dict(
    name="Replace Existing",
    description="Replace the file if it exists (its name shows red in the file browser)",
    default=False,
    options={"SKIP_SAVE"},
)


# ----------------------------------------------------------------------------- tasks


class _Task:
    """One Watermark or Verify run: prepared on the main thread (``__init__``), computed anywhere
    (``compute``, numpy and pmwm only), finished on the main thread (``finish``, the only step that
    changes the scene or writes a file)."""

    verb = ""  # "watermarked" / "verified"
    doing = ""  # "watermarking" / "verifying"

    def _remember_mesh(self, ob) -> None:
        self.name = ob.name
        self.pointer = ob.as_pointer()
        self.V, self.F = _read_mesh(ob)
        self.positions32 = meshdata.read_positions32(ob.data)

    def compute(self, progress):
        raise NotImplementedError

    def finish(self, context, result, report):
        raise NotImplementedError

    def current_object(self):
        """The object this task read, if it still holds exactly the mesh that was read; else _Failed
        (the user may edit, undo or delete while the worker runs)."""
        return still_there(self.name, self.pointer, self.positions32, self.F, self.verb)


def still_there(name: str, pointer: int, positions32: np.ndarray, F: np.ndarray, verb: str):
    """The object ``name`` if it is the one read (``pointer``) and still holds exactly that mesh, its
    positions (n, 3) float32 and triangles (m, 3); else _Failed saying nothing was written."""
    ob = bpy.data.objects.get(name)
    same = (
        ob is not None
        and ob.as_pointer() == pointer
        and ob.type == "MESH"
        and ob.mode == "OBJECT"
        and session.same_positions(positions32, meshdata.read_positions32(ob.data))
        and np.array_equal(meshdata.read_triangles(ob.data), F)
    )
    if not same:
        raise _Failed(f"'{name}' changed while it was being {verb}: nothing was written; run it again")
    return ob


class WatermarkTask(_Task):
    """pmwm.watermark: embed into the active object's base mesh, write its key file."""

    verb, doing = "watermarked", "watermarking"

    def __init__(
        self,
        context,
        payload: str = "",
        key_path: str = "",
        scheme: str = "robust",
        strength: float = 2.0,
        base_ratio: float = 0.03,
        seed: int = -1,
        overwrite_key: bool = False,
        blind_margin: float = 0.0,
        progressive: bool = True,
    ):
        import pmwm

        ob = _active_mesh(context)
        self.blind = _uses_passphrase(scheme)
        if self.blind:
            phrase = props.passphrase(context)
            if not phrase:
                raise _Failed("the Blind scheme needs a Pass Phrase: type it in the Mark panel")
            self._remember_mesh(ob)
            self.key_path = ""
            # the Margin is the histogram carrier's strength (0: chosen per mesh); keyed waves choose their own
            margin = (round(float(blind_margin), 6) or None) if scheme == "blind-histogram" else None
            self.opts = pmwm.EmbedOptions(
                payload=payload or None,
                strength=margin,
                base_ratio=float(base_ratio),
                seed=None if seed < 0 else int(seed),
                scheme=scheme,
                passphrase=phrase,
                progressive=bool(progressive),
            )
            return
        self.key_path, self.make_folder = _key_path(context, ob, key_path)
        self.overwrite = bool(overwrite_key)
        if os.path.isdir(self.key_path):
            raise _Failed(f"key file path is a folder: {self.key_path}")
        if os.path.exists(self.key_path) and not self.overwrite:
            raise _Failed(f"key file exists: {self.key_path}: choose another path or enable Overwrite Key")
        folder = os.path.dirname(self.key_path)
        if not self.make_folder and not os.path.isdir(folder):
            raise _Failed(f"folder does not exist: {folder}")
        if self.make_folder and os.path.exists(folder) and not os.path.isdir(folder):
            raise _Failed(f"the key folder {folder} is a file: set another Key Folder in the add-on's preferences")
        self._remember_mesh(ob)
        self.opts = pmwm.EmbedOptions(
            payload=payload or None,
            strength=float(strength),
            base_ratio=float(base_ratio),
            seed=None if seed < 0 else int(seed),
            scheme=scheme,
            progressive=bool(progressive),
        )

    def compute(self, progress):
        import pmwm

        return pmwm.embed(self.V, self.F, self.opts, progress=progress)

    def finish(self, context, res, report):
        import pmwm

        ob = self.current_object()
        if res.key is not None:
            if self.make_folder:
                os.makedirs(os.path.dirname(self.key_path), exist_ok=True)
            pmwm.write_key(self.key_path, res.key, overwrite=self.overwrite)

        # Success: write back (nothing before this touched the scene).
        mesh = ob.data
        apply_marked(ob, res)
        if ob.modifiers or mesh.shape_keys is not None:
            report(
                {"WARNING"},
                f"'{ob.name}' has modifiers or shape keys: the base mesh was watermarked; "
                "apply topology-changing modifiers before watermarking to mark what you ship",
            )
        if context.scene.pmwm.show_carriers:
            meshdata.mark_carriers(ob, res.carriers)
            report(
                {"WARNING"},
                "carriers are in vertex group 'pmwm_carriers': turn Show Carriers off before sharing the .blend",
            )
        where = "no key file (the pass phrase reads it)" if self.blind else f"key written to {self.key_path}"
        carriers = f"{len(res.carriers)} carriers, " if len(res.carriers) else ""
        report({"INFO"}, f"Watermarked '{ob.name}': {len(res.bits)} bits, {carriers}VSNR {res.vsnr_db:.1f} dB; {where}")
        for note in res.notes:  # (e.g. the Blind scheme marked it with its baseline carrier, and why)
            report({"WARNING"}, note)


class VerifyTask(_Task):
    """pmwm.verify: read the mark from the active object with a key file, or with the Pass Phrase (the
    Scheme chosen in Mark reads with one); the verdict goes to the object and the panel."""

    verb, doing = "verified", "verifying"

    def __init__(self, context, key_path: str = ""):
        import pmwm

        ob = _active_mesh(context)
        self.passphrase = None
        if _uses_passphrase(context.scene.pmwm.scheme):
            phrase = props.passphrase(context)
            if not phrase:
                raise _Failed("the Blind scheme needs a Pass Phrase: type it in the Mark panel")
            # (its secret is derived by pmwm.verify, beside the reading, off the interface's thread)
            self.key, self.passphrase = None, phrase
            self.key_path = self.key_sha256 = ""
            self._remember_mesh(ob)
            return
        self.key_path, _ = _key_path(context, ob, key_path)
        if not os.path.isfile(self.key_path):
            raise _Failed(
                f"key file not found: {self.key_path}: set Key File (Verification) to the key "
                "written when this object was watermarked"
            )
        from pmwm.atomic import file_sha256

        self.key = pmwm.read_key(self.key_path)
        self.key_sha256 = file_sha256(self.key_path)
        self._remember_mesh(ob)

    def compute(self, progress):
        import pmwm

        return pmwm.verify(self.V, self.F, self.key, passphrase=self.passphrase, progress=progress)

    def finish(self, context, verdict, report):
        ob = self.current_object()
        session.remember_verified(
            ob,
            session.Verified(
                name=ob.name,
                verdict=verdict,
                key=self.key,
                key_path=self.key_path,
                key_sha256=self.key_sha256,
                positions=self.positions32,
                faces=self.F,
            ),
        )
        record = ob.pmwm_verdict
        record.verified, record.marked = True, bool(verdict.marked)
        record.p_value = min(max(float(verdict.p_value), 0.0), 1.0)
        record.payload = verdictwords.confirmed_payload(verdict)
        how = " with the pass phrase" if self.key is None else ""
        report({"INFO"}, f"'{ob.name}' read{how}: {verdictwords.report_line(verdict)}")


class ReportTask(_Task):
    """pmwm.save_report: the HTML report of the active object's last verification (with a key file)."""

    verb, doing = "reported", "saving the report of"

    def __init__(self, context, filepath: str, overwrite: bool = False):
        from pmwm.atomic import file_sha256

        ob = _active_mesh(context)
        rec = _remembered(ob, session.lookup_verified, NOT_VERIFIED)
        if not rec.reportable:
            raise _Failed(NOT_REPORTABLE.format(ob.name))
        if not (
            session.same_positions(rec.positions, meshdata.read_positions32(ob.data))
            and np.array_equal(meshdata.read_triangles(ob.data), rec.faces)
        ):
            raise _Failed(CHANGED_SINCE_VERIFIED.format(ob.name))
        if not os.path.isfile(rec.key_path) or file_sha256(rec.key_path) != rec.key_sha256:
            raise _Failed(f"the key file {rec.key_path} changed or went away since the verification: verify again")
        path = _file_path(filepath, "report")
        if not path.lower().endswith((".html", ".htm")):
            raise _Failed(f"{path}: give the report an .html name")
        if os.path.realpath(path) == os.path.realpath(rec.key_path):
            raise _Failed(f"{path} is the key file: choose another name for the report")
        if os.path.isdir(path):
            raise _Failed(f"{path} is a folder: give the report a file name")
        _check_new(path, overwrite)
        self.path, self.overwrite, self.rec = path, bool(overwrite), rec
        self.name, self.pointer = ob.name, ob.as_pointer()
        self.positions32, self.F = rec.positions, rec.faces
        blend = os.path.basename(bpy.data.filepath) if bpy.data.filepath else "an unsaved .blend"
        self.suspect = f"Blender object '{ob.name}' in {blend}"

    def compute(self, progress):
        from pmwm.verify_report import build_report

        progress(0.0, "drawing the pictures")
        rec = self.rec
        return build_report(
            rec.verdict,
            rec.key,
            rec.positions,
            rec.faces,
            key_path=rec.key_path,
            suspect_name=self.suspect,
            progress=progress,
        )

    def finish(self, context, text, report):
        from pmwm.atomic import atomic_write_bytes

        _check_new(self.path, self.overwrite)  # (a file may have appeared meanwhile)
        atomic_write_bytes(self.path, text.encode("utf-8"), force=self.overwrite)
        report({"INFO"}, f"Report on '{self.name}' written to {self.path}")


class ModalRun:
    """The modal path of one task: ``start`` puts its compute step in a worker thread; ``step`` is
    called for each event: Esc cancels, a timer tick shows the progress, and once the worker is done
    the task is finished on this (the main) thread. No window-manager calls here (the operator adds
    the timer and the handler), so the steps can be driven headless."""

    def __init__(self, task: _Task, report):
        self.task = task
        self.report = report
        self.job = BackgroundJob(task.compute)
        self.status_text: str | None = None
        self.finished = False

    def start(self, context) -> None:
        session.set_busy(self.task.pointer, self.task.verb)
        self.job.start()
        self._show(context)

    def _status(self, context, text: str | None) -> None:
        self.status_text = text
        workspace = getattr(context, "workspace", None)
        if workspace is not None and getattr(context, "window", None) is not None:
            workspace.status_text_set(text)

    def progress_text(self) -> str:
        """What runs: its percentage, stage and the seconds it has run (these move even while a stage reports
        nothing)."""
        job = self.job
        parts = [f"{int(100 * job.fraction)}%"]
        parts += [job.message] if job.message else []
        parts.append(f"{job.elapsed:.0f} s")
        return ", ".join(parts)

    def _show(self, context) -> None:
        session.set_progress(self.task.pointer, self.progress_text())
        self._status(
            context, f"{self.task.doing.capitalize()} '{self.task.name}': {self.progress_text()} (Esc to cancel)"
        )

    def _end(self, context) -> None:
        session.set_busy(self.task.pointer, None)
        self._status(context, None)

    def cancel(self, context) -> None:
        """Stop: the worker unwinds at its next progress call, its result is dropped."""
        self.job.cancel()
        self._end(context)

    def step(self, context, event_type: str) -> set:
        if event_type == "ESC":
            self.cancel(context)
            self.report(
                {"WARNING"}, f"{self.task.doing.capitalize()} '{self.task.name}' cancelled: nothing was changed"
            )
            return {"CANCELLED"}
        if not self.job.done:
            if event_type == "TIMER":
                self._show(context)
                return {"RUNNING_MODAL"}
            return {"PASS_THROUGH"}  # the rest of the interface keeps working
        self._end(context)
        if self.job.error is not None:
            raise self.job.error
        if self.job.cancelled:
            return {"CANCELLED"}
        self.task.finish(context, self.job.result, self.report)
        self.finished = True
        return {"FINISHED"}


# ----------------------------------------------------------------------------- operators


class _PmwmOperator:
    """Shared execute wrapper: every failure becomes an ERROR report and CANCELLED."""

    def execute(self, context):
        return self._guard(self.run, context)

    def _guard(self, fn, *args):
        import pmwm

        try:
            return fn(*args)
        except (_Failed, pmwm.PmwmError) as exc:
            self.report({"ERROR"}, str(exc))
        except OSError as exc:
            self.report({"ERROR"}, f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": "))
        except Exception as exc:  # a bug: keep Blender alive, leave the scene as it was
            traceback.print_exc()
            self.report({"ERROR"}, f"pmwm internal error ({type(exc).__name__}: {exc}); see the system console")
        return {"CANCELLED"}

    def option(self, context, name, scene_name=None):
        """The operator argument when given, else the Scene option ``scene_name`` (default: the same name).

        The value used is stored back in the operator, so the redo panel shows what ran.
        """
        if self.properties.is_property_set(name):
            return getattr(self, name)
        value = getattr(context.scene.pmwm, scene_name or name)
        setattr(self, name, value)
        return value


class _BackgroundOperator(_PmwmOperator):
    """execute: the task's three steps in a row. invoke (a click in the interface): compute in a worker
    thread under a modal operator (``ModalRun``); without a window it falls back to execute."""

    def make_task(self, context) -> _Task:
        raise NotImplementedError

    def run(self, context):
        task = self.make_task(context)
        with _progress(context) as progress:
            result = task.compute(progress)
        task.finish(context, result, self.report)
        return {"FINISHED"}

    def invoke(self, context, event):
        return self._in_background(context)

    def _in_background(self, context):
        if bpy.app.background or context.window is None:
            return self._guard(self.run, context)
        return self._guard(self._start, context)

    def _start(self, context):
        self._run = ModalRun(self.make_task(context), self.report)
        self._run.start(context)
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _stop_timer(self, context) -> None:
        if getattr(self, "_timer", None) is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None

    @staticmethod
    def _redraw_sidebars(context) -> None:
        for area in context.screen.areas if context.screen else ():
            if area.type == "VIEW_3D":
                area.tag_redraw()

    def modal(self, context, event):
        result = self._guard(self._run.step, context, event.type)
        if result not in ({"RUNNING_MODAL"}, {"PASS_THROUGH"}):
            if not self._run.finished and not self._run.job.done:
                self._run.cancel(context)
            self._run._end(context)
            self._stop_timer(context)
        if event.type == "TIMER" or result not in ({"RUNNING_MODAL"}, {"PASS_THROUGH"}):
            self._redraw_sidebars(context)  # the panel's progress line and, at the end, the verdict
        return result

    def cancel(self, context):  # Blender ends the modal operator (a file is loaded, the file browser closed)
        if getattr(self, "_run", None) is not None:
            self._run.cancel(context)
        self._stop_timer(context)


class WatermarkOptions:
    """The options of Watermark (and Watermark Selected), its redo panel (a mixin: Blender registers the
    properties of each operator class that inherits them)."""

    payload: StringProperty(name="Payload", description="Text to embed; empty: 64 random bits", options={"SKIP_SAVE"})
    key_path: StringProperty(
        name="Key File",
        description="Empty: <object name>.pmwm-key.json beside the .blend, or in the key folder of the preferences",
        subtype="FILE_PATH",
        options={"SKIP_SAVE"},
    )
    scheme: EnumProperty(name="Scheme", items=SCHEME_ITEMS, default="robust", options={"SKIP_SAVE"})
    strength: FloatProperty(name="Strength", default=2.0, min=0.01, max=100.0, options={"SKIP_SAVE"})
    base_ratio: FloatProperty(name="Base Ratio", default=0.03, min=0.0001, max=1.0, options={"SKIP_SAVE"})
    seed: IntProperty(name="Seed", description="-1: a fresh random secret", default=-1, min=-1, options={"SKIP_SAVE"})
    overwrite_key: BoolProperty(name="Overwrite Key", default=False, options={"SKIP_SAVE"})
    blind_margin: FloatProperty(
        name="Margin",
        description="The Blind (histogram) scheme's strength (Cho's alpha); "
        "0: chosen per mesh for a distortion of 0.019 % of the size",
        default=0.0,
        min=0.0,
        max=0.45,
        options={"SKIP_SAVE"},
    )
    progressive: BoolProperty(
        name="Progressive Mesh",
        description="Build the progressive mesh (Export Progressive Mesh needs it)",
        default=True,
        options={"SKIP_SAVE"},
    )

    SHARED = ("payload", "scheme", "base_ratio", "seed", "progressive")
    KEY_FILE = ("key_path", "overwrite_key", "strength")  # only with a scheme that writes a key file
    PASS_PHRASE = ("blind_margin",)  # only with the Blind scheme

    @classmethod
    def options_for(cls, scheme: str) -> tuple:
        """The options a run with ``scheme`` reads (and its redo panel shows)."""
        return cls.SHARED + (cls.PASS_PHRASE if _uses_passphrase(scheme) else cls.KEY_FILE)

    def run_options(self, context) -> dict:
        """The options of this run (the operator's arguments, else the Scene's), by name."""
        return {n: self.option(context, n) for n in self.options_for(self.option(context, "scheme"))}

    def draw(self, context):  # the redo panel: the options this run used, no key path for the Blind scheme
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        for name in self.options_for(self.scheme):
            layout.prop(self, name)


class PMWM_OT_watermark(WatermarkOptions, _BackgroundOperator, Operator):
    """Watermark the active mesh object and write its key file"""

    bl_idname = "pmwm.watermark"
    bl_label = "Watermark"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _poll_mesh(cls, context)

    def make_task(self, context):
        return WatermarkTask(context, **self.run_options(context))


class VerifyOptions:
    """The option of Verify (and Verify Selected), a mixin as ``WatermarkOptions``."""

    key_path: StringProperty(
        name="Key File",
        description="Empty: the object's own key, <object name>"
        ".pmwm-key.json beside the .blend, or in the key folder of the preferences",
        subtype="FILE_PATH",
        options={"SKIP_SAVE"},
    )


class PMWM_OT_verify(VerifyOptions, _BackgroundOperator, Operator):
    """Verify whether the active mesh object carries the watermark of a key file"""

    bl_idname = "pmwm.verify"
    bl_label = "Verify"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return _poll_mesh(cls, context)

    def make_task(self, context):
        if _uses_passphrase(context.scene.pmwm.scheme):
            return VerifyTask(context)
        return VerifyTask(context, key_path=self.option(context, "key_path", "verify_key_path"))


class _FileOperator(_PmwmOperator):
    """A file browser suggesting a new name for the active object (``suffix``), never replacing a file
    unless Replace Existing is ticked (the file browser shows the name red when it exists)."""

    suffix = ""

    def invoke(self, context, event):
        self.filepath = default_file(context, context.active_object, self.suffix)
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def draw(self, context):  # the file browser's side panel
        self.layout.prop(self, "overwrite")


class PMWM_OT_export_pm(_FileOperator, Operator, ExportHelper):
    """Write the progressive mesh of the active object's last watermark (this session) to a .pmwm file"""

    bl_idname = "pmwm.export_pm"
    bl_label = "Export Progressive Mesh"
    bl_options = {"REGISTER"}

    filename_ext = suffix = ".pmwm"
    filter_glob: StringProperty(default="*.pmwm", options={"HIDDEN"})
    filepath: StringProperty(name="File Path", subtype="FILE_PATH", options={"SKIP_SAVE"})
    overwrite: BoolProperty(**REPLACE)

    @classmethod
    def poll(cls, context):
        return _poll_remembered(cls, context, session.lookup, NOT_WATERMARKED)

    def run(self, context):
        import pmwm

        ob, pm = _marked_pm(context)
        path = _file_path(self.filepath, "progressive mesh")
        _check_new(path, self.overwrite)
        pmwm.write_pm(path, pm, force=self.overwrite)
        self.report(
            {"INFO"},
            f"Wrote progressive mesh of '{ob.name}' to {path}: {pm.n_base_vertices} base "
            f"vertices, {pm.n_records} vertex splits in {len(pm.level_records)} levels",
        )
        return {"FINISHED"}


def _marked_pm(context):
    """(the active object, the progressive mesh of its last watermark) if the object still holds it."""
    ob = _active_mesh(context)
    marked = _remembered(ob, session.lookup, NOT_WATERMARKED)
    if not session.same_positions(marked.positions, meshdata.read_positions32(ob.data)):
        raise _Failed(f"'{ob.name}' changed since it was watermarked (edit or undo): watermark this object first")
    if marked.pm is None:
        raise _Failed(
            f"'{ob.name}' was watermarked without its progressive mesh: undo the watermark, turn on "
            "Progressive Mesh (Advanced) and watermark it again"
        )
    return ob, marked.pm


class PMWM_OT_import_pm(_PmwmOperator, Operator, ImportHelper):
    """Import a .pmwm progressive mesh as a new object at a level of detail"""

    bl_idname = "pmwm.import_pm"
    bl_label = "Import Progressive Mesh"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".pmwm"
    filter_glob: StringProperty(default="*.pmwm", options={"HIDDEN"})
    level: IntProperty(
        name="Level of Detail",
        description="0: base mesh; -1: full resolution",
        default=-1,
        min=-1,
        options={"SKIP_SAVE"},
    )

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
        lod["detail"] = 100.0 * level / n_levels if n_levels else 100.0  # (an item write: no decode either)
        lod.pm_path = path
        self.report({"INFO"}, f"Imported '{ob.name}' at level {level}/{n_levels}: {len(V)} of {pm.n_vertices} vertices")
        return {"FINISHED"}


class PMWM_OT_save_report(_BackgroundOperator, _FileOperator, Operator, ExportHelper):
    """Save the last verification of the active object as a self-contained HTML report (verdict, hashes, \
per-bit chart, pictures)"""

    bl_idname = "pmwm.save_report"
    bl_label = "Save Report"
    bl_options = {"REGISTER"}

    filename_ext = ".html"
    suffix = ".pmwm-report.html"
    filter_glob: StringProperty(default="*.html", options={"HIDDEN"})
    filepath: StringProperty(name="File Path", subtype="FILE_PATH", options={"SKIP_SAVE"})
    overwrite: BoolProperty(**REPLACE)
    chosen: BoolProperty(options={"HIDDEN", "SKIP_SAVE"})  # set by invoke: the file browser ran

    @classmethod
    def poll(cls, context):
        return _poll_reportable(cls, context)

    def invoke(self, context, event):
        self.chosen = True
        return _FileOperator.invoke(self, context, event)

    def execute(self, context):
        if self.chosen:  # back from the file browser: draw the report in the background
            return self._in_background(context)
        return _PmwmOperator.execute(self, context)

    def make_task(self, context):
        return ReportTask(context, self.filepath, overwrite=self.overwrite)


class PMWM_OT_publish_web(_FileOperator, Operator, ExportHelper):
    """Write a web page showing the active object's progressive mesh streaming in (a folder to upload: \
index.html, its script and model.pmwm)"""

    bl_idname = "pmwm.publish_web"
    bl_label = "Publish for Web"
    bl_options = {"REGISTER"}

    filename_ext = ""
    suffix = "-web"
    filter_glob: StringProperty(default="", options={"HIDDEN"})
    filepath: StringProperty(
        name="Folder", subtype="FILE_PATH", options={"SKIP_SAVE"}, description="The folder to write (created)"
    )
    overwrite: BoolProperty(
        name="Replace Existing",
        description="Replace the folder's web page if the folder exists and is not empty",
        default=False,
        options={"SKIP_SAVE"},
    )

    @classmethod
    def poll(cls, context):
        return _poll_remembered(cls, context, session.lookup, NOT_WATERMARKED)

    def check(self, context):  # (ExportHelper's adds the extension; a folder has none)
        return False

    def run(self, context):
        ob, pm = _marked_pm(context)
        folder = _file_path(self.filepath.rstrip("/\\") if self.filepath.strip("/\\") else "", "folder")
        if os.path.exists(folder) and not os.path.isdir(folder):
            raise _Failed(f"{folder} is a file: choose a name for a new folder")
        if os.path.isdir(folder) and os.listdir(folder) and not self.overwrite:
            raise _Failed(
                f"{folder} exists and is not empty: tick Replace Existing in the file browser "
                "(overwrite=True in scripts), or choose another name"
            )
        from pmwm import viewer

        site = viewer.write_site(pm, folder, title=ob.name, force=self.overwrite)
        self.report({"INFO"}, f"Published '{ob.name}' for the web in {site}: upload the folder, open index.html")
        return {"FINISHED"}


classes = (
    PMWM_OT_watermark,
    PMWM_OT_export_pm,
    PMWM_OT_import_pm,
    PMWM_OT_verify,
    PMWM_OT_save_report,
    PMWM_OT_publish_web,
)


register, unregister = bpy.utils.register_classes_factory(classes)
