"""timbre's Blender extension, in real Blender (bpy 5.0.1, headless): installed from
its zip, it renders the soundtrack of a cube dropped on a floor by Blender's own
rigid-body simulation, and the impacts are heard when the motion says they happen."""

import os
import struct
import subprocess

import bpy
import numpy as np
import pytest

from conftest import SHOTS, enable, load_script, timbre_command

make_contacts = load_script("make_contacts", os.path.join(SHOTS, "make-contacts.py"))
contact_reference = make_contacts.contact_reference


def read_wav(path):
    """(samples as float64 frames × channels, rate) of a 32-bit float WAV file."""
    data = open(path, "rb").read()
    assert data[:4] == b"RIFF" and data[8:12] == b"WAVE", path
    at, fmt, samples = 12, None, None
    while at + 8 <= len(data):
        tag, size = struct.unpack_from("<4sI", data, at)
        body = data[at + 8:at + 8 + size]
        if tag == b"fmt ":
            fmt = struct.unpack_from("<HHI", body)
        elif tag == b"data":
            samples = np.frombuffer(body, dtype="<f4")
        at += 8 + size + (size & 1)
    kind, channels, rate = fmt
    assert kind in (3, 0xFFFE), f"{path}: not float samples (format {kind})"
    return samples.reshape(-1, channels).astype(np.float64), rate


def cube_drop(tmp_path, installed, fps=24, fps_base=1.0, frames=(1, 72)):
    """The cube-drop shot of examples/shots/make-contacts.py, left as Blender's live
    rigid-body simulation (not baked), with the extension's settings on it; at another
    frame rate and range if asked."""
    scene, _objects, _moving = make_contacts.build_cube_drop()
    enable(installed)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = fps, fps_base
    scene.frame_start, scene.frame_end = frames
    cache = scene.rigidbody_world.point_cache
    cache.frame_start, cache.frame_end = frames
    scene.objects["Cube"].timbre.material = "oak"
    scene.objects["Floor"].timbre.material = "concrete"
    scene.timbre.output_dir = str(tmp_path / "out")
    return scene


def reference_impacts(scene):
    """The impacts that examples/shots/contact_reference.py (physics and geometry, no
    timbre) derives from the cube's motion as Blender simulates it, in seconds from
    the start frame."""
    fps = scene.render.fps / scene.render.fps_base
    frames = list(range(scene.frame_start, scene.frame_end + 1))
    track = []
    for frame in frames:
        scene.frame_set(frame)
        location, rotation, _ = scene.objects["Cube"].matrix_world.decompose()
        track.append({"frame": frame, "position": list(location),
                      "rotation_wxyz": list(rotation)})
    scene.frame_set(scene.frame_start)
    floor = scene.objects["Floor"]
    location, rotation, _ = floor.matrix_world.decompose()
    shot = {
        "fps": fps, "frame_start": frames[0], "frame_end": frames[-1],
        "gravity": list(scene.gravity),
        "objects": {
            "Floor": {"shape": "box", "size": [4.0, 4.0, 0.2], "static": True,
                      "margin": make_contacts.BOX_MARGIN, "top_z": 0.0,
                      "position": list(location), "rotation_wxyz": list(rotation)},
            "Cube": make_contacts.body_entry(scene.objects["Cube"], "box", [0.2, 0.2, 0.2],
                                             make_contacts.BOX_MARGIN),
        },
        "frames": {"Cube": track},
    }
    impacts = contact_reference.analyse(shot)["impacts"]
    # The landings of flights of 0.1 s or more (the cube then tumbles on in hops of two
    # frames, whose times a fit of so few frames does not pin down to a millisecond).
    # The reference's times are glTF's, frame / fps; the soundtrack starts at the
    # start frame.
    long = [i for i in impacts
            if (i["flight_before_frames"][1] - i["flight_before_frames"][0]) / fps >= 0.1]
    return [impact["time"] - scene.frame_start / fps for impact in long]


def onsets(samples, rate, after=0.002, rise=30.0):
    """Sample indices where the sound starts anew: the first sample whose level is
    `rise` times the mean level of the `after` seconds before it, found on the
    high-passed (first difference) mono sum, which the ringing of an earlier impact
    (low modes, decaying) feeds little and a new strike's broadband force much."""
    x = np.diff(samples.sum(axis=1), prepend=0.0)
    level = x * x
    window = int(after * rate)
    before = np.convolve(level, np.ones(window) / window, mode="full")[:len(level)]
    floor = 1e-9 * level.max()
    found, k = [], 0
    while k < len(level):
        prior = before[k - 1] if k > 0 else 0.0
        if level[k] > floor and level[k] > rise * max(prior, floor):
            found.append(k)
            k += int(0.02 * rate)  # one strike, not its every sample
        else:
            k += 1
    return found


