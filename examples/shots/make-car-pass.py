"""Build the car-pass shot in Blender from nothing and export it as glTF.

Run it with a Python that has Blender's module (`pip install bpy==5.0.1`, Blender 5,
Python 3.11):

    python3 examples/shots/make-car-pass.py OUTDIR

The committed examples/car-pass.glb and examples/shots/car-pass.reference.json are
its output (run it into a scratch folder and copy them); it makes the same bytes every
time. .ci/run makes a fresh pair for the tests (TIMBRE_BLENDER_SHOT).

It writes two files:

- OUTDIR/car-pass.glb, exported by Blender's own glTF exporter;
- OUTDIR/car-pass.reference.json, what Blender itself says about the shot: every
  object's world transform (`matrix_world`) at every frame and at sub-frames, the
  camera's view direction, and the raw keyframes. Tests compare timbre's import of
  the .glb against it.

The scene runs at 24 fps, frames 1 to 120 (5 s of glTF time, 0.0417 s to 5 s: the
exporter writes frame f at time f / 24 s). Blender's axes, Z up, metres:

- "Road", an empty at (0, 4, 0), turned 5 degrees about Z and scaled 1.25: the
  parent of the car, so the car's world position needs the hierarchy.
- "Car", a 4 x 1.8 x 1.4 m box driving along the road's x axis from -48 to +48
  road units, with Bezier keys (automatic clamped handles: it eases in at the start
  and out at the end). In the world it goes from (-59.8, -1.2, 0) to (59.8, 9.2, 0):
  24 m/s on average, 33 m/s at most, 16 m from the camera at its closest.
- "Ball", a sphere of radius 0.12 m dropped from 2 m at (2, -6) and bouncing lower
  each time (peaks 1.2, 0.7, 0.4, 0.22 m) while it rolls to x = 4, with linear keys.
  At each contact (frames 16, 40, 60, 76, 88) its centre dips to 0.10 m (a 2 cm
  squash), so its height falls through 0.12 m five times; it rests from frame 88.
- "Door", a 1 x 0.05 x 2.1 m box hinged on its vertical edge at (-4, -9, 0): it
  opens from 0 to 100 degrees about Z (frames 20 to 50) and closes again (80 to
  110), Bezier keys.
- "Wall", a static 6 x 0.3 x 3 m box, for obstacles.
- "Camera" at (0, -12, 1.6) looking along +Y at the road, panning from 25 degrees
  left to 25 degrees right with Bezier keys (its camera data is named "CameraLens",
  so that the two names can be told apart in the file).
"""

import json
import math
import os
import sys

import bpy
from bpy_extras import anim_utils
from mathutils import Vector

FPS = 24
FRAME_START = 1
FRAME_END = 120
# Sub-frame offsets sampled for the reference, besides the frames themselves.
SUBFRAMES = (0.0, 0.25, 0.5)
ANIMATED = ("Car", "Ball", "Door", "Camera", "Road")

# The exporter's settings, as an animator would set them in File > Export > glTF 2.0.
# Everything not named here is the exporter's default.
EXPORT_SETTINGS = dict(
    export_format="GLB",  # Format: glTF Binary (.glb)
    export_yup=True,  # Transform: +Y Up (the glTF convention)
    export_cameras=True,  # Include: Cameras (off by default: no camera node without it)
    export_apply=True,  # Data > Mesh: Apply Modifiers
    export_animations=True,  # Animation: on
    export_animation_mode="ACTIONS",  # Animation mode: Actions (one glTF animation per action)
    export_frame_range=True,  # Rest & Ranges: Limit to Playback Range, frames 1..120
    export_force_sampling=True,  # Sampling Animations: on (LINEAR keys at every frame)
    export_frame_step=1,  # Sampling Animations: Sampling Rate 1, every frame
    export_optimize_animation_size=True,  # Optimize Animation Size: default, drops nothing here
)


