"""The motion of a Blender scene, written as an animated glTF 2.0 binary (.glb) that
timbre's `motion` form reads.

Blender's own glTF exporter is not used: it exports no rigid-body simulation (only
actions), keys cameras only when asked, and puts NTSC frames at the wrong times.
Here every object is read as Blender evaluates it: the scene is stepped frame by
frame (and sub-frame) from its start frame, so rigid-body caches, constraints,
drivers and parents are what the picture shows, and each object's `matrix_world` is
written as the world transform of a node of its own (no hierarchy), with LINEAR keys.

Time: the scene's start frame is time 0, and frame f plays at
(f - frame_start) * fps_base / fps seconds, so the sound lines up with a strip at the
start frame. Units: Blender units times the scene's unit scale, in metres. Axes:
Blender's (x, y, z) is written as glTF's (x, z, -y), which timbre reads back as
Blender's.
"""

import json
import math
import struct

import numpy as np

# glTF's component types and targets.
FLOAT = 5126
UNSIGNED_INT = 5125
ARRAY_BUFFER = 34962
ELEMENT_ARRAY_BUFFER = 34963

# A camera's local frame in glTF looks along -Z with +Y up, as Blender's does; after
# the change of axes it must be turned -90 degrees about X to stay so.
CAMERA_CORRECTION = (math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0)  # w, x, y, z


class ShotError(Exception):
    """A scene whose motion cannot be written (the message says why)."""


def metres_per_unit(scene):
    """Metres in one Blender unit: the scene's unit scale (1 without a unit system)."""
    units = scene.unit_settings
    return units.scale_length if units.system != "NONE" else 1.0