def soundtrack_strips(scene):
    return [s for s in scene.sequence_editor.strips_all if s.get("timbre_soundtrack")]


def test_the_extension_installs_and_enables(installed):
    import addon_utils

    enabled = {addon.module for addon in bpy.context.preferences.addons}
    assert installed in enabled
    assert addon_utils.check(installed) == (True, True)
    assert hasattr(bpy.ops.timbre, "render_soundtrack")
    assert hasattr(bpy.ops.timbre, "save_scene")
    materials = bpy.types.Object.bl_rna.properties["timbre"].fixed_type.properties["material"]
    assert {"oak", "steel", "concrete", "NONE"} <= {item.identifier for item in
                                                     materials.enum_items}


@pytest.mark.parametrize("fps, fps_base, frames", [
    (24, 1.0, (1, 72)),
    # NTSC (29.97 fps), from frame 5.
    (30, 1.001, (5, 95)),
])
def test_a_rigid_body_drop_sounds_its_impacts_when_they_happen(tmp_path, installed, fps,
                                                              fps_base, frames):
    scene = cube_drop(tmp_path, installed, fps, fps_base, frames)
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    strips = soundtrack_strips(scene)
    assert len(strips) == 1
    strip = strips[0]
    assert strip.type == "SOUND"
    assert strip.frame_start == scene.frame_start
    assert strip.frame_final_duration == scene.frame_end - scene.frame_start + 1
    samples, rate = read_wav(bpy.path.abspath(strip.sound.filepath))
    assert rate == scene.timbre.sample_rate
    seconds = (frames[1] - frames[0] + 1) * fps_base / fps
    assert samples.shape == (round(seconds * rate), 2)
    expected = reference_impacts(scene)
    assert len(expected) == 3, expected
    heard = [k / rate for k in onsets(samples, rate)]
    for t in expected:
        nearest = min(heard, key=lambda h: abs(h - t))
        assert abs(nearest - t) <= 0.001, (
            f"the impact at {t:.5f} s (frame {frames[0] + t * fps / fps_base:.2f}) is heard at "
            f"{nearest:.5f} s; onsets heard: {[round(h, 4) for h in heard]}")
    # Nothing before the first impact: the cube falls in silence.
    assert np.abs(samples[: int((expected[0] - 0.001) * rate)]).max() == 0.0

    # A second render replaces the first: still one strip.
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    assert len(soundtrack_strips(scene)) == 1


def test_the_saved_scene_renders_the_same_bits_with_the_command_line(tmp_path, installed):
    scene = cube_drop(tmp_path, installed)
    scene.timbre.receiver = "MONO"
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    panel, _ = read_wav(bpy.path.abspath(soundtrack_strips(scene)[0].sound.filepath))
    saved = tmp_path / "saved" / "drop.tt"
    assert bpy.ops.timbre.save_scene(filepath=str(saved)) == {"FINISHED"}
    assert (tmp_path / "saved" / "drop.glb").is_file()
    out = tmp_path / "cli.wav"
    run = subprocess.run([timbre_command(), "render", str(saved), "-o", str(out), "--format",
                          "f32"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    cli, _ = read_wav(str(out))
    assert cli.shape == panel.shape
    assert np.array_equal(cli.view(np.uint64), panel.view(np.uint64))
    assert np.abs(panel).max() > 0.01


def test_stems_are_strips_on_the_channels_above(tmp_path, installed):
    scene = cube_drop(tmp_path, installed)
    scene.timbre.stems = True
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    strips = sorted(soundtrack_strips(scene), key=lambda s: s.channel)
    mix = strips[0]
    assert mix.channel == scene.timbre.channel and not mix.mute
    names = [s.name for s in strips[1:]]
    assert any("objects/Cube" in n for n in names) and any("kinds/impacts" in n for n in names)
    assert all(s.mute for s in strips[1:])
    assert [s.channel for s in strips] == list(range(mix.channel, mix.channel + len(strips)))
    total, _ = read_wav(bpy.path.abspath(mix.sound.filepath))
    objects = sum(read_wav(bpy.path.abspath(s.sound.filepath))[0]
                  for s in strips[1:] if "objects/" in s.name)
    assert np.array_equal(objects, total)


def frequency(samples, rate, start, length):
    """The frequency (Hz) of the strongest partial of samples[start:start+length]:
    the peak of a Hann-windowed spectrum, refined by a parabola through its log
    magnitudes."""
    x = samples[start:start + length].sum(axis=1)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x)), 16 * len(x)))
    k = int(np.argmax(spectrum))
    a, b, c = np.log(spectrum[k - 1:k + 2])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) * rate / (16 * len(x))