def box_mesh(name, size, origin_offset=(0.0, 0.0, 0.0)):
    """A box mesh of `size` (x, y, z) metres whose centre sits at `origin_offset`."""
    sx, sy, sz = (s / 2.0 for s in size)
    ox, oy, oz = origin_offset
    verts = [
        (ox + x * sx, oy + y * sy, oz + z * sz)
        for x in (-1, 1)
        for y in (-1, 1)
        for z in (-1, 1)
    ]
    faces = [
        (0, 1, 3, 2),
        (4, 6, 7, 5),
        (0, 4, 5, 1),
        (2, 3, 7, 6),
        (0, 2, 6, 4),
        (1, 5, 7, 3),
    ]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def sphere_mesh(name, radius, segments=12, rings=6):
    """A low-poly UV sphere, built vertex by vertex: bmesh's sphere numbers its loops
    differently from run to run, and the file should come out the same every time."""
    verts = [(0.0, 0.0, radius)]
    for ring in range(1, rings):
        polar = math.pi * ring / rings
        for segment in range(segments):
            azimuth = 2.0 * math.pi * segment / segments
            verts.append((radius * math.sin(polar) * math.cos(azimuth),
                          radius * math.sin(polar) * math.sin(azimuth),
                          radius * math.cos(polar)))
    verts.append((0.0, 0.0, -radius))
    bottom = len(verts) - 1

    def ring_vertex(ring, segment):
        return 1 + (ring - 1) * segments + segment % segments

    faces = [(0, ring_vertex(1, s), ring_vertex(1, s + 1)) for s in range(segments)]
    for ring in range(1, rings - 1):
        for s in range(segments):
            faces.append((ring_vertex(ring, s), ring_vertex(ring + 1, s),
                          ring_vertex(ring + 1, s + 1), ring_vertex(ring, s + 1)))
    faces += [(bottom, ring_vertex(rings - 1, s + 1), ring_vertex(rings - 1, s))
              for s in range(segments)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def add_object(name, data, location=(0.0, 0.0, 0.0)):
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def fcurves_of(obj):
    """The object's F-curves (Blender 5 keeps them in the action slot's channelbag)."""
    anim = obj.animation_data
    if anim is None or anim.action is None:
        return []
    bag = anim_utils.action_get_channelbag_for_slot(anim.action, anim.action_slot)
    return list(bag.fcurves) if bag is not None else []


def key(obj, path, frame, value, index=-1):
    """Set `obj.path` (or one component of it) to `value` and key it at `frame`."""
    if index < 0:
        setattr(obj, path, value)
    else:
        getattr(obj, path)[index] = value
    obj.keyframe_insert(data_path=path, index=index, frame=frame)


def set_interpolation(obj, interpolation):
    for fcurve in fcurves_of(obj):
        for point in fcurve.keyframe_points:
            point.interpolation = interpolation
        fcurve.update()


def build_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = FPS
    scene.render.fps_base = 1.0
    scene.frame_start = FRAME_START
    scene.frame_end = FRAME_END
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 1.0

    road = add_object("Road", None, location=(0.0, 4.0, 0.0))
    road.empty_display_type = "ARROWS"
    road.rotation_euler = (0.0, 0.0, math.radians(5.0))
    road.scale = (1.25, 1.25, 1.25)

    # The car is modelled in road units: 4 x 1.8 x 1.4 m in the world after the
    # road's 1.25 scale, wheels on the road (its origin at the bottom centre).
    car_size = (4.0 / 1.25, 1.8 / 1.25, 1.4 / 1.25)
    car = add_object("Car", box_mesh("CarBody", car_size, (0, 0, car_size[2] / 2)))
    car.parent = road  # parent inverse stays identity: the car's keys are in road space
    for frame, x, y in ((1, -48.0, 0.0), (40, -16.0, 0.4), (80, 16.0, -0.4), (120, 48.0, 0.0)):
        key(car, "location", frame, (x, y, 0.0))
    set_interpolation(car, "BEZIER")

    # The ball falls from 2 m and bounces, each bounce lower; linear keys make the
    # bounces sharp V's at each contact.
    ball = add_object("Ball", sphere_mesh("BallSurface", 0.12), location=(2.0, -6.0, 2.0))
    heights = [(1, 2.0), (16, 0.10), (28, 1.2), (40, 0.10), (50, 0.70), (60, 0.10),
               (68, 0.40), (76, 0.10), (82, 0.22), (88, 0.10), (120, 0.10)]
    for frame, z in heights:
        key(ball, "location", frame, z, index=2)
    key(ball, "location", 1, 2.0, index=0)
    key(ball, "location", 88, 4.0, index=0)
    key(ball, "location", 1, -6.0, index=1)
    set_interpolation(ball, "LINEAR")

    # The door's origin is its hinge: the panel extends 1 m along +x from it.
    door = add_object("Door", box_mesh("DoorPanel", (1.0, 0.05, 2.1), (0.5, 0.0, 1.05)),
                      location=(-4.0, -9.0, 0.0))
    for frame, degrees in ((1, 0.0), (20, 0.0), (50, 100.0), (80, 100.0), (110, 0.0)):
        key(door, "rotation_euler", frame, math.radians(degrees), index=2)
    set_interpolation(door, "BEZIER")

    add_object("Wall", box_mesh("WallBlock", (6.0, 0.3, 3.0)), location=(-10.0, -5.0, 1.5))

    lens = bpy.data.cameras.new("CameraLens")
    lens.lens = 35.0
    camera = add_object("Camera", lens, location=(0.0, -12.0, 1.6))
    # Rotation X 88 degrees looks along +Y, 2 degrees down; Z pans left to right.
    camera.rotation_euler = (math.radians(88.0), 0.0, 0.0)
    key(camera, "rotation_euler", 1, math.radians(25.0), index=2)
    key(camera, "rotation_euler", 120, math.radians(-25.0), index=2)
    set_interpolation(camera, "BEZIER")
    scene.camera = camera
    return scene


def rounded(values, digits=9):
    return [round(v, digits) + 0.0 for v in values]


def sample(obj):
    location, rotation, _scale = obj.matrix_world.decompose()
    entry = {"position": rounded(location), "rotation_wxyz": rounded(rotation)}
    if obj.type == "CAMERA":
        view = obj.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))
        entry["view_direction"] = rounded(view.normalized())
    return entry


