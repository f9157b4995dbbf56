"""A scene's soundtrack: the timbre scene written from the animator's settings, the
files it goes to, and the WAV files written from the samples."""

import os
import struct
import tempfile

import numpy as np

from . import shot

# The names of the generated files, in the output folder.
SCENE_FILE = "soundtrack.tt"
MOTION_FILE = "soundtrack.glb"
SOUND_FILE = "soundtrack.wav"
STEMS_DIR = "stems"

# The mode of the files written (a temporary file is made private, 0600).
FILE_MODE = 0o644


# What an emitted class's parameters may be, by name: the object's motion, read from
# the shot as the sound plays (lang-spec/motion.md, quantities of motion).
MOTION_PARAMETERS = {
    "speed": '(speed {obj})',
    "angular-speed": '(angular-speed {obj})',
    "height": '(index (position {obj}) 2)',
    "distance": '(distance {obj} {listener})',
    "approach": '(approach {obj} {listener})',
}


class SettingError(Exception):
    """A setting that cannot make a soundtrack; the message names it and says what to
    do."""


def quoted(name):
    """`name` as a timbre string."""
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def number(value):
    """A float as timbre reads it back exactly (the shortest repr)."""
    value = float(value)
    if value == int(value) and abs(value) < 2 ** 53:
        return str(int(value))
    return repr(value)


def decimal(value):
    """A setting Blender keeps as a 32-bit float (a mass, the gravity) as the shortest
    decimal that is that float (5.6, not 5.599999904632568)."""
    return float(str(np.float32(value)))


def setting(value):
    """`decimal(value)` as timbre text."""
    return number(decimal(value))


def seconds_of(scene):
    """The length of the scene's frame range in seconds (the last frame included)."""
    frames = scene.frame_end - scene.frame_start + 1
    return frames * scene.render.fps_base / scene.render.fps


def listener_of(scene):
    listener = scene.timbre.listener or scene.camera
    if listener is None:
        raise SettingError(
            "the scene has no camera to hear it from: set the scene's camera, or choose "
            "a Listener in the Soundtrack panel")
    return listener


def library_path(scene, abspath):
    """The library's absolute path, or None; a library that is named but missing is
    an error."""
    library = scene.timbre.library.strip()
    if not library:
        return None
    path = abspath(library)
    if not os.path.isfile(path):
        raise SettingError(f"the library `{library}` is not a file ({path})")
    return path


def has_material(obj):
    """Whether `obj` takes part in contacts."""
    return obj.timbre.material != "NONE"


def objects_of(scene):
    """The objects that take part: those with a material or an emitted class, unless
    they are hidden in renders (as they are from the picture)."""
    return [obj for obj in scene.objects if not obj.hide_render
            and (has_material(obj) or obj.timbre.emit_class.strip())]


def scene_text(scene, objects, listener, library, blend_name, motion_file=MOTION_FILE,
               classes=None):
    """The timbre scene of the soundtrack, reading its motion from `motion_file`
    (beside it). `classes` maps the library's classes to their parameters' names."""
    settings = scene.timbre
    fps = scene.render.fps / scene.render.fps_base
    sounding = [obj for obj in objects if has_material(obj)]
    emitters = [obj for obj in objects if obj.timbre.emit_class.strip()]
    if not sounding and not emitters:
        raise SettingError(
            "no object has a sound: give objects a Material (Object properties, Timbre "
            "panel) or a class to emit")
    if len(sounding) == 1:
        raise SettingError(
            f"only `{sounding[0].name}` has a material: contacts need two objects with "
            "one (give the floor or what it hits a material too)")
    if scene.render.frame_map_old != scene.render.frame_map_new:
        raise SettingError(
            "the scene's Time Stretching (Output properties, Frame Range) plays frames at "
            "other times than the motion's: set Old and New equal")
    for obj in objects:
        for name in (obj.timbre.sound_class, obj.timbre.emit_class):
            if any(c in name.strip() for c in ' \t\n()";'):
                raise SettingError(
                    f"`{obj.name}` names the class `{name.strip()}`: a class's name has no "
                    "spaces, parentheses, quotes or semicolons")
        uses_class = (has_material(obj) and obj.timbre.sound == "CLASS") or \
            obj.timbre.emit_class.strip()
        if uses_class and library is None:
            raise SettingError(
                f"`{obj.name}` sounds a class of the library, but the scene names no "
                "library: choose a .tt file as the Soundtrack panel's Library")
        if has_material(obj) and obj.timbre.sound == "CLASS" and \
                not obj.timbre.sound_class.strip():
            raise SettingError(f"`{obj.name}` sounds a class of the library, but names none")
    stereo = settings.receiver != "MONO"
    lines = [
        f"; The soundtrack of the Blender scene {quoted(scene.name)}"
        + (f" in {blend_name}" if blend_name else "") + ",",
        f"; frames {scene.frame_start} to {scene.frame_end} at {fps:g} fps, written by "
        "timbre's Blender extension.",
        f"; Time 0 is frame {scene.frame_start}. The motion, read from Blender at every "
        + ("frame" if settings.subframes == 1 else f"1/{settings.subframes} frame")
        + f", is in {motion_file}.",
        "(scene :sample-rate {} :duration {} :sync {}{} :seed {})".format(
            settings.sample_rate, number(seconds_of(scene)),
            "picture" if settings.sync == "PICTURE" else "physical",
            " :channels 2" if stereo else "", settings.seed),
    ]
    if library is not None:
        lines.append(f"(include {quoted(library)})")
    lines.append(f"(motion shot {quoted(motion_file)})")
    pair = {"MONO": "", "SPACED": " :pair spaced", "XY": " :pair xy"}[settings.receiver]
    lines.append(f"(listener :object {quoted(listener.name)}{pair})")
    if sounding:
        unit = shot.metres_per_unit(scene)
        gravity = [decimal(g) * unit for g in scene.gravity] if scene.use_gravity else [0.0] * 3
        options = [
            ":gravity (vector {})".format(" ".join(number(g) for g in gravity)),
            ":materials ({})".format(" ".join(
                f"({quoted(obj.name)} {obj.timbre.material})" for obj in sounding)),
        ]
        modal = [obj for obj in sounding if obj.timbre.sound == "MODAL"]
        if modal:
            options.append(":modal ({})".format(" ".join(quoted(obj.name) for obj in modal)))
            if settings.modes != 32:
                options.append(f":modes {settings.modes}")
        sounding_classes = [obj for obj in sounding if obj.timbre.sound == "CLASS"]
        if sounding_classes:
            options.append(":sounds ({})".format(" ".join(
                f"({quoted(obj.name)} {obj.timbre.sound_class.strip()})"
                for obj in sounding_classes)))
        masses = [(obj, mass_of(obj)) for obj in sounding]
        masses = [(obj, m) for obj, m in masses if m is not None]
        if masses:
            options.append(":masses ({})".format(" ".join(
                f"({quoted(obj.name)} {setting(m)})" for obj, m in masses)))
        options.append(f":frame-rate {number(fps)}")
        options.append(f":first-frame {scene.frame_start}")
        options.append(f":gain {setting(settings.gain)}")
        lines.append("(contacts shot")
        lines += ["          " + option for option in options]
        lines[-1] += ")"
    for k, obj in enumerate(emitters, 1):
        name = obj.timbre.emit_class.strip()
        call = " ".join([name] + [f":{p} {value}" for p, value in
                                  emitted_parameters(obj, name, listener, classes or {})])
        lines.append(f"(source emitter-{k} :object {quoted(obj.name)})")
        lines.append(f"(instance emits-{k} ({call}) :source emitter-{k} "
                     f":stop {number(seconds_of(scene))})")
    return "\n".join(lines) + "\n"


