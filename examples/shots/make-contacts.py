"""Build the rigid-body contact shots in Blender, simulate them, and export them as glTF.

Run it with a Python that has Blender's module (`pip install bpy==5.0.1`, Blender 5,
Python 3.11):

    python3 examples/shots/make-contacts.py OUTDIR [NAME...]

NAME is any of cube-drop, stairs, dominoes, can (all four without one). For each it
writes OUTDIR/NAME.glb (Blender's own glTF exporter, every frame sampled) and
OUTDIR/NAME.reference.json: the scene as Blender simulated it (gravity, each body's
mass, collision shape, margin and size, its world transform at every frame) and the
contacts derived from that motion alone by examples/shots/contact_reference.py, which
knows the physics and the shapes and nothing of timbre. The committed copies in
examples/shots/ are its output; it makes the same bytes every time. .ci/run makes a
fresh set for the tests (TIMBRE_BLENDER_SHOT).

Every shot runs at 24 fps from frame 1; glTF time is frame / 24 s. Blender's axes,
Z up, metres, gravity (0, 0, -9.81) m/s^2. The simulation is Blender's rigid-body
world (Bullet): 20 substeps per frame (480 Hz), 20 solver iterations. Then every
body's matrix_world is read at every frame and keyed (location and quaternion, linear),
the rigid-body world is removed, and the keys are exported.

Settings that matter for the contacts, the same in every shot unless a shot says:

- Linear and angular damping 0 (Blender's defaults are 0.04 and 0.1): free flight is
  then an exact parabola at constant angular velocity. With 20 substeps Bullet's
  semi-implicit Euler makes the second difference of the positions over one frame
  exactly g / fps^2, so the reference can tell flight frames from contact frames.
- Collision margins: 1 mm on boxes and cylinders (Bullet keeps the margin inside their
  size and rounds their edges by it; 0 would make its box-box contact unreliable), 0 on
  the triangle-mesh stairs (a margin there would thicken the surface), none on spheres
  (Bullet's sphere is its own margin).
- Bullet multiplies the two bodies' restitutions and frictions: the static bodies have
  restitution 1 and friction 1, so the moving body's own values are the pair's.
- Deactivation (sleeping) is off: a body at rest stays simulated.
- Starting velocities: Blender's rigid body has no initial velocity, so a body that
  must be thrown is "Animated" (kinematic) for its first frames, keyed linearly along
  its launch velocity, and turns dynamic at LAUNCH_FRAME; Bullet hands the kinematic
  motion's velocity on to the dynamic body. The kinematic frames carry no gravity.

The shots:

1. cube-drop (frames 1-72): "Cube", 0.2 m oak cube (5.6 kg, restitution 0.5,
   friction 0.5), tilted 20 deg about X and 12 deg about Y, dropped from 1 m (centre)
   onto "Floor", a static 4 x 4 x 0.2 m box whose top is z = 0. It lands on a corner,
   tumbles and bounces to rest.
2. stairs (frames 1-96): "Ball", radius 0.1 m, 0.5 kg, restitution 0.75, friction
   0.5, launched at 0.6 m/s along +x from (-0.95, 0, 1.35), 0.25 m above the top step
   of "Stairs" (one triangle mesh of five steps 0.3 m deep and 0.2 m high, tops
   z = 1.0, 0.8, ... 0.2, going down along +x from x = -1 to 0.5 m, 1 m wide in y; the
   mesh's origin is at (-1, 0, 0)). It bounces on every step, on the second and third
   twice (the second time on the step's nose), and then on "Floor".
3. dominoes (frames 1-72): eight pine dominoes "Domino.000" ... "Domino.007",
   0.02 x 0.1 x 0.2 m (x, y, z), 0.2 kg, friction 0.5, restitution 0.2, standing on
   "Floor" every 0.1 m along +x from x = 0. The first is tilted 8 deg forward about its
   front bottom edge (past balance, which is at 5.7 deg) and topples; each topples the
   next, and all lie on one another by frame 36.
4. can (frames 1-96): "Can", a closed cylinder (radius 0.033 m, height 0.12 m, 0.06
   kg, collision shape cylinder, restitution 0.1, friction 0.1) lying on its side (its
   axis along world Y), launched at 1.5 m/s along +x without spin from (-1, 0, 0.133),
   0.1 m above "Floor". It lands, slides while friction spins it up, rolls, and comes
   to rest. Its rolling resistance is its angular damping, 0.999 (Bullet multiplies its
   angular velocity by 0.001 per second; it launches without spin, so its flight is
   still exact): without it a cylinder on a flat floor rolls on for ever.
"""

import importlib.util
import math
import os
import sys