def keyframes(obj):
    curves = []
    for fcurve in fcurves_of(obj):
        curves.append({
            "data_path": fcurve.data_path,
            "index": fcurve.array_index,
            "keys": [{
                "frame": point.co[0],
                "value": round(point.co[1], 12) + 0.0,
                "interpolation": point.interpolation,
                "handle_left": rounded(point.handle_left, 12),
                "handle_right": rounded(point.handle_right, 12),
                "handle_left_type": point.handle_left_type,
                "handle_right_type": point.handle_right_type,
            } for point in fcurve.keyframe_points],
        })
    return curves


def reference(scene):
    """Blender's own answer: world transforms at every frame and sub-frame."""
    objects = {name: {"type": scene.objects[name].type, "samples": []} for name in ANIMATED}
    for frame in range(FRAME_START, FRAME_END + 1):
        for subframe in SUBFRAMES:
            if frame == FRAME_END and subframe > 0.0:
                continue
            scene.frame_set(frame, subframe=subframe)
            for name in ANIMATED:
                entry = {"frame": frame + subframe}
                entry.update(sample(scene.objects[name]))
                objects[name]["samples"].append(entry)
    for name in ANIMATED:
        objects[name]["keyframes"] = keyframes(scene.objects[name])
    scene.frame_set(FRAME_START)
    # No object here animates its scale: one world scale per object is enough.
    for name in ANIMATED:
        objects[name]["world_scale"] = rounded(scene.objects[name].matrix_world.to_scale())
    wall = scene.objects["Wall"]
    objects["Wall"] = {"type": wall.type, "static": sample(wall),
                       "mesh_bounds_world": mesh_bounds_world(wall)}
    return {
        "blender_version": bpy.app.version_string,
        "axes": "Blender world: Z up, metres; rotation_wxyz is the world rotation",
        "fps": scene.render.fps / scene.render.fps_base,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "gltf_time_of_frame": "t = frame / fps",
        "export_settings": EXPORT_SETTINGS,
        "objects": objects,
    }


def mesh_bounds_world(obj):
    corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    return {
        "min": rounded([min(c[i] for c in corners) for i in range(3)]),
        "max": rounded([max(c[i] for c in corners) for i in range(3)]),
    }


def write_reference(data, path):
    """JSON with one sample per line: small, and readable in a diff."""
    with open(path, "w", encoding="utf-8") as out:
        out.write("{\n")
        top = [k for k in data if k != "objects"]
        for name in top:
            out.write(f"  {json.dumps(name)}: {json.dumps(data[name])},\n")
        out.write('  "objects": {\n')
        names = list(data["objects"])
        for i, name in enumerate(names):
            obj = data["objects"][name]
            out.write(f"    {json.dumps(name)}: {{\n")
            fields = list(obj)
            for j, field in enumerate(fields):
                end = ",\n" if j + 1 < len(fields) else "\n"
                value = obj[field]
                if isinstance(value, list):
                    out.write(f"      {json.dumps(field)}: [\n")
                    lines = [f"        {json.dumps(item)}" for item in value]
                    out.write(",\n".join(lines))
                    out.write(f"\n      ]{end}")
                else:
                    out.write(f"      {json.dumps(field)}: {json.dumps(value)}{end}")
            out.write("    }" + (",\n" if i + 1 < len(names) else "\n"))
        out.write("  }\n}\n")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: make-car-pass.py OUTDIR")
    outdir = os.path.abspath(sys.argv[1])
    os.makedirs(outdir, exist_ok=True)
    scene = build_scene()
    scene.frame_set(FRAME_START)
    glb = os.path.join(outdir, "car-pass.glb")
    result = bpy.ops.export_scene.gltf(filepath=glb, **EXPORT_SETTINGS)
    if result != {"FINISHED"}:
        sys.exit(f"glTF export failed: {result}")
    write_reference(reference(scene), os.path.join(outdir, "car-pass.reference.json"))
    print(f"wrote {glb} and car-pass.reference.json")


if __name__ == "__main__":
    main()