@pytest.mark.parametrize("unit_scale", [1.0, 0.5])
def test_an_object_emits_a_class_as_it_moves_with_its_doppler_shift(tmp_path, installed,
                                                                     unit_scale):
    """An empty driven past the camera at 20 m/s emits a 440 Hz tone from the library:
    heard higher as it comes and lower as it goes, as f = f0 / (1 - v.u / c) says
    (u the direction from it to the listener when it emitted what is heard, c 343
    m/s). With a unit scale of 0.5 the scene is modelled in units of half a metre and
    sounds the same."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    enable(installed)
    scene = bpy.context.scene
    scene.render.fps, scene.frame_start, scene.frame_end = 24, 1, 97
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = unit_scale
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Lens"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    car = bpy.data.objects.new("Car", None)
    scene.collection.objects.link(car)
    start, end, v = np.array([-40.0, 10.0, 0.0]), np.array([40.0, 10.0, 0.0]), 20.0
    for frame, where in ((1, start), (97, end)):
        car.location = tuple(where / unit_scale)
        car.keyframe_insert("location", frame=frame)
    make_contacts.car_pass.set_interpolation(car, "LINEAR")
    library = tmp_path / "tones.tt"
    library.write_text("(define-sound tone () (* 0.5 (sine (* t 440))))\n")
    scene.timbre.library = str(library)
    scene.timbre.receiver = "MONO"
    scene.timbre.subframes = 2
    scene.timbre.output_dir = str(tmp_path / "out")
    car.timbre.emit_class = "tone"
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    strip = soundtrack_strips(scene)[0]
    samples, rate = read_wav(bpy.path.abspath(strip.sound.filepath))
    c = 343.0
    for at in (0.5, 3.5):
        # The emission time of what is heard at `at`, and the car's direction then.
        emitted = at
        for _ in range(50):
            where = start + (end - start) * emitted / 4.0
            emitted = at - np.linalg.norm(where) / c
        u = -where / np.linalg.norm(where)
        expected = 440.0 / (1.0 - np.dot(np.array([v, 0.0, 0.0]), u) / c)
        measured = frequency(samples, rate, int((at - 0.1) * rate), int(0.2 * rate))
        assert abs(measured / expected - 1.0) < 1e-3, (at, measured, expected)


def render_fails(match):
    with pytest.raises(RuntimeError, match=match):
        bpy.ops.timbre.render_soundtrack()


def test_a_broken_setting_is_an_error_report_and_blender_goes_on(tmp_path, installed):
    scene = cube_drop(tmp_path, installed)
    library = tmp_path / "sounds.tt"
    library.write_text("(define-sound knock (force) (* 0.001 force (sine (* t 700))))\n")
    cube = scene.objects["Cube"].timbre
    cube.sound, cube.sound_class = "CLASS", "knok"
    # A class, but no library to find it in.
    render_fails("names no library")
    scene.timbre.library = str(library)
    # A class the library does not have: timbre's diagnostic, naming it.
    render_fails("knok")
    # A library that is not timbre.
    library.write_text("(define-sound knock (force)\n  (* force (sinee (* t 700))))\n")
    cube.sound_class = "knock"
    render_fails(r"sinee.*sounds\.tt:2:")
    library.write_text("(define-sound knock (force) (* 0.001 force (sine (* t 700))))\n")
    # A name that is not a name.
    cube.sound_class = "knock it"
    render_fails("knock it.*no spaces")
    cube.sound_class = "knock"
    # No camera to hear from.
    camera, scene.camera = scene.camera, None
    render_fails("no camera")
    scene.camera = camera
    assert len(soundtrack_strips(scene)) == 0 if scene.sequence_editor else True
    # Mended, it renders.
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    assert len(soundtrack_strips(scene)) == 1


def test_a_cancelled_render_stops(tmp_path, installed):
    import importlib

    operators = importlib.import_module(installed + ".operators")
    scene = cube_drop(tmp_path, installed)
    folder = operators.output_folder(scene)
    operators.write_scene(bpy.context, folder)
    job = operators.Job(folder, scene.timbre.sample_rate, stems=False)
    job.cancelled = True
    job.run()
    import timbre

    assert isinstance(job.error, timbre.Cancelled)


class Layout:
    """Stands in for Blender's UILayout (a panel draws only in a window): records what
    a panel draws and checks that each property and operator it names exists."""

    def __init__(self, drawn):
        self.drawn = drawn
        self.use_property_split = self.use_property_decorate = self.active = False
        self.scale_y = 1.0

    def column(self, **_):
        return self

    row = column

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, f"{data!r} has no property {name!r}"
        self.drawn.append(name)

    def operator(self, idname, **_):
        family, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, family), name), idname
        self.drawn.append(idname)

    def label(self, **_):
        pass

    def separator(self, **_):
        pass


def test_the_panels_draw_every_setting(tmp_path, installed):
    import importlib

    panels = importlib.import_module(installed + ".panels")
    scene = cube_drop(tmp_path, installed)
    drawn = []
    panels.draw_soundtrack(Layout(drawn), scene)
    settings = set(scene.timbre.bl_rna.properties.keys()) - {"rna_type", "name"}
    assert settings <= set(drawn), settings - set(drawn)
    assert "timbre.render_soundtrack" in drawn and "timbre.save_scene" in drawn

    class Context:
        object = scene.objects["Cube"]

    class Panel:
        layout = Layout(drawn)

    drawn.clear()
    scene.objects["Cube"].timbre.sound = "CLASS"
    panels.TIMBRE_PT_object.draw(Panel(), Context())
    fields = set(scene.objects["Cube"].timbre.bl_rna.properties.keys()) - {"rna_type", "name"}
    assert fields <= set(drawn), fields - set(drawn)


def test_an_emitted_class_reads_its_objects_motion_by_parameter_name(tmp_path, installed):
    """A whine whose pitch is 20 × its speed, on an empty 10 m from the camera, carried
    round it once in 4 s by a rotating parent: no Doppler shift (its distance does not
    change), speed 2π·10/4 = 15.71 m/s through the hierarchy, so 314.2 Hz; a class
    with a parameter the motion cannot give is a report naming it."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    enable(installed)
    scene = bpy.context.scene
    scene.render.fps, scene.frame_start, scene.frame_end = 24, 1, 97
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Lens"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    arm = bpy.data.objects.new("Arm", None)
    scene.collection.objects.link(arm)
    for frame, angle in ((1, 0.0), (97, 2.0 * np.pi)):
        arm.rotation_euler = (0.0, 0.0, angle)
        arm.keyframe_insert("rotation_euler", frame=frame)
    make_contacts.car_pass.set_interpolation(arm, "LINEAR")
    drone = bpy.data.objects.new("Drone", None)
    scene.collection.objects.link(drone)
    drone.parent = arm
    drone.location = (10.0, 0.0, 0.0)
    # Two blocks that never touch, so that the scene has contacts too.
    for k, name in enumerate(("Left", "Right")):
        block = make_contacts.add_object(name, make_contacts.box_mesh(name, (1.0, 1.0, 1.0)),
                                         (-50.0 + 100.0 * k, 0.0, 0.0))
        block.timbre.material = "stone"
    library = tmp_path / "drones.tt"
    library.write_text("(define-sound whine (speed distance) "
                       "(* 0.3 (/ 10 distance) (sine (* t (* 20 speed)))))\n"
                       "(define-sound buzz (speed wings) (* 0.3 (sine (* t wings))))\n")
    scene.timbre.library = str(library)
    scene.timbre.receiver = "MONO"
    scene.timbre.output_dir = str(tmp_path / "out")
    drone.timbre.emit_class = "buzz"
    render_fails("buzz.*wings")
    drone.timbre.emit_class = "whine"
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    samples, rate = read_wav(bpy.path.abspath(soundtrack_strips(scene)[0].sound.filepath))
    expected = 20.0 * 2.0 * np.pi * 10.0 / 4.0
    for at in (1.0, 3.0):
        measured = frequency(samples, rate, int((at - 0.25) * rate), int(0.5 * rate))
        assert abs(measured / expected - 1.0) < 1e-3, (at, measured, expected)