def emitted_parameters(obj, name, listener, classes):
    """(parameter, expression) for each parameter of the class `obj` emits: its
    motion, by the parameter's name (MOTION_PARAMETERS)."""
    if name not in classes:
        return []  # timbre's own diagnostic names the class the library lacks
    unknown = [p for p in classes[name] if p not in MOTION_PARAMETERS]
    if unknown:
        raise SettingError(
            f"`{obj.name}` emits `{name}`, whose parameters {', '.join(unknown)} the motion "
            f"cannot give: an emitted class's parameters are named "
            f"{', '.join(MOTION_PARAMETERS)}")
    return [(p, MOTION_PARAMETERS[p].format(obj=quoted(obj.name), listener=quoted(listener.name)))
            for p in classes[name]]


def mass_of(obj):
    """The mass an object's contacts take: its own setting, else its active rigid
    body's, else None (timbre's volume × density)."""
    if obj.timbre.mass > 0.0:
        return obj.timbre.mass
    body = obj.rigid_body
    if body is not None and body.type == "ACTIVE" and body.enabled:
        return body.mass
    return None


def write_atomically(path, write):
    """Calls `write(file)` on a temporary file beside `path`, then renames it into
    place, so a failure leaves no partial file."""
    folder = os.path.dirname(path) or "."
    handle, temporary = tempfile.mkstemp(prefix=".timbre-", suffix=".part", dir=folder)
    try:
        with os.fdopen(handle, "wb") as out:
            write(out)
        os.chmod(temporary, FILE_MODE)
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.remove(temporary)
        raise


def write_wav(path, samples, rate):
    """Writes float32 samples (frames × channels) as a 32-bit float WAV file, the
    format `timbre render --format f32` writes."""
    samples = np.ascontiguousarray(samples, dtype="<f4")
    frames, channels = samples.shape
    data = samples.tobytes()
    fmt = struct.pack("<HHIIHHH", 3, channels, rate, rate * 4 * channels, 4 * channels, 32, 0)
    header = b"RIFF" + struct.pack("<I", 4 + 8 + len(fmt) + 12 + 8 + len(data)) + b"WAVE"
    header += b"fmt " + struct.pack("<I", len(fmt)) + fmt
    header += b"fact" + struct.pack("<II", 4, frames)
    header += b"data" + struct.pack("<I", len(data))

    def write(out):
        out.write(header)
        out.write(data)

    write_atomically(path, write)


def write_text(path, text):
    write_atomically(path, lambda out: out.write(text.encode("utf-8")))


def write_motion(path, scene, depsgraph, objects, subframes, progress=None):
    """The shot's motion into `path`, written atomically."""
    write_atomically(
        path, lambda out: shot.write_glb(out, scene, depsgraph, objects, subframes, progress))


def safe_file_name(label):
    """A stem's label as a file name."""
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in label)
    return keep.strip(".") or "unnamed"