def qmul(a, b):
    """The product of quaternions a and b, each (w, x, y, z)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def to_gltf_point(p, scale):
    """Blender's (x, y, z) in its units as glTF's (x, z, -y) in metres."""
    return (p[0] * scale, p[2] * scale, -p[1] * scale)


def world_pose(matrix, unit_scale, is_camera):
    """The glTF translation, rotation (x, y, z, w) and scale of a world matrix."""
    location, rotation, size = matrix.decompose()
    w, x, y, z = rotation.normalized()
    q = (w, x, z, -y)
    if is_camera:
        q = qmul(q, CAMERA_CORRECTION)
    translation = to_gltf_point(location, unit_scale)
    return translation, (q[1], q[2], q[3], q[0]), (size[0], size[2], size[1])


def sample_times(scene, subframes):
    """(frame, subframe, seconds) of every sample: each frame of the range and, with
    `subframes` > 1, that many evenly spaced samples per frame up to the last frame."""
    fps = scene.render.fps / scene.render.fps_base
    out = []
    for frame in range(scene.frame_start, scene.frame_end + 1):
        for k in range(subframes if frame < scene.frame_end else 1):
            sub = k / subframes
            out.append((frame, sub, (frame + sub - scene.frame_start) / fps))
    return out


def evaluated_mesh(obj, depsgraph, unit_scale):
    """The triangles of `obj` as Blender shows it (modifiers applied), in its own
    frame before its scale: (vertices N x 3 float32 in glTF axes, indices M x 3
    uint32), or None for an object with no surface."""
    evaluated = obj.evaluated_get(depsgraph)
    try:
        mesh = evaluated.to_mesh()
    except RuntimeError:
        return None
    if mesh is None:
        return None
    try:
        mesh.calc_loop_triangles()
        n = len(mesh.vertices)
        m = len(mesh.loop_triangles)
        if n == 0 or m == 0:
            return None
        co = np.empty(n * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        tris = np.empty(m * 3, dtype=np.int64)
        mesh.loop_triangles.foreach_get("vertices", tris)
    finally:
        evaluated.to_mesh_clear()
    co = co.reshape(n, 3) * unit_scale
    vertices = np.stack([co[:, 0], co[:, 2], -co[:, 1]], axis=1).astype(np.float32)
    return vertices, tris.reshape(m, 3).astype(np.uint32)


class _Buffer:
    """The binary chunk, with glTF's buffer views and accessors into it."""

    def __init__(self):
        self.data = bytearray()
        self.views = []
        self.accessors = []

    def add(self, array, kind, component, target=None, bounds=False):
        array = np.ascontiguousarray(array)
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self.data += array.tobytes()
        self.views.append(view)
        accessor = {
            "bufferView": len(self.views) - 1,
            "componentType": component,
            "count": int(array.shape[0]),
            "type": kind,
        }
        if bounds:
            flat = array.reshape(array.shape[0], -1)
            accessor["min"] = [float(v) for v in flat.min(axis=0)]
            accessor["max"] = [float(v) for v in flat.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def write_glb(out, scene, depsgraph, objects, subframes=1, progress=None):
    """Step `scene` through its frame range and write the world motion, meshes and
    cameras of `objects` (a list of Blender objects) to the binary file `out`. The scene is left at
    the frame it was on. `progress(fraction)` is called as frames go by."""
    unit_scale = metres_per_unit(scene)
    if not (unit_scale > 0.0 and math.isfinite(unit_scale)):
        raise ShotError(f"the scene's unit scale is {unit_scale}: it must be above 0")
    if scene.frame_end < scene.frame_start:
        raise ShotError("the scene's frame range is empty (End is before Start)")
    names = [obj.name for obj in objects]
    times = sample_times(scene, subframes)
    poses = {name: [] for name in names}
    was = (scene.frame_current, scene.frame_subframe)
    try:
        # From the start frame on, one frame at a time: a rigid-body world steps
        # (or reads its cache) only forwards from its start.
        for k, (frame, sub, _) in enumerate(times):
            scene.frame_set(frame, subframe=sub)
            for obj in objects:
                evaluated = obj.evaluated_get(depsgraph)
                poses[obj.name].append(
                    world_pose(evaluated.matrix_world, unit_scale, obj.type == "CAMERA"))
            if progress is not None and k % 8 == 0:
                progress(k / len(times))
        scene.frame_set(scene.frame_start)
        meshes = {obj.name: evaluated_mesh(obj, depsgraph, unit_scale)
                  for obj in objects if obj.type != "CAMERA"}
    finally:
        scene.frame_set(was[0], subframe=was[1])

    buffer = _Buffer()
    seconds = np.array([t for _, _, t in times], dtype=np.float32)
    if len(seconds) > 1 and not np.all(np.diff(seconds) > 0):
        raise ShotError("the frame rate is too high for glTF's times (they do not increase)")
    time_accessor = None
    gltf_nodes, gltf_meshes, gltf_cameras = [], [], []
    samplers, channels = [], []
    for index, obj in enumerate(objects):
        track = poses[obj.name]
        translation, rotation, scale = track[0]
        node = {"name": obj.name, "translation": list(translation),
                "rotation": list(rotation), "scale": list(scale)}
        mesh = meshes.get(obj.name)
        if mesh is not None:
            vertices, triangles = mesh
            position = buffer.add(vertices, "VEC3", FLOAT, ARRAY_BUFFER, bounds=True)
            indices = buffer.add(triangles.reshape(-1), "SCALAR", UNSIGNED_INT,
                                 ELEMENT_ARRAY_BUFFER)
            gltf_meshes.append({"name": obj.data.name if obj.data else obj.name,
                                "primitives": [{"attributes": {"POSITION": position},
                                                "indices": indices, "mode": 4}]})
            node["mesh"] = len(gltf_meshes) - 1
        if obj.type == "CAMERA":
            camera = obj.data
            aspect = scene.render.resolution_x * scene.render.pixel_aspect_x / max(
                1e-9, scene.render.resolution_y * scene.render.pixel_aspect_y)
            gltf_cameras.append({"name": camera.name, "type": "perspective", "perspective": {
                "yfov": float(camera.angle_y), "znear": max(1e-6, float(camera.clip_start)),
                "zfar": float(camera.clip_end), "aspectRatio": float(aspect)}})
            node["camera"] = len(gltf_cameras) - 1
        if len(track) > 1 and any(pose != track[0] for pose in track):
            if time_accessor is None:
                time_accessor = buffer.add(seconds, "SCALAR", FLOAT, bounds=True)
            values = {
                "translation": np.array([p[0] for p in track], dtype=np.float32),
                "rotation": _continuous(np.array([p[1] for p in track], dtype=np.float64)),
                "scale": np.array([p[2] for p in track], dtype=np.float32),
            }
            for target, array in values.items():
                kind = "VEC4" if target == "rotation" else "VEC3"
                output = buffer.add(array, kind, FLOAT)
                samplers.append({"input": time_accessor, "output": output,
                                 "interpolation": "LINEAR"})
                channels.append({"sampler": len(samplers) - 1,
                                 "target": {"node": index, "path": target}})
        gltf_nodes.append(node)

    document = {
        "asset": {"version": "2.0", "generator": "timbre Blender extension"},
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": list(range(len(gltf_nodes)))}],
        "nodes": gltf_nodes,
    }
    if gltf_meshes:
        document["meshes"] = gltf_meshes
    if gltf_cameras:
        document["cameras"] = gltf_cameras
    if channels:
        document["animations"] = [{"name": scene.name, "samplers": samplers,
                                   "channels": channels}]
    while len(buffer.data) % 4:
        buffer.data.append(0)
    if buffer.data:
        document["buffers"] = [{"byteLength": len(buffer.data)}]
        document["bufferViews"] = buffer.views
        document["accessors"] = buffer.accessors
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text
    if buffer.data:
        chunks += struct.pack("<I4s", len(buffer.data), b"BIN\0") + bytes(buffer.data)
    out.write(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)))
    out.write(chunks)


def _continuous(quaternions):
    """Quaternions with each on the side of the one before (q and -q are one
    rotation), as float32."""
    q = quaternions.copy()
    for k in range(1, len(q)):
        if np.dot(q[k], q[k - 1]) < 0.0:
            q[k] = -q[k]
    return q.astype(np.float32)