def test_a_scripts_warnings_are_warning_reports(tmp_path, installed, capfd):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    enable(installed)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 12
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Lens"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    horn = bpy.data.objects.new("Horn", None)
    horn.location = (0.0, 5.0, 0.0)
    scene.collection.objects.link(horn)
    library = tmp_path / "horns.tt"
    library.write_text("(define-sound flat () (* 0.1 (sine 440)))\n")
    scene.timbre.library = str(library)
    scene.timbre.output_dir = str(tmp_path / "out")
    horn.timbre.emit_class = "flat"
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    out = capfd.readouterr().out
    assert "Warning: timbre: `(sine 440)` has a constant phase" in out, out


def test_an_object_can_sound_the_modes_of_its_shape(tmp_path, installed):
    """The cube sounds the modes of its own mesh: the scene names it in `:modal` with
    the panel's count of modes, and renders (the modes themselves are checked against
    closed forms in crates/timbre-modal)."""
    scene = cube_drop(tmp_path, installed)
    scene.objects["Cube"].timbre.sound = "MODAL"
    scene.timbre.modes = 8
    scene.timbre.receiver = "MONO"
    assert bpy.ops.timbre.render_soundtrack() == {"FINISHED"}
    text = open(os.path.join(scene.timbre.output_dir, "Scene", "soundtrack.tt")).read()
    assert ':modal ("Cube")' in text and ":modes 8" in text, text
    samples, _ = read_wav(bpy.path.abspath(soundtrack_strips(scene)[0].sound.filepath))
    assert np.abs(samples).max() > 0.01
