"""Contacts of a simulated shot, derived from its per-frame motion and nothing else.

make-contacts.py calls `analyse(shot)` with the shot's description: fps, gravity, the
shapes (box, sphere, cylinder; the floor's top plane; the stairs as boxes) and every
moving body's world position and rotation (quaternion w, x, y, z) at every frame. It
knows the physics and the geometry, and nothing of timbre: it is the independent
answer timbre's contact reconstruction is tested against.

Impacts from free flight. Between contacts a rigid body flies under gravity alone:
its centre follows a parabola with acceleration g and (for the shapes here, all
spinning about a principal axis or not spinning) it turns at a constant angular
velocity. A frame is a flight frame when the second difference of the positions
around it is g (within ACCEL_TOL) and the rotation step into it equals the step out
of it (within ANGULAR_ACCEL_TOL). Each run of such frames, with its two neighbours, is
one flight. The flight before a contact is fitted one-sided, from its own frames only
(centre: least squares with g known; rotation: the mean step), the fitted pose is
carried forward, and the impact is the first instant at which that pose touches a
static object (the root of the signed distance, by bisection). Its speeds are those of
the body's touching point (v + omega x r) in that fitted pose; the speed after comes
from the flight after, fitted the same way and carried back to the impact.

Dominoes: a domino falls about its edge, not in free flight; its impact on the next
is the instant its top front edge reaches the next one's back face, from a quadratic
fit of the edge's path over the frames before (the next one still stands there).

Rolling and sliding (the can): at each frame in contact with the floor, the slip
speed is the horizontal speed of the body's lowest point, |v + omega x r_contact|,
compared with the rolling speed |v| of its centre.
"""

import json
import math

import numpy as np

# Flight frames: |second difference * fps^2 - g| below this (m/s^2). Bullet's
# semi-implicit steps make it exactly g in flight (float32 noise is ~1e-3 m/s^2);
# one frame touching anything changes it by far more.
ACCEL_TOL = 0.05
# Flight frames: change of the angular velocity between the frame steps before and
# after, per second (rad/s^2). Exactly 0 in flight for these shapes.
ANGULAR_ACCEL_TOL = 0.5
# An impact counts only after a flight of at least this many frames.
MIN_FLIGHT_FRAMES = 3
# The impact is searched for from this many frames before the flight's last frame to
# this many after it (the contact lies between the last flight frame and the next).
SEARCH_BEFORE_FRAMES = 1.0
SEARCH_AFTER_FRAMES = 2.0
# A flight starting within this many frames after the impact's frame is its after-flight.
AFTER_FLIGHT_GAP_FRAMES = 2
# Rest: centre speed below REST_SPEED (m/s) and angular speed below REST_ANGULAR
# (rad/s), from central differences, for at least REST_MIN_FRAMES frames in a row.
# 0.3 rad/s turns the can's rim (the smallest radius here) at 0.01 m/s.
REST_SPEED = 0.01
REST_ANGULAR = 0.3
REST_MIN_FRAMES = 3
# A domino has started moving once it is this far (m) or this much turned (rad) from
# where it stood at the first frame.
MOVE_DISTANCE = 5e-4
MOVE_ANGLE = 5e-3
# The domino edge fit uses this many frames before the touch.
EDGE_FIT_FRAMES = 4
# The can touches the floor while its lowest point is within this gap (m) of the
# floor's top (its 1 mm margin is inside its size).
CONTACT_GAP = 2e-3
# Rolling: slip speed below SLIP_ABS + SLIP_REL * rolling speed (m/s).
SLIP_ABS = 0.02
SLIP_REL = 0.05


# --- quaternions (w, x, y, z) ----------------------------------------------------

def qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def qconj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


def rotation_matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def rotvec(q):
    """The rotation vector (axis * angle, angle in [0, pi]) of a unit quaternion."""
    if q[0] < 0:
        q = -q
    s = np.linalg.norm(q[1:])
    if s < 1e-12:
        return 2.0 * q[1:]
    return q[1:] / s * 2.0 * math.atan2(s, q[0])


def qexp(v):
    """The unit quaternion of the rotation vector v."""
    angle = np.linalg.norm(v)
    if angle < 1e-12:
        return np.array([1.0, v[0] / 2, v[1] / 2, v[2] / 2])
    axis = v / angle
    return np.concatenate([[math.cos(angle / 2)], axis * math.sin(angle / 2)])


