"""Render soundtrack, and Save timbre scene.

A render has three steps. On Blender's main thread the motion is read (the scene is
stepped through its frames) and the timbre scene written; then the `timbre` package
renders it, on a thread of its own when run from the interface (the GIL is released
while it renders, so Blender stays responsive, and Esc cancels it) or in place when
run from a script; then, on the main thread again, the sound is written and its strip
replaces the last one. Every failure is a report naming the problem, never a
traceback.
"""

import os
import shutil
import threading
import warnings

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from . import shot, soundtrack

# A custom property that marks the strips a render added (and the next replaces).
STRIP_MARK = "timbre_soundtrack"


def _timbre():
    """The `timbre` package (bundled with the extension as a wheel)."""
    import timbre

    return timbre


def describe(error):
    """One line for a Blender report: what went wrong and what to do."""
    timbre = _timbre()
    if isinstance(error, timbre.Error):
        where = ""
        if error.line is not None:
            where = f" ({os.path.basename(error.file or '')}:{error.line}:{error.column})"
        text = f"timbre: {error.message}{where}"
        return text + (f". {error.help}" if error.help else "")
    if isinstance(error, (soundtrack.SettingError, shot.ShotError)):
        return f"timbre: {error}"
    if isinstance(error, OSError):
        return f"timbre: cannot write {error.filename or 'a file'}: {error.strerror or error}"
    return f"timbre: {type(error).__name__}: {error}"


def warning_line(text):
    """The message of a warning as the command line prints it ("warning: …" with its
    source lines after): its first line that says something."""
    for line in text.splitlines():
        line = line.strip().lstrip("⚠!").strip()
        if line and not line.startswith("timbre::"):
            return line.removeprefix("warning:").strip()
    return text.strip()


class Job:
    """One render: where its files go and what it was asked."""

    def __init__(self, folder, rate, stems, on_progress=None):
        self.folder = folder
        self.rate = rate
        self.on_progress = on_progress
        self.scene_path = os.path.join(folder, soundtrack.SCENE_FILE)
        self.stems = stems
        self.fraction = 0.0
        self.cancelled = False
        self.result = None
        self.error = None
        # The script's warnings (timbre.Warning), reported once the render is done.
        self.warnings = []

    def progress(self, fraction):
        """The render's callback: keeps the fraction, and says whether to go on."""
        self.fraction = fraction
        if self.on_progress is not None:
            self.on_progress(fraction)
        return not self.cancelled

    def run(self):
        """Renders the scene file (on any thread)."""
        timbre = _timbre()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", timbre.Warning)
                self.result = timbre.render(self.scene_path, stems=self.stems,
                                            progress=self.progress)
            self.warnings = [str(w.message) for w in caught
                             if issubclass(w.category, timbre.Warning)]
        except Exception as error:  # reported on the main thread
            self.error = error


def output_folder(scene):
    """The folder of the scene's soundtrack files, made if missing. A `//` path in an
    unsaved file is under Blender's temporary folder."""
    folder = scene.timbre.output_dir.strip() or "//timbre/"
    if folder.startswith("//") and not bpy.data.filepath:
        folder = os.path.join(bpy.app.tempdir or os.path.join(os.sep, "tmp"), folder[2:])
    folder = os.path.join(os.path.abspath(bpy.path.abspath(folder)),
                          bpy.path.clean_name(scene.name))
    os.makedirs(folder, exist_ok=True)
    return folder


def write_scene(context, folder, motion_name=soundtrack.MOTION_FILE,
                scene_name=soundtrack.SCENE_FILE, progress=None):
    """Reads the motion and writes the timbre scene and its motion into `folder`;
    returns the scene file's path."""
    scene = context.scene
    listener = soundtrack.listener_of(scene)
    library = soundtrack.library_path(scene, bpy.path.abspath)
    objects = soundtrack.objects_of(scene)
    blend = os.path.basename(bpy.data.filepath) if bpy.data.filepath else None
    classes = None
    if library is not None:
        engine = _timbre().Engine(file_access=True)
        classes = engine.load_library_file(library).classes()
    text = soundtrack.scene_text(scene, objects, listener, library, blend, motion_name, classes)
    exported = objects + ([listener] if listener not in objects else [])
    depsgraph = context.evaluated_depsgraph_get()
    soundtrack.write_motion(os.path.join(folder, motion_name), scene, depsgraph, exported,
                            scene.timbre.subframes, progress)
    path = os.path.join(folder, scene_name)
    soundtrack.write_text(path, text)
    return path


def finish(context, job):
    """Writes the rendered sound and puts its strips in the sequencer."""
    scene = context.scene
    result, rate = job.result, job.rate
    if job.stems:
        mix = result.mix
        families = {"objects": result.objects, "kinds": result.kinds}
    else:
        mix, families = result, {}
    sound_path = os.path.join(job.folder, soundtrack.SOUND_FILE)
    soundtrack.write_wav(sound_path, mix, rate)
    # The last render's stems go: their objects may not be this one's.
    shutil.rmtree(os.path.join(job.folder, soundtrack.STEMS_DIR), ignore_errors=True)
    stems = []
    for family, parts in families.items():
        folder = os.path.join(job.folder, soundtrack.STEMS_DIR, family)
        os.makedirs(folder, exist_ok=True)
        used = set()
        for label, samples in sorted(parts.items()):
            name = soundtrack.safe_file_name(label)
            while name in used:  # two labels made one name ("a b", "a_b")
                name += "_"
            used.add(name)
            path = os.path.join(folder, name + ".wav")
            soundtrack.write_wav(path, samples, rate)
            stems.append((f"{family}/{label}", path))
    add_strips(scene, sound_path, stems)