import bpy
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import contact_reference  # noqa: E402  (beside this script)

# The car-pass script's deterministic mesh builders and helpers.
_spec = importlib.util.spec_from_file_location(
    "make_car_pass", os.path.join(os.path.dirname(os.path.abspath(__file__)), "make-car-pass.py"))
car_pass = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(car_pass)
box_mesh, sphere_mesh, add_object = car_pass.box_mesh, car_pass.sphere_mesh, car_pass.add_object

FPS = 24
GRAVITY = (0.0, 0.0, -9.81)
SUBSTEPS = 20
SOLVER_ITERATIONS = 20
BOX_MARGIN = 0.001
MESH_MARGIN = 0.0
# The frame at which a launched body turns from kinematic to dynamic.
LAUNCH_FRAME = 4

# The exporter's settings: as in make-car-pass.py (every frame sampled, linear keys).
EXPORT_SETTINGS = dict(car_pass.EXPORT_SETTINGS)


def cylinder_mesh(name, radius, height, segments=24):
    """A closed cylinder along local Z, centred on the origin."""
    half = height / 2.0
    verts = []
    for z in (-half, half):
        for s in range(segments):
            a = 2.0 * math.pi * s / segments
            verts.append((radius * math.cos(a), radius * math.sin(a), z))
    faces = [tuple(range(segments - 1, -1, -1)), tuple(range(segments, 2 * segments))]
    faces += [(s, (s + 1) % segments, segments + (s + 1) % segments, segments + s)
              for s in range(segments)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def stairs_mesh(name, steps, depth, rise, width):
    """A staircase going down along +x: step k (0 at the top) has its top at
    z = (steps - k) * rise over x in [k * depth, (k + 1) * depth]; bottom at z = 0."""
    profile = [(0.0, 0.0)]
    for k in range(steps):
        top = (steps - k) * rise
        profile += [(k * depth, top), ((k + 1) * depth, top)]
    profile.append((steps * depth, 0.0))
    n = len(profile)
    half = width / 2.0
    verts = [(x, -half, z) for x, z in profile] + [(x, half, z) for x, z in profile]
    faces = [tuple(range(n)), tuple(range(2 * n - 1, n - 1, -1))]
    faces += [(i, n + i, n + (i + 1) % n, (i + 1) % n) for i in range(n)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    boxes = [{"min": [k * depth, -half, 0.0], "max": [(k + 1) * depth, half, (steps - k) * rise]}
             for k in range(steps)]
    return mesh, boxes


def new_scene(frame_end):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = FPS
    scene.render.fps_base = 1.0
    scene.frame_start = 1
    scene.frame_end = frame_end
    scene.unit_settings.system = "METRIC"
    scene.gravity = GRAVITY
    bpy.ops.rigidbody.world_add()
    world = scene.rigidbody_world
    world.substeps_per_frame = SUBSTEPS
    world.solver_iterations = SOLVER_ITERATIONS
    world.point_cache.frame_start = 1
    world.point_cache.frame_end = frame_end
    return scene


def rigid(obj, body_type, shape, margin, mass=1.0, friction=1.0, restitution=1.0):
    """Make `obj` a rigid body; returns the body's description for the reference."""
    with bpy.context.temp_override(object=obj, active_object=obj, selected_objects=[obj]):
        bpy.ops.rigidbody.object_add(type=body_type)
    body = obj.rigid_body
    body.collision_shape = shape
    body.use_margin = True
    body.collision_margin = margin
    body.mass = mass
    body.friction = friction
    body.restitution = restitution
    body.linear_damping = 0.0
    body.angular_damping = 0.0
    body.use_deactivation = False
    return body


def add_floor():
    floor = add_object("Floor", box_mesh("FloorSlab", (4.0, 4.0, 0.2)), (0.0, 0.0, -0.1))
    rigid(floor, "PASSIVE", "BOX", BOX_MARGIN)
    return {"Floor": {"shape": "box", "size": [4.0, 4.0, 0.2], "static": True,
                      "margin": BOX_MARGIN, "top_z": 0.0}}


def add_camera(scene, location, target):
    lens = bpy.data.cameras.new("CameraLens")
    lens.lens = 35.0
    camera = add_object("Camera", lens, location)
    direction = Vector(target) - Vector(location)
    camera.rotation_mode = "QUATERNION"
    camera.rotation_quaternion = direction.to_track_quat("-Z", "Y")
    scene.camera = camera


def launch(obj, velocity, frame_end_kinematic=LAUNCH_FRAME - 1):
    """Key `obj` kinematic along `velocity` (m/s) from frame 1, dynamic from LAUNCH_FRAME."""
    body = obj.rigid_body
    start = Vector(obj.location)
    for frame in (1, LAUNCH_FRAME):
        obj.location = start + Vector(velocity) * ((frame - 1) / FPS)
        obj.keyframe_insert("location", frame=frame)
    body.kinematic = True
    obj.keyframe_insert("rigid_body.kinematic", frame=frame_end_kinematic)
    body.kinematic = False
    obj.keyframe_insert("rigid_body.kinematic", frame=LAUNCH_FRAME)
    for fcurve in car_pass.fcurves_of(obj):
        for point in fcurve.keyframe_points:
            point.interpolation = "LINEAR" if fcurve.data_path == "location" else "CONSTANT"
        fcurve.extrapolation = "LINEAR" if fcurve.data_path == "location" else "CONSTANT"
    obj.location = start


def body_entry(obj, shape, size, margin):
    body = obj.rigid_body
    return {"shape": shape, "size": size, "margin": margin, "static": False,
            "mass": body.mass, "friction": body.friction, "restitution": body.restitution,
            "linear_damping": body.linear_damping, "angular_damping": body.angular_damping}


def build_cube_drop():
    scene = new_scene(72)
    objects = add_floor()
    cube = add_object("Cube", box_mesh("CubeBox", (0.2, 0.2, 0.2)), (0.0, 0.0, 1.0))
    cube.rotation_euler = (math.radians(20.0), math.radians(12.0), 0.0)
    rigid(cube, "ACTIVE", "BOX", BOX_MARGIN, mass=5.6, friction=0.5, restitution=0.5)
    objects["Cube"] = body_entry(cube, "box", [0.2, 0.2, 0.2], BOX_MARGIN)
    add_camera(scene, (1.6, -2.4, 1.2), (0.0, 0.0, 0.4))
    return scene, objects, ["Cube"]


def build_stairs():
    scene = new_scene(96)
    objects = add_floor()
    mesh, boxes = stairs_mesh("StairsSteps", 5, 0.3, 0.2, 1.0)
    stairs = add_object("Stairs", mesh, (-1.0, 0.0, 0.0))
    rigid(stairs, "PASSIVE", "MESH", MESH_MARGIN)
    for box in boxes:
        box["min"][0] -= 1.0
        box["max"][0] -= 1.0
    objects["Stairs"] = {"shape": "mesh", "static": True, "margin": MESH_MARGIN,
                         "steps": 5, "step_depth": 0.3, "step_rise": 0.2, "width": 1.0,
                         "location": [-1.0, 0.0, 0.0], "boxes": boxes}
    ball = add_object("Ball", sphere_mesh("BallSurface", 0.1), (-0.95, 0.0, 1.35))
    rigid(ball, "ACTIVE", "SPHERE", 0.0, mass=0.5, friction=0.5, restitution=0.75)
    launch(ball, (0.6, 0.0, 0.0))
    objects["Ball"] = body_entry(ball, "sphere", [0.2, 0.2, 0.2], 0.0)
    objects["Ball"]["radius"] = 0.1
    objects["Ball"]["launch"] = {"velocity": [0.6, 0.0, 0.0], "dynamic_from_frame": LAUNCH_FRAME}
    add_camera(scene, (0.0, -3.5, 1.2), (-0.1, 0.0, 0.5))
    return scene, objects, ["Ball"]


DOMINOES = 8
DOMINO_SIZE = (0.02, 0.1, 0.2)
DOMINO_SPACING = 0.1


def build_dominoes():
    scene = new_scene(72)
    objects = add_floor()
    thick, width, height = DOMINO_SIZE
    names = []
    for i in range(DOMINOES):
        name = f"Domino.{i:03d}"
        domino = add_object(name, box_mesh(f"DominoBlock.{i:03d}", DOMINO_SIZE),
                            (i * DOMINO_SPACING, 0.0, height / 2.0))
        if i == 0:
            # Tilt about the front bottom edge (x = thick / 2, z = 0): past balance.
            tilt = Matrix.Rotation(math.radians(8.0), 4, "Y")
            pivot = Vector((thick / 2.0, 0.0, 0.0))
            standing = Matrix.Translation((0.0, 0.0, height / 2.0))
            domino.matrix_world = (Matrix.Translation(pivot) @ tilt @ Matrix.Translation(-pivot)
                                   @ standing)
        rigid(domino, "ACTIVE", "BOX", BOX_MARGIN, mass=0.2, friction=0.5, restitution=0.2)
        objects[name] = body_entry(domino, "box", list(DOMINO_SIZE), BOX_MARGIN)
        names.append(name)
    objects["Domino.000"]["start"] = "tilted 8 deg about its front bottom edge"
    add_camera(scene, (0.35, -1.6, 0.6), (0.35, 0.0, 0.1))
    return scene, objects, names


def build_can():
    scene = new_scene(96)
    objects = add_floor()
    can = add_object("Can", cylinder_mesh("CanShell", 0.033, 0.12), (-1.0, 0.0, 0.133))
    can.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    rigid(can, "ACTIVE", "CYLINDER", BOX_MARGIN, mass=0.06, friction=0.1, restitution=0.1)
    can.rigid_body.angular_damping = 0.999
    launch(can, (1.5, 0.0, 0.0))
    objects["Can"] = body_entry(can, "cylinder", [0.066, 0.066, 0.12], BOX_MARGIN)
    objects["Can"].update(radius=0.033, height=0.12, axis_local="z",
                          launch={"velocity": [1.5, 0.0, 0.0], "dynamic_from_frame": LAUNCH_FRAME})
    add_camera(scene, (0.0, -2.5, 0.6), (0.0, 0.0, 0.05))
    return scene, objects, ["Can"]


SHOTS = {
    "cube-drop": build_cube_drop,
    "stairs": build_stairs,
    "dominoes": build_dominoes,
    "can": build_can,
}


def simulate_and_bake(scene, moving):
    """Step the simulation frame by frame, read every moving body's world transform,
    then replace the rigid-body world by plain linear keys at every frame."""
    frames = list(range(scene.frame_start, scene.frame_end + 1))
    poses = {name: [] for name in moving}
    for frame in frames:
        scene.frame_set(frame)
        for name in moving:
            location, rotation, _scale = scene.objects[name].matrix_world.decompose()
            poses[name].append((tuple(location), tuple(rotation)))
    for name in moving:
        obj = scene.objects[name]
        obj.animation_data_clear()
    bpy.ops.rigidbody.world_remove()
    for name in moving:
        obj = scene.objects[name]
        if obj.rigid_body is not None:
            with bpy.context.temp_override(object=obj, active_object=obj, selected_objects=[obj]):
                bpy.ops.rigidbody.object_remove()
        obj.rotation_mode = "QUATERNION"
        for frame, (location, rotation) in zip(frames, poses[name]):
            obj.location = location
            obj.rotation_quaternion = rotation
            obj.keyframe_insert("location", frame=frame)
            obj.keyframe_insert("rotation_quaternion", frame=frame)
        car_pass.set_interpolation(obj, "LINEAR")
    scene.frame_set(scene.frame_start)
    return frames, poses


def static_pose(obj):
    location, rotation, _scale = obj.matrix_world.decompose()
    return {"position": list(location), "rotation_wxyz": list(rotation)}


def make_shot(name, outdir):
    scene, objects, moving = SHOTS[name]()
    frames, poses = simulate_and_bake(scene, moving)
    for obj_name, entry in objects.items():
        if entry["static"]:
            entry.update(static_pose(scene.objects[obj_name]))
    glb = os.path.join(outdir, f"{name}.glb")
    result = bpy.ops.export_scene.gltf(filepath=glb, **EXPORT_SETTINGS)
    if result != {"FINISHED"}:
        sys.exit(f"glTF export failed: {result}")
    shot = {
        "shot": name,
        "blender_version": bpy.app.version_string,
        "axes": "Blender world: Z up, metres; rotation_wxyz is the world rotation",
        "fps": FPS,
        "frame_start": frames[0],
        "frame_end": frames[-1],
        "time_of_frame": "t = frame / fps (the glTF time)",
        "gravity": list(GRAVITY),
        "rigidbody_world": {"substeps_per_frame": SUBSTEPS, "solver_iterations": SOLVER_ITERATIONS},
        "export_settings": EXPORT_SETTINGS,
        "camera": static_pose(scene.objects["Camera"]),
        "objects": objects,
        "frames": {obj: [{"frame": f, "position": list(p), "rotation_wxyz": list(q)}
                         for f, (p, q) in zip(frames, poses[obj])] for obj in moving},
    }
    shot["contacts_reference"] = contact_reference.analyse(shot)
    contact_reference.write_json(shot, os.path.join(outdir, f"{name}.reference.json"))
    return shot


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: make-contacts.py OUTDIR [" + "|".join(SHOTS) + " ...]")
    outdir = os.path.abspath(sys.argv[1])
    names = sys.argv[2:] or list(SHOTS)
    unknown = [n for n in names if n not in SHOTS]
    if unknown:
        sys.exit(f"unknown shot {unknown[0]!r}: one of {', '.join(SHOTS)}")
    os.makedirs(outdir, exist_ok=True)
    for name in names:
        shot = make_shot(name, outdir)
        print(contact_reference.summary(shot))


if __name__ == "__main__":
    main()