def step_omega(q0, q1, fps):
    """World angular velocity that turns q0 into q1 in one frame."""
    return rotvec(qmul(q1, qconj(q0))) * fps


# --- shapes ----------------------------------------------------------------------

def support(body, rotation, centre, direction):
    """The body's surface point farthest along `direction` (world), in the given pose."""
    shape = body["shape"]
    local = rotation.T @ direction
    if shape == "sphere":
        return centre + body["radius"] * direction / np.linalg.norm(direction)
    if shape == "box":
        half = np.array(body["size"]) / 2.0
        return centre + rotation @ (np.sign(local) * half)
    if shape == "cylinder":
        radius, half = body["radius"], body["height"] / 2.0
        radial = np.array([local[0], local[1], 0.0])
        radial = radius * radial / max(np.linalg.norm(radial), 1e-12)
        # Lying flat (axis across `direction`): the middle of the contact line.
        axial = 0.0 if abs(local[2]) < 1e-3 else math.copysign(half, local[2])
        return centre + rotation @ (radial + np.array([0.0, 0.0, axial]))
    raise ValueError(f"no support for shape {shape}")


def box_distance(point, lo, hi):
    """Distance from a point outside an axis-aligned box, and the outward normal."""
    closest = np.minimum(np.maximum(point, lo), hi)
    gap = point - closest
    d = np.linalg.norm(gap)
    if d > 0:
        return d, gap / d
    # Inside: the nearest face.
    faces = [(point[i] - lo[i], -np.eye(3)[i]) for i in range(3)]
    faces += [(hi[i] - point[i], np.eye(3)[i]) for i in range(3)]
    depth, normal = min(faces, key=lambda f: f[0])
    return -depth, normal


def signed_distance(body, centre, rotation, static):
    """(distance, world contact point on the body, normal from the static object)."""
    if "top_z" in static:  # the floor: its top plane
        normal = np.array([0.0, 0.0, 1.0])
        point = support(body, rotation, centre, -normal)
        return point[2] - static["top_z"], point, normal
    if "boxes" in static:  # the stairs, as the union of its steps
        if body["shape"] != "sphere":
            raise ValueError("stairs contacts are worked out for a sphere only")
        best = None
        for box in static["boxes"]:
            d, normal = box_distance(centre, np.array(box["min"]), np.array(box["max"]))
            if best is None or d < best[0]:
                best = (d, normal)
        d, normal = best
        return d - body["radius"], centre - body["radius"] * normal, normal
    raise ValueError("unknown static object")


# --- flights ---------------------------------------------------------------------

def flight_frames(positions, rotations, fps, gravity):
    """Runs (first, last) of frame indices whose positions lie on one free flight."""
    free = []
    for i in range(1, len(positions) - 1):
        accel = (positions[i + 1] - 2 * positions[i] + positions[i - 1]) * fps * fps
        spin_in = step_omega(rotations[i - 1], rotations[i], fps)
        spin_out = step_omega(rotations[i], rotations[i + 1], fps)
        free.append(np.linalg.norm(accel - gravity) < ACCEL_TOL
                    and np.linalg.norm(spin_out - spin_in) * fps < ANGULAR_ACCEL_TOL)
    runs, start = [], None
    for i, ok in enumerate(free, start=1):
        if ok and start is None:
            start = i
        if not ok and start is not None:
            runs.append((start - 1, i))
            start = None
    if start is not None:
        runs.append((start - 1, len(positions) - 1))
    return runs


class Flight:
    """A free flight fitted from its own frames: pose(t) for any t, one-sided."""

    def __init__(self, frames, times, positions, rotations, gravity, fps, anchor):
        self.frames = frames
        self.gravity = gravity
        self.t0 = times[anchor]
        tau = times[frames[0]:frames[1] + 1] - self.t0
        lifted = positions[frames[0]:frames[1] + 1] - 0.5 * np.outer(tau * tau, gravity)
        # Least squares: lifted = p0 + v0 * tau.
        design = np.column_stack([np.ones_like(tau), tau])
        (self.p0, self.v0), *_ = np.linalg.lstsq(design, lifted, rcond=None)
        steps = [step_omega(rotations[i], rotations[i + 1], fps)
                 for i in range(frames[0], frames[1])]
        self.omega = np.mean(steps, axis=0)
        self.q0 = rotations[anchor]

    def pose(self, t):
        tau = t - self.t0
        centre = self.p0 + self.v0 * tau + 0.5 * self.gravity * tau * tau
        return centre, rotation_matrix(qmul(qexp(self.omega * tau), self.q0))

    def velocity(self, t):
        return self.v0 + self.gravity * (t - self.t0)

    def point_velocity(self, t, point):
        centre, _ = self.pose(t)
        return self.velocity(t) + np.cross(self.omega, point - centre)


