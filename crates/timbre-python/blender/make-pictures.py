"""The pictures of docs/animators.md's worked shot: the cube dropped on the floor by
Blender's rigid bodies (examples/shots/make-contacts.py), its soundtrack rendered by
the extension, and frames of the picture above the sound, frame by frame.

    python crates/timbre-python/blender/make-pictures.py OUTDIR EXTENSION.zip

Run it with a Python that has Blender's module (`pip install bpy==5.0.1 pillow`).
It writes OUTDIR/blender-cube-drop.png: frames of the shot (Cycles, CPU, cropped to
where the cube falls) and under each the soundtrack's waveform during that frame
(1/24 s from the time its picture shows, all at one scale); and
OUTDIR/blender-cube-drop.tt, the scene the extension generated.
"""

import importlib.util
import os
import shutil
import struct
import sys
import tempfile

import numpy as np
from PIL import Image, ImageDraw

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.abspath(os.path.join(HERE, "..", "..", ".."))

# Frames shown, in rows: the fall, and the frames before and after each of the three
# landings of its long flights (at frames 10.99, 20.06 and 24.73).
FRAMES = ((1, 6, 10, 11), (19, 20, 21, 22), (23, 24, 25, 26))
# The camera's picture is rendered at RENDER_SIZE and cropped to the part of it where
# the cube falls (CROP: left, bottom, right, top, as fractions).
RENDER_SIZE = (960, 540)
CROP = (0.3, 0.25, 0.65, 0.85)


def load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def read_wav(path):
    data = open(path, "rb").read()
    at, channels, samples = 12, 1, None
    while at + 8 <= len(data):
        tag, size = struct.unpack_from("<4sI", data, at)
        if tag == b"fmt ":
            channels = struct.unpack_from("<H", data, at + 10)[0]
        elif tag == b"data":
            samples = np.frombuffer(data[at + 8:at + 8 + size], dtype="<f4")
        at += 8 + size + (size & 1)
    return samples.reshape(-1, channels).mean(axis=1)


def look(bpy, scene):
    """A sun, a sky, wood and concrete, for Cycles on the CPU."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 24
    scene.render.resolution_x, scene.render.resolution_y = RENDER_SIZE
    scene.render.resolution_percentage = 100
    scene.render.use_border = True
    scene.render.use_crop_to_border = True
    (scene.render.border_min_x, scene.render.border_min_y,
     scene.render.border_max_x, scene.render.border_max_y) = CROP
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.6, 0.7, 1)
    scene.world = world
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.2, 0.8)
    scene.collection.objects.link(sun)
    for name, colour in (("Cube", (0.55, 0.33, 0.15, 1)), ("Floor", (0.5, 0.5, 0.48, 1))):
        material = bpy.data.materials.new(name)
        material.use_nodes = True
        material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = colour
        scene.objects[name].data.materials.append(material)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: make-pictures.py OUTDIR EXTENSION.zip")
    out, extension = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    os.makedirs(out, exist_ok=True)
    home = tempfile.mkdtemp(prefix="timbre-pictures-")
    os.environ["HOME"] = home
    import bpy
    import addon_utils  # Blender's, once bpy is imported

    bpy.ops.extensions.package_install_files(filepath=extension, repo="user_default",
                                             enable_on_install=True)
    make_contacts = load("make_contacts", os.path.join(REPO, "examples", "shots",
                                                       "make-contacts.py"))
    make_contacts.build_cube_drop()
    addon_utils.enable("bl_ext.user_default.timbre", default_set=True)
    scene = bpy.context.scene
    scene.objects["Cube"].timbre.material = "oak"
    scene.objects["Floor"].timbre.material = "concrete"
    scene.timbre.output_dir = os.path.join(home, "soundtrack")
    if bpy.ops.timbre.render_soundtrack() != {"FINISHED"}:
        sys.exit("the soundtrack did not render")
    strip = [s for s in scene.sequence_editor.strips_all if s.get("timbre_soundtrack")][0]
    sound = read_wav(bpy.path.abspath(strip.sound.filepath))
    shutil.copy(os.path.join(scene.timbre.output_dir, "Scene", "soundtrack.tt"),
                os.path.join(out, "blender-cube-drop.tt"))

    look(bpy, scene)
    frames = {}
    shown = [frame for row in FRAMES for frame in row]
    for frame in range(scene.frame_start, max(shown) + 1):
        scene.frame_set(frame)
        if frame in shown:
            path = os.path.join(home, f"frame-{frame}.png")
            scene.render.filepath = path
            bpy.ops.render.render(write_still=True)
            frames[frame] = Image.open(path).convert("RGB")

    fps = scene.render.fps / scene.render.fps_base
    width, height = frames[shown[0]].size
    pad, label, wave_height = 6, 16, 90
    row_height = height + label + wave_height + 2 * pad
    picture = Image.new("RGB", (len(FRAMES[0]) * (width + pad) + pad,
                                len(FRAMES) * row_height + pad), "white")
    draw = ImageDraw.Draw(picture)
    rate = len(sound) / ((scene.frame_end - scene.frame_start + 1) / fps)
    peak = max(1e-9, float(np.abs(sound).max()))
    for r, row in enumerate(FRAMES):
        y = pad + r * row_height
        middle = y + height + label + wave_height // 2
        for k, frame in enumerate(row):
            x = pad + k * (width + pad)
            picture.paste(frames[frame], (x, y))
            draw.text((x + 4, y + height + 2), f"frame {frame}", fill="black")
            # The frame's 1/fps seconds of sound, from the time its picture shows.
            start = int((frame - scene.frame_start) / fps * rate)
            stop = int((frame + 1 - scene.frame_start) / fps * rate)
            piece = sound[start:stop] / peak
            draw.line([(x, middle), (x + width, middle)], fill=(200, 200, 200))
            for column in range(width):
                a = int(column * len(piece) / width)
                b = max(a + 1, int((column + 1) * len(piece) / width))
                lo, hi = float(piece[a:b].min()), float(piece[a:b].max())
                half = wave_height // 2 - 2
                draw.line([(x + column, middle - hi * half), (x + column, middle - lo * half)],
                          fill=(20, 60, 140))
    path = os.path.join(out, "blender-cube-drop.png")
    picture.save(path)
    print(path)


if __name__ == "__main__":
    main()
