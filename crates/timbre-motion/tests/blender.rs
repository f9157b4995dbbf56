//! The import against Blender itself: `examples/shots/make-car-pass.py` builds a shot
//! with Blender's Python module and writes, beside the glTF file its exporter made,
//! Blender's own `matrix_world` of every object at every frame and at sub-frames.
//! `.ci/run` makes the shot afresh and points `TIMBRE_BLENDER_SHOT` at it; without
//! that variable the committed copies are read.

use glam::{DQuat, DVec3};
use serde_json::Value;
use timbre_motion::{Shot, ShotOptions};
use timbre_testkit::blender_shot;

struct Reference {
    fps: f64,
    objects: Value,
}

fn load() -> (Shot, Reference) {
    let (glb, json) = blender_shot();
    let bytes = std::fs::read(&glb).unwrap_or_else(|e| panic!("{}: {e}", glb.display()));
    let shot = Shot::read(
        &bytes,
        &mut |uri| Err(format!("no external buffers expected ({uri})")),
        &ShotOptions::default(),
    )
    .unwrap();
    let text = std::fs::read_to_string(&json).unwrap();
    let value: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(value["gltf_time_of_frame"], "t = frame / fps");
    let reference = Reference {
        fps: value["fps"].as_f64().unwrap(),
        objects: value["objects"].clone(),
    };
    (shot, reference)
}

fn vec3(v: &Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

/// Blender's samples of one object: (frame, position, rotation, view direction).
fn samples(reference: &Reference, object: &str) -> Vec<(f64, DVec3, DQuat, Option<DVec3>)> {
    reference.objects[object]["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            let q = &s["rotation_wxyz"];
            let rotation = DQuat::from_xyzw(
                q[1].as_f64().unwrap(),
                q[2].as_f64().unwrap(),
                q[3].as_f64().unwrap(),
                q[0].as_f64().unwrap(),
            );
            let view = (!s["view_direction"].is_null()).then(|| vec3(&s["view_direction"]));
            (
                s["frame"].as_f64().unwrap(),
                vec3(&s["position"]),
                rotation,
                view,
            )
        })
        .collect()
}

const OBJECTS: [&str; 4] = ["Car", "Ball", "Door", "Camera"];

#[test]
fn every_frame_is_where_blender_puts_it() {
    let (shot, reference) = load();
    for object in OBJECTS {
        let node = shot.node(object).unwrap();
        let position = shot.position(node);
        let mut frames = 0;
        for (frame, blender, _, _) in samples(&reference, object) {
            if frame.fract() != 0.0 {
                continue;
            }
            let ours = position.position(frame / reference.fps);
            let error = (ours - blender).length();
            assert!(
                error <= 1e-4,
                "{object} at frame {frame}: {ours} against Blender's {blender} ({error:e} m)"
            );
            frames += 1;
        }
        assert_eq!(frames, 120, "{object}");
    }
}

#[test]
fn the_camera_looks_where_blender_says() {
    let (shot, reference) = load();
    let forward = shot.forward(shot.node("Camera").unwrap());
    let up = shot.up(shot.node("Camera").unwrap());
    for (frame, _, rotation, view) in samples(&reference, "Camera") {
        if frame.fract() != 0.0 {
            continue;
        }
        let t = frame / reference.fps;
        let view = view.unwrap();
        let ours = forward.position(t);
        assert!(
            (ours - view).length() <= 1e-4,
            "frame {frame}: {ours} against {view}"
        );
        // Blender's camera looks down its local −Z with +Y up.
        let blender_up = rotation * DVec3::Y;
        assert!(
            (up.position(t) - blender_up).length() <= 1e-4,
            "frame {frame}"
        );
    }
}

/// The file's keys are Blender's frames, sampled LINEAR (the exporter leaves out keys
/// a straight line makes redundant): between two keys a position follows the
/// straight line between Blender's positions at their frames, and a rotation the
/// spherical linear interpolation of Blender's rotations there (computed here from
/// Blender's numbers, as the glTF specification defines them).
#[test]
fn between_frames_the_motion_follows_the_gltf_samplers() {
    let (shot, reference) = load();
    for object in OBJECTS {
        let node = shot.node(object).unwrap();
        let (position, forward) = (shot.position(node), shot.forward(node));
        let all = samples(&reference, object);
        let at = |frame: f64| all.iter().find(|s| s.0 == frame).unwrap();
        let key_frames: Vec<f64> = shot
            .key_times(node)
            .iter()
            .map(|t| (t * reference.fps).round())
            .collect();
        for s in all.iter().filter(|s| s.0.fract() != 0.0) {
            let Some(k) = key_frames.iter().position(|&f| f > s.0).filter(|&k| k > 0) else {
                continue;
            };
            let (frame, next) = (key_frames[k - 1], key_frames[k]);
            let fraction = (s.0 - frame) / (next - frame);
            let (a, b) = (at(frame), at(next));
            let t = s.0 / reference.fps;
            let line = a.1.lerp(b.1, fraction);
            let error = (position.position(t) - line).length();
            assert!(
                error <= 1e-4,
                "{object} at frame {}: {error:e} m off the line",
                s.0
            );
            // The spec's slerp (the shortest arc), as glam computes it.
            let q = a.2.normalize().slerp(b.2.normalize(), fraction);
            // Forward is the object's local +Y in Blender's axes (a camera's −Z).
            let local = if object == "Camera" {
                DVec3::NEG_Z
            } else {
                DVec3::Y
            };
            let expected = q * local;
            let ours = forward.position(t);
            assert!(
                (ours - expected).length() <= 1e-4,
                "{object} at frame {}: forward {ours} against {expected}",
                s.0
            );
        }
    }
}

/// Velocity is the exact derivative of the LINEAR sampler: constant between two
/// frames, the secant of Blender's positions at them.
#[test]
fn velocity_between_frames_is_the_secant_of_blenders_positions() {
    let (shot, reference) = load();
    for object in ["Car", "Ball"] {
        let position = shot.position(shot.node(object).unwrap());
        let all = samples(&reference, object);
        let at = |frame: f64| all.iter().find(|s| s.0 == frame).unwrap().1;
        for frame in 1..120 {
            let frame = frame as f64;
            let secant = (at(frame + 1.0) - at(frame)) * reference.fps;
            // Not at a frame itself: there the key time, stored in single precision,
            // may fall a hair either side of frame / fps, where the slope jumps.
            for fraction in [0.1, 0.25, 0.5, 0.9] {
                let k = position.kinematics((frame + fraction) / reference.fps);
                let error = (k.velocity - secant).length();
                assert!(
                    error <= 1e-4 * reference.fps * 2.0,
                    "{object} at frame {frame}+{fraction}: {} against {secant}",
                    k.velocity
                );
                assert!(
                    k.acceleration.length() < 1e-9,
                    "{object}: linear keys do not accelerate"
                );
            }
        }
    }
}

#[test]
fn the_wall_s_mesh_bounds_are_blender_s() {
    let (shot, reference) = load();
    let wall = &reference.objects["Wall"]["mesh_bounds_world"];
    let (lo, hi) = shot.mesh_bounds(shot.node("Wall").unwrap(), 0.0).unwrap();
    assert!((lo - vec3(&wall["min"])).length() < 1e-5, "{lo}");
    assert!((hi - vec3(&wall["max"])).length() < 1e-5, "{hi}");
}