def first_touch(flight, body, statics, t_from, t_to, steps=400):
    """The first root of the signed distance between t_from and t_to, or None."""
    def nearest(t):
        centre, rotation = flight.pose(t)
        return min(((signed_distance(body, centre, rotation, s), name)
                    for name, s in statics.items()), key=lambda x: x[0][0])

    times = np.linspace(t_from, t_to, steps + 1)
    (d_prev, _, _), _ = nearest(times[0])
    if d_prev <= 0:
        return None
    for lo, hi in zip(times[:-1], times[1:]):
        (d_hi, _, _), _ = nearest(hi)
        if d_hi <= 0:
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if nearest(mid)[0][0] > 0:
                    lo = mid
                else:
                    hi = mid
            t = 0.5 * (lo + hi)
            (d, point, normal), name = nearest(t)
            return t, name, point, normal
    return None


def flight_impacts(name, body, track, statics, fps, gravity, frame_start):
    times, positions, rotations = track
    runs = flight_frames(positions, rotations, fps, gravity)
    impacts = []
    for k, run in enumerate(runs):
        count = run[1] - run[0] + 1
        if count < MIN_FLIGHT_FRAMES or run[1] == len(times) - 1:
            continue
        before = Flight(run, times, positions, rotations, gravity, fps, anchor=run[1])
        touch = first_touch(before, body, statics, times[run[1]] - SEARCH_BEFORE_FRAMES / fps,
                            times[run[1]] + SEARCH_AFTER_FRAMES / fps)
        if touch is None:
            continue
        t, other, point, normal = touch
        v = before.point_velocity(t, point)
        vn = float(np.dot(v, normal))
        entry = {
            "time": t, "frame": t * fps, "a": name, "b": other,
            "point": point.tolist(), "normal": normal.tolist(),
            "normal_speed_before": -vn,
            "tangential_speed_before": float(np.linalg.norm(v - vn * normal)),
            "flight_before_frames": [frame_start + run[0], frame_start + run[1]],
            "normal_speed_after": None, "flight_after_frames": None,
            "after_flight_distance_at_impact": None,
        }
        following = runs[k + 1] if k + 1 < len(runs) else None
        if (following is not None and following[1] - following[0] + 1 >= MIN_FLIGHT_FRAMES
                and following[0] - t * fps + frame_start <= AFTER_FLIGHT_GAP_FRAMES):
            after = Flight(following, times, positions, rotations, gravity, fps,
                           anchor=following[0])
            centre_before, rotation_before = before.pose(t)
            body_point = rotation_before.T @ (point - centre_before)
            centre_after, rotation_after = after.pose(t)
            v_after = after.point_velocity(t, centre_after + rotation_after @ body_point)
            entry["normal_speed_after"] = float(np.dot(v_after, normal))
            # How far the after-flight, carried back, is from touching at the impact:
            # ~0 for one clean bounce (Bullet bounces on its 1/480 s substeps, so a
            # few mm at these speeds); large when more contacts came in between (a
            # cube landing on a corner and then on an edge).
            static = statics[other]
            entry["after_flight_distance_at_impact"] = signed_distance(
                body, centre_after, rotation_after, static)[0]
            entry["flight_after_frames"] = [frame_start + following[0],
                                            frame_start + following[1]]
        impacts.append(entry)
    return impacts


# --- rest, dominoes, rolling -------------------------------------------------------

def velocities(track, fps):
    """Central-difference centre velocity and angular velocity at interior frames."""
    times, positions, rotations = track
    out = []
    for i in range(1, len(times) - 1):
        v = (positions[i + 1] - positions[i - 1]) * fps / 2
        w = (step_omega(rotations[i - 1], rotations[i], fps)
             + step_omega(rotations[i], rotations[i + 1], fps)) / 2
        out.append((i, v, w))
    return out