def add_strips(scene, sound_path, stems):
    """The soundtrack's strip at the scene's start frame (and its stems, muted, on the
    channels above), replacing those of the last render."""
    editor = scene.sequence_editor or scene.sequence_editor_create()
    old_sounds = set()
    for strip in list(editor.strips_all):
        if strip.get(STRIP_MARK):
            if strip.type == "SOUND" and strip.sound is not None:
                old_sounds.add(strip.sound)
            editor.strips.remove(strip)
    for sound in old_sounds:
        if sound.users == 0:
            bpy.data.sounds.remove(sound)
    channel = scene.timbre.channel
    strip = editor.strips.new_sound("Soundtrack", sound_path, channel, scene.frame_start)
    strip[STRIP_MARK] = 1
    for k, (label, path) in enumerate(stems, 1):
        stem = editor.strips.new_sound(f"Soundtrack {label}", path, channel + k, scene.frame_start)
        stem.mute = True
        stem[STRIP_MARK] = 1


class TIMBRE_OT_render_soundtrack(bpy.types.Operator):
    """Render the scene's soundtrack from its motion and put it in the sequencer at the
    start frame"""

    bl_idname = "timbre.render_soundtrack"
    bl_label = "Render Soundtrack"
    bl_options = {"REGISTER"}

    _job = None
    _thread = None
    _timer = None
    # A render on its thread, started from the interface: one at a time.
    rendering = False

    @classmethod
    def poll(cls, context):
        if cls.rendering:
            cls.poll_message_set("a soundtrack is rendering (Esc cancels it)")
            return False
        return True

    def prepare(self, context, on_progress=None):
        folder = output_folder(context.scene)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            write_scene(context, folder, progress=lambda f: wm.progress_update(int(20 * f)))
        finally:
            wm.progress_end()
        settings = context.scene.timbre
        return Job(folder, settings.sample_rate, settings.stems, on_progress)

    def fail(self, error):
        self.report({"ERROR"}, describe(error))
        if isinstance(error, _timbre().Error):
            print(str(error))
        return {"CANCELLED"}

    def done(self, job):
        """Reports the script's warnings (their first line; the console has them
        whole) and where the soundtrack went."""
        for text in job.warnings:
            print(text)
            self.report({"WARNING"}, "timbre: " + warning_line(text))
        self.report({"INFO"}, f"timbre: soundtrack written to {job.folder}")
        return {"FINISHED"}

    def execute(self, context):
        """From a script: renders in place, with Blender's progress in the status bar."""
        wm = context.window_manager
        try:
            job = self.prepare(context, lambda f: wm.progress_update(20 + int(80 * f)))
            wm.progress_begin(0, 100)
            try:
                job.run()
            finally:
                wm.progress_end()
            if job.error is not None:
                raise job.error
            finish(context, job)
        except Exception as error:
            return self.fail(error)
        return self.done(job)

    def invoke(self, context, event):
        """From the interface: renders on a thread; Esc cancels."""
        try:
            self._job = self.prepare(context)
        except Exception as error:
            return self.fail(error)
        self._thread = threading.Thread(target=self._job.run, name="timbre render", daemon=True)
        self._thread.start()
        TIMBRE_OT_render_soundtrack.rendering = True
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            job.cancelled = True  # the render stops at its next chunk
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm = context.window_manager
        wm.progress_update(20 + int(80 * job.fraction))
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"timbre: rendering the soundtrack, {100 * job.fraction:.0f} % (Esc cancels)")
        if self._thread.is_alive():
            return {"RUNNING_MODAL"}
        TIMBRE_OT_render_soundtrack.rendering = False
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        if isinstance(job.error, _timbre().Cancelled):
            self.report({"WARNING"}, "timbre: render cancelled; the last soundtrack is kept")
            return {"CANCELLED"}
        if job.error is not None:
            return self.fail(job.error)
        try:
            finish(context, job)
        except Exception as error:
            return self.fail(error)
        return self.done(job)


class TIMBRE_OT_save_scene(bpy.types.Operator, ExportHelper):
    """Save the timbre scene of the soundtrack (and its motion, beside it as .glb) for
    editing and rendering with timbre"""

    bl_idname = "timbre.save_scene"
    bl_label = "Save timbre Scene"

    filename_ext = ".tt"
    filter_glob: StringProperty(default="*.tt", options={"HIDDEN"})

    def execute(self, context):
        path = os.path.abspath(self.filepath)
        folder, name = os.path.split(path)
        motion = os.path.splitext(name)[0] + ".glb"
        try:
            os.makedirs(folder, exist_ok=True)
            write_scene(context, folder, motion_name=motion, scene_name=name)
        except Exception as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"timbre: scene saved as {path} (motion in {motion})")
        return {"FINISHED"}


CLASSES = (TIMBRE_OT_render_soundtrack, TIMBRE_OT_save_scene)

register, unregister = bpy.utils.register_classes_factory(CLASSES)