def runs_of(labels):
    """[(label, first, last)] for runs of equal labels over (index, label) pairs."""
    runs = []
    for index, label in labels:
        if runs and runs[-1][0] == label and runs[-1][2] == index - 1:
            runs[-1][2] = index
        else:
            runs.append([label, index, index])
    return runs


def rest_intervals(track, fps, frame_start):
    labels = [(i, np.linalg.norm(v) < REST_SPEED and np.linalg.norm(w) < REST_ANGULAR)
              for i, v, w in velocities(track, fps)]
    return [{"frames": [frame_start + a, frame_start + b],
             "times": [(frame_start + a) / fps, (frame_start + b) / fps]}
            for still, a, b in runs_of(labels) if still and b - a + 1 >= REST_MIN_FRAMES]


def start_of_motion(track):
    _, positions, rotations = track
    for i in range(len(positions)):
        moved = np.linalg.norm(positions[i] - positions[0])
        turned = np.linalg.norm(rotvec(qmul(rotations[i], qconj(rotations[0]))))
        if moved > MOVE_DISTANCE or turned > MOVE_ANGLE:
            return i
    return None


def domino_touch(pusher, pushed, body, track_a, track_b, pusher_start, fps, frame_start):
    """When domino `pusher`'s top front edge reaches `pushed`'s back face.

    The frames [last, last + 1] between which the foremost corner of the edge crosses
    the face (as the pushed one stood at the first frame) bracket the touch. When the
    pusher was already toppling freely for EDGE_FIT_FRAMES frames up to `last` (that
    is, after the frame it was itself pushed), the corner's path over them is fitted by
    a quadratic and carried to the face; otherwise the gap is interpolated linearly
    between the two frames (a domino struck hard a frame before strikes the next)."""
    times, pos_a, rot_a = track_a
    _, pos_b, rot_b = track_b
    half = np.array(body["size"]) / 2.0
    corners = [np.array([half[0], y, half[2]]) for y in (-half[1], half[1])]
    face_normal = rotation_matrix(rot_b[0]) @ np.array([1.0, 0.0, 0.0])
    face_point = pos_b[0] - face_normal * half[0]

    def corner(i, c):
        return pos_a[i] + rotation_matrix(rot_a[i]) @ c

    def gap(i, c):
        return float(np.dot(face_point - corner(i, c), face_normal))

    crossing = next((i for i in range(len(times)) if min(gap(i, c) for c in corners) <= 0), None)
    if crossing is None or crossing == 0:
        return None
    last = crossing - 1
    lead = min(corners, key=lambda c: gap(crossing, c))  # the corner that gets there first
    entry = {"a": pusher, "b": pushed, "normal": (-face_normal).tolist(),
             "frames_bracket": [frame_start + last, frame_start + crossing]}
    first_fit = last + 1 - EDGE_FIT_FRAMES
    if first_fit >= pusher_start:
        window = range(first_fit, last + 1)
        tau = np.array([times[i] - times[last] for i in window])
        path = np.polyfit(tau, np.array([corner(i, lead) for i in window]), 2)
        gaps = np.polyfit(tau, [gap(i, lead) for i in window], 2)
        roots = sorted(r.real for r in np.roots(gaps) if abs(r.imag) < 1e-12 and r.real > 0)
        if roots and roots[0] <= times[crossing] - times[last]:
            tau_c = roots[0]
            velocity = 2 * path[0] * tau_c + path[1]
            point = path[0] * tau_c ** 2 + path[1] * tau_c + path[2]
            entry["fitted"] = True
            entry["method"] = (f"quadratic fit of the leading corner's path over frames "
                               f"{frame_start + first_fit}-{frame_start + last}")
            return finish_domino_touch(entry, times[last] + tau_c, point, velocity,
                                       face_normal, fps)
    g0, g1 = gap(last, lead), gap(crossing, lead)
    fraction = g0 / (g0 - g1)
    point = corner(last, lead) + fraction * (corner(crossing, lead) - corner(last, lead))
    velocity = (corner(crossing, lead) - corner(last, lead)) * fps
    # Without a fit the instant is within the bracket only roughly and the speeds are
    # the secant over the frame, the touch included: tests should not hold them to 5 %.
    entry["fitted"] = False
    entry["method"] = "linear between the bracketing frames (too few frames for a fit)"
    return finish_domino_touch(entry, times[last] + fraction / fps, point, velocity,
                               face_normal, fps)


def finish_domino_touch(entry, t, point, velocity, face_normal, fps):
    vn = float(np.dot(velocity, face_normal))
    entry.update({
        "time": t, "frame": t * fps, "point": list(point),
        "normal_speed_before": vn,
        "tangential_speed_before": float(np.linalg.norm(velocity - vn * face_normal)),
    })
    return entry


def rolling_contacts(name, body, track, floor, fps, frame_start, first_dynamic):
    times, positions, rotations = track
    labels, detail = [], {}
    for i, v, w in velocities(track, fps):
        if frame_start + i - 1 < first_dynamic:
            continue
        rotation = rotation_matrix(rotations[i])
        lowest = support(body, rotation, positions[i], np.array([0.0, 0.0, -1.0]))
        if lowest[2] - floor["top_z"] > CONTACT_GAP:
            continue
        slip_velocity = v + np.cross(w, lowest - positions[i])
        slip = float(np.linalg.norm(slip_velocity[:2]))
        rolling = float(np.linalg.norm(v[:2]))
        if np.linalg.norm(v) < REST_SPEED and np.linalg.norm(w) < REST_ANGULAR:
            kind = "rest"
        elif slip < SLIP_ABS + SLIP_REL * rolling:
            kind = "roll"
        else:
            kind = "slide"
        labels.append((i, kind))
        detail[i] = (slip, rolling)
    intervals = []
    for kind, a, b in runs_of(labels):
        slips = [detail[i][0] for i in range(a, b + 1)]
        speeds = [detail[i][1] for i in range(a, b + 1)]
        intervals.append({
            "kind": kind, "a": name, "b": "Floor",
            "frames": [frame_start + a, frame_start + b],
            "times": [(frame_start + a) / fps, (frame_start + b) / fps],
            "slip_speed": [min(slips), max(slips)],
            "rolling_speed": [min(speeds), max(speeds)],
        })
    return intervals


# --- the whole shot --------------------------------------------------------------

def tracks_of(shot):
    fps = shot["fps"]
    out = {}
    for name, frames in shot["frames"].items():
        times = np.array([f["frame"] / fps for f in frames])
        positions = np.array([f["position"] for f in frames], dtype=float)
        rotations = np.array([f["rotation_wxyz"] for f in frames], dtype=float)
        out[name] = (times, positions, rotations)
    return out


def tolerances():
    names = ["ACCEL_TOL", "ANGULAR_ACCEL_TOL", "MIN_FLIGHT_FRAMES", "SEARCH_BEFORE_FRAMES",
             "SEARCH_AFTER_FRAMES", "AFTER_FLIGHT_GAP_FRAMES", "REST_SPEED", "REST_ANGULAR",
             "REST_MIN_FRAMES", "MOVE_DISTANCE", "MOVE_ANGLE", "EDGE_FIT_FRAMES",
             "CONTACT_GAP", "SLIP_ABS", "SLIP_REL"]
    return {n.lower(): globals()[n] for n in names}


def analyse(shot):
    fps, gravity = shot["fps"], np.array(shot["gravity"], dtype=float)
    start = shot["frame_start"]
    objects = shot["objects"]
    statics = {n: o for n, o in objects.items() if o["static"]}
    tracks = tracks_of(shot)
    result = {
        "method": (
            "impacts: one-sided fits of each free flight (frames whose second difference "
            "is g and whose rotation steps are equal), carried to the first touch of a "
            f"static object; only impacts after a flight of >= {MIN_FLIGHT_FRAMES} frames. "
            "Speeds are of the touching point, v + omega x r: normal_speed_before "
            "towards the surface, normal_speed_after away from it (after-flight fit). "
            "Times are t = frame / fps."),
        "tolerances": tolerances(),
        "impacts": [],
        "rest": {},
    }
    dominoes = sorted(n for n in tracks if n.startswith("Domino"))
    for name, track in tracks.items():
        if not dominoes:
            result["impacts"] += flight_impacts(name, objects[name], track, statics, fps,
                                                gravity, start)
        result["rest"][name] = rest_intervals(track, fps, start)
    if dominoes:
        result["method"] += (" Dominoes: none flies; each impact is the leading corner of "
                             "the top front edge of one reaching the back face of the next "
                             "as it stood; frames_bracket are the frames before and after, "
                             "and each entry's method says how the instant was found.")
        starts = {n: start_of_motion(tracks[n]) for n in dominoes}
        result["starts_moving"] = [
            {"object": n, "frame": start + starts[n], "time": (start + starts[n]) / fps}
            for n in sorted(dominoes, key=lambda n: starts[n])]
        for a, b in zip(dominoes, dominoes[1:]):
            touch = domino_touch(a, b, objects[a], tracks[a], tracks[b], starts[a], fps, start)
            if touch is not None:
                result["impacts"].append(touch)
    for name, body in objects.items():
        if body.get("shape") == "cylinder" and not body["static"]:
            first_dynamic = body.get("launch", {}).get("dynamic_from_frame", start)
            result["contacts"] = rolling_contacts(name, body, tracks[name], statics["Floor"],
                                                  fps, start, first_dynamic)
            result["contacts_method"] = (
                "frames at which the body's lowest point is within contact_gap of the "
                "floor; slip = horizontal speed of that point (v + omega x r, central "
                "differences), rolling speed = horizontal speed of the centre; rest when "
                "v < rest_speed and omega < rest_angular, roll when slip < slip_abs + "
                "slip_rel * rolling speed, else slide.")
    result["impacts"].sort(key=lambda e: e["time"])
    return result


# --- output ----------------------------------------------------------------------

def rounded(value, digits=7):
    """Floats to `digits` significant digits, recursively."""
    if isinstance(value, float):
        return float(f"{value:.{digits}g}") + 0.0
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(v, digits) for v in value]
    return value


def dumps(value, indent=2):
    """JSON with dicts and lists of dicts indented, lists of numbers on one line."""
    pad = " " * indent
    if isinstance(value, dict) and value:
        items = [f"{pad}  {json.dumps(k)}: {dumps(v, indent + 2)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{pad}}}"
    if isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        items = [f"{pad}  {dumps(v, indent + 2)}" for v in value]
        return "[\n" + ",\n".join(items) + f"\n{pad}]"
    return json.dumps(value)


def write_json(shot, path):
    """The shot as JSON: one frame per line, everything else indented."""
    shot = rounded(shot)
    frames = shot.pop("frames")
    lines = []
    for key, value in shot.items():
        lines.append(f"  {json.dumps(key)}: {dumps(value, 2)}")
    tracks = [f"    {json.dumps(name)}: [\n"
              + ",\n".join(f"      {json.dumps(f)}" for f in samples) + "\n    ]"
              for name, samples in frames.items()]
    lines.append('  "frames": {\n' + ",\n".join(tracks) + "\n  }")
    with open(path, "w", encoding="utf-8") as out:
        out.write("{\n" + ",\n".join(lines) + "\n}\n")


def summary(shot):
    ref = shot["contacts_reference"]
    lines = [f"{shot['shot']}: {len(ref['impacts'])} impacts",
             "  time s   frame    a           b           vn before  vt before  vn after"
             "  point (x, y, z) m"]
    for e in ref["impacts"]:
        after = "-" if e.get("normal_speed_after") is None else f"{e['normal_speed_after']:.3f}"
        point = ", ".join(f"{c:6.3f}" for c in e["point"])
        lines.append(f"  {e['time']:.4f}  {e['frame']:7.3f}  {e['a']:<10}  {e['b']:<10}  "
                     f"{e['normal_speed_before']:9.3f}  {e['tangential_speed_before']:9.3f}  "
                     f"{after:>8}  ({point})")
    for name, intervals in ref["rest"].items():
        spans = ", ".join(f"{r['frames'][0]}-{r['frames'][1]}" for r in intervals) or "never"
        lines.append(f"  {name} rests at frames {spans}")
    if "starts_moving" in ref:
        lines.append("  starts moving: " + ", ".join(
            f"{s['object']}@{s['frame']}" for s in ref["starts_moving"]))
    for c in ref.get("contacts", []):
        lines.append(f"  {c['kind']:<5} frames {c['frames'][0]}-{c['frames'][1]}  slip "
                     f"{c['slip_speed'][0]:.3f}-{c['slip_speed'][1]:.3f} m/s  rolling "
                     f"{c['rolling_speed'][0]:.3f}-{c['rolling_speed'][1]:.3f} m/s")
    return "\n".join(lines)
