//! glTF files written by the tests, read back and checked against the glTF 2.0
//! specification's formulas computed here, independently of the crate.

mod builder;

use std::f64::consts::PI;

use builder::{pack_glb, Builder, Channel};
use glam::{DQuat, DVec3};
use serde_json::json;
use timbre_ir::motion::Trajectory;
use timbre_ir::op::Description;
use timbre_motion::{MotionError, Shot, ShotOptions};

fn no_files(uri: &str) -> Result<Vec<u8>, String> {
    Err(format!("no file {uri}"))
}

fn read(glb: &[u8]) -> Shot {
    match Shot::read(glb, &mut no_files, &ShotOptions::default()) {
        Ok(shot) => shot,
        Err(e) => panic!("{e}"),
    }
}

fn read_err(glb: &[u8], options: &ShotOptions) -> MotionError {
    match Shot::read(glb, &mut no_files, options) {
        Ok(_) => panic!("read a bad file"),
        Err(e) => e,
    }
}

fn close(a: DVec3, b: DVec3, tolerance: f64) -> bool {
    (a - b).length() <= tolerance * (1.0 + b.length())
}

/// glTF (x, y, z) in timbre axes.
fn z_up(v: DVec3) -> DVec3 {
    DVec3::new(v.x, -v.z, v.y)
}

fn f(x: f32) -> f64 {
    x as f64
}

/// A root node "Box" whose translation is keyed with `interpolation`.
fn translated(interpolation: &str, times: &[f32], values: &[f32]) -> Shot {
    let mut b = Builder::default();
    let node = b.node(json!({"name": "Box"}));
    b.animation(
        "move",
        &[Channel {
            node,
            path: "translation",
            interpolation,
            times,
            values,
        }],
    );
    read(&b.glb())
}

const TIMES: [f32; 3] = [0.5, 1.5, 3.5];
const POINTS: [f32; 9] = [0.0, 1.0, 2.0, 4.0, -1.0, 2.5, 3.0, 3.0, -6.0];

fn key(k: usize) -> DVec3 {
    DVec3::new(f(POINTS[3 * k]), f(POINTS[3 * k + 1]), f(POINTS[3 * k + 2]))
}

#[test]
fn step_holds_each_key_until_the_next() {
    let shot = translated("STEP", &TIMES, &POINTS);
    let p = shot.position(shot.node("Box").unwrap());
    for (t, k) in [
        (0.0, 0),
        (0.5, 0),
        (1.4999, 0),
        (1.5, 1),
        (3.0, 1),
        (3.5, 2),
        (9.0, 2),
    ] {
        let kin = p.kinematics(t);
        assert_eq!(kin.position, z_up(key(k)), "t = {t}");
        assert_eq!(kin.velocity, DVec3::ZERO);
    }
}

#[test]
fn linear_is_component_wise_and_holds_the_ends() {
    let shot = translated("LINEAR", &TIMES, &POINTS);
    let p = shot.position(shot.node("Box").unwrap());
    assert_eq!(p.position(0.0), z_up(key(0)));
    assert_eq!(p.position(10.0), z_up(key(2)));
    for (k, &t) in TIMES.iter().enumerate() {
        assert!(close(p.position(f(t)), z_up(key(k)), 1e-15));
    }
    for t in [0.7, 1.5, 2.0, 3.2] {
        let k = if t < 1.5 { 0 } else { 1 };
        let (t0, t1) = (f(TIMES[k]), f(TIMES[k + 1]));
        let s = (t - t0) / (t1 - t0);
        let expected = key(k) * (1.0 - s) + key(k + 1) * s;
        let kin = p.kinematics(t);
        assert!(close(kin.position, z_up(expected), 1e-14), "t = {t}");
        // Right-continuous: at 1.5 the slope of the interval that starts there.
        let slope = (key(k + 1) - key(k)) / (t1 - t0);
        assert!(close(kin.velocity, z_up(slope), 1e-14), "t = {t}");
        assert_eq!(kin.acceleration, DVec3::ZERO);
    }
    assert_eq!(p.kinematics(3.5).velocity, DVec3::ZERO);
    assert_eq!(shot.duration(), 3.5);
    assert_eq!(
        shot.key_times(shot.node("Box").unwrap()),
        vec![0.5, 1.5, 3.5]
    );
}

/// Cubic-spline outputs: in-tangent, value, out-tangent per key.
fn cubic_outputs() -> Vec<f32> {
    let tangents_in = [[1.0, 0.0, -2.0], [0.5, 3.0, 1.0], [-1.0, 2.0, 0.0]];
    let tangents_out = [[2.0, -1.0, 0.0], [-3.0, 1.5, 2.0], [0.0, 0.0, 4.0]];
    let mut out = Vec::new();
    for k in 0..3 {
        out.extend_from_slice(&tangents_in[k]);
        out.extend_from_slice(&POINTS[3 * k..3 * k + 3]);
        out.extend_from_slice(&tangents_out[k]);
    }
    out
}

/// The cubic between keys k and k+1 as a polynomial in s = (t − t_k)/h, written from
/// the spec's Hermite form: p = a s³ + b s² + c s + d, with its t-derivatives.
fn cubic_expected(out: &[f32], k: usize, t: f64) -> [DVec3; 3] {
    let v = |i: usize| DVec3::new(f(out[i]), f(out[i + 1]), f(out[i + 2]));
    let (v0, b0) = (v(9 * k + 3), v(9 * k + 6));
    let (a1, v1) = (v(9 * (k + 1)), v(9 * (k + 1) + 3));
    let (t0, t1) = (f(TIMES[k]), f(TIMES[k + 1]));
    let h = t1 - t0;
    let s = (t - t0) / h;
    let d = v0;
    let c = b0 * h;
    let b = (v1 - v0) * 3.0 - b0 * (2.0 * h) - a1 * h;
    let a = (v0 - v1) * 2.0 + b0 * h + a1 * h;
    [
        a * s.powi(3) + b * s * s + c * s + d,
        (a * (3.0 * s * s) + b * (2.0 * s) + c) / h,
        (a * (6.0 * s) + b * 2.0) / (h * h),
    ]
}

#[test]
fn cubic_spline_is_the_hermite_cubic_with_exact_derivatives() {
    let out = cubic_outputs();
    let shot = translated("CUBICSPLINE", &TIMES, &out);
    let p = shot.position(shot.node("Box").unwrap());
    for (k, &t) in TIMES.iter().enumerate() {
        assert!(close(p.position(f(t)), z_up(key(k)), 1e-15));
    }
    for t in [0.5, 0.9, 1.2, 1.5, 2.2, 3.4] {
        let k = if t < 1.5 { 0 } else { 1 };
        let [x, v, a] = cubic_expected(&out, k, t);
        let kin = p.kinematics(t);
        assert!(close(kin.position, z_up(x), 1e-12), "t = {t}");
        assert!(
            close(kin.velocity, z_up(v), 1e-9),
            "t = {t}: {} {}",
            kin.velocity,
            z_up(v)
        );
        assert!(close(kin.acceleration, z_up(a), 1e-9), "t = {t}");
    }
    // Before the first key and after the last: the values, standing still.
    assert_eq!(p.kinematics(0.0).position, z_up(key(0)));
    assert_eq!(p.kinematics(4.0).velocity, DVec3::ZERO);
}

fn hinge(angles: &[f32], times: &[f32]) -> Shot {
    let mut b = Builder::default();
    let door = b.node(json!({"name": "Door", "translation": [1.0, 2.0, 3.0]}));
    // Rotations about glTF +Y (timbre +Z).
    let values: Vec<f32> = angles
        .iter()
        .flat_map(|&a| {
            let q = DQuat::from_rotation_y(a as f64);
            [q.x as f32, q.y as f32, q.z as f32, q.w as f32]
        })
        .collect();
    b.animation(
        "swing",
        &[Channel {
            node: door,
            path: "rotation",
            interpolation: "LINEAR",
            times,
            values: &values,
        }],
    );
    read(&b.glb())
}

#[test]
fn a_hinge_turns_at_its_angle_over_its_interval() {
    let angles = [0.0f32, 1.2, 0.4];
    let times = [0.0f32, 2.0, 3.0];
    let shot = hinge(&angles, &times);
    let door = shot.node("Door").unwrap();
    let (omega, forward, up) = (
        shot.angular_velocity(door),
        shot.forward(door),
        shot.up(door),
    );
    for t in [0.0, 0.3, 1.0, 1.99, 2.0, 2.5] {
        let k = if t < 2.0 { 0 } else { 1 };
        let (t0, t1) = (f(times[k]), f(times[k + 1]));
        // The quaternions stored are f32: the angle between them, from them.
        let q = |i: usize| {
            let q = DQuat::from_rotation_y(angles[i] as f64);
            let stored = [q.x, q.y, q.z, q.w].map(|c| c as f32 as f64);
            DQuat::from_array(stored).normalize()
        };
        let (a0, a1) = (f(angles[k]), f(angles[k + 1]));
        let rate = (a1 - a0) / (t1 - t0);
        let phi = a0 + rate * (t - t0);
        let w = omega.kinematics(t);
        assert!(
            close(w.position, DVec3::new(0.0, 0.0, rate), 1e-6),
            "t = {t}: {}",
            w.position
        );
        assert!(w.velocity.length() < 1e-9, "t = {t}");
        // The slerp of the file's own (f32) keys, checked to 1e-9.
        let slerp = q(k).slerp(q(k + 1), (t - t0) / (t1 - t0));
        let fwd = z_up(slerp * DVec3::NEG_Z);
        let f_kin = forward.kinematics(t);
        assert!(close(f_kin.position, fwd, 1e-6));
        // Analytic: forward = (−sin φ, cos φ, 0) in timbre axes.
        assert!(close(
            f_kin.position,
            DVec3::new(-phi.sin(), phi.cos(), 0.0),
            1e-6
        ));
        let turn = DVec3::new(-phi.cos(), -phi.sin(), 0.0) * rate;
        assert!(close(f_kin.velocity, turn, 1e-6), "t = {t}");
        assert!(close(
            f_kin.acceleration,
            -DVec3::new(-phi.sin(), phi.cos(), 0.0) * rate * rate,
            1e-6
        ));
        assert!(close(up.position(t), DVec3::Z, 1e-12));
        // The angular speed equals the angle between the stored keys over the interval.
        let angle = q(k).angle_between(q(k + 1));
        assert!(
            (w.position.length() - angle / (t1 - t0)).abs() < 1e-9 * angle / (t1 - t0),
            "{} {}",
            w.position.length(),
            angle / (t1 - t0)
        );
    }
    // The hinge turns in place.
    assert!(close(
        shot.position(door).position(1.0),
        DVec3::new(1.0, -3.0, 2.0),
        1e-15
    ));
}

#[test]
fn slerp_takes_the_shortest_path() {
    // Keys 300° apart about Y; q and −q are the same rotation, so the path is −60°.
    let shot = hinge(&[0.0, 300f32.to_radians()], &[0.0, 1.0]);
    let door = shot.node("Door").unwrap();
    let w = shot.angular_velocity(door).kinematics(0.5).position;
    assert!(close(w, DVec3::new(0.0, 0.0, -PI / 3.0), 1e-6), "{w}");
}

#[test]
fn a_child_composes_with_its_rotating_translated_scaled_parent() {
    let mut b = Builder::default();
    let child =
        b.node(json!({"name": "Child", "translation": [1.0, 0.5, 0.0], "scale": [3.0, 3.0, 3.0]}));
    let parent = b.node(json!({
        "name": "Parent", "children": [child],
        "translation": [1.0, 2.0, 3.0], "scale": [2.0, 2.0, 2.0]
    }));
    // The parent turns about glTF Z from 0 to 90° in 1 s.
    let q = DQuat::from_rotation_z(PI / 2.0);
    b.animation(
        "turn",
        &[Channel {
            node: parent,
            path: "rotation",
            interpolation: "LINEAR",
            times: &[0.0, 1.0],
            values: &[
                0.0, 0.0, 0.0, 1.0, q.x as f32, q.y as f32, q.z as f32, q.w as f32,
            ],
        }],
    );
    let shot = read(&b.glb());
    let c = shot.node("Child").unwrap();
    let rate = 2.0 * ((q.z as f32) as f64).atan2((q.w as f32) as f64); // the f32 keys' angle
    for t in [0.0f64, 0.25, 0.6, 1.0, 2.0] {
        let phi = rate * t.min(1.0);
        let speed = if t < 1.0 { rate } else { 0.0 };
        // p = T_p + R_z(φ)·(S_p ⊙ T_c), T_c = (1, 0.5, 0), S_p = 2.
        let (x, y) = (2.0, 1.0);
        let world = DVec3::new(
            1.0 + x * phi.cos() - y * phi.sin(),
            2.0 + x * phi.sin() + y * phi.cos(),
            3.0,
        );
        let velocity = DVec3::new(
            -x * phi.sin() - y * phi.cos(),
            x * phi.cos() - y * phi.sin(),
            0.0,
        ) * speed;
        let kin = shot.position(c).kinematics(t);
        assert!(
            close(kin.position, z_up(world), 1e-12),
            "t = {t}: {} {}",
            kin.position,
            z_up(world)
        );
        assert!(close(kin.velocity, z_up(velocity), 1e-9), "t = {t}");
        assert!(close(
            kin.acceleration,
            z_up(-(world - DVec3::new(1.0, 2.0, 3.0)) * speed * speed),
            1e-9
        ));
        assert!(close(shot.scale(c).position(t), DVec3::splat(6.0), 1e-12));
    }
    assert_eq!(shot.key_times(c), vec![0.0, 1.0]);
}

#[test]
fn y_up_becomes_z_up() {
    let mut b = Builder::default();
    b.node(json!({"name": "Lamp", "translation": [1.0, 2.0, 3.0]}));
    // A camera looking along glTF −X (turned 90° about +Y): timbre −X too.
    b.cameras
        .push(json!({"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}));
    let q = DQuat::from_rotation_y(PI / 2.0);
    b.node(json!({"name": "Camera", "camera": 0, "rotation": [q.x, q.y, q.z, q.w]}));
    let shot = read(&b.glb());
    let lamp = shot.node("Lamp").unwrap();
    assert_eq!(
        shot.position(lamp).position(0.0),
        DVec3::new(1.0, -3.0, 2.0)
    );
    let camera = shot.node("Camera").unwrap();
    assert!(shot.is_camera(camera) && !shot.is_camera(lamp));
    assert!(close(
        shot.forward(camera).position(0.0),
        DVec3::new(-1.0, 0.0, 0.0),
        1e-7
    ));
    assert!(close(shot.up(camera).position(0.0), DVec3::Z, 1e-7));
    assert_eq!(shot.node_names().collect::<Vec<_>>(), ["Lamp", "Camera"]);
    assert!(shot.node("lamp").is_none());
}

#[test]
fn normalised_short_rotations_are_decoded_as_the_spec_says() {
    let mut b = Builder::default();
    let node = b.node(json!({"name": "N"}));
    let times = b.floats(&[0.0, 1.0], "SCALAR");
    // i16 quaternions: identity, then 90° about Y as (0, 23170, 0, 23170).
    let raw: Vec<u8> = [0i16, 0, 0, 32767, 0, 23170, 0, 23170]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let output = b.accessor(&raw, 5122, "VEC4", 2, json!({"normalized": true}));
    b.animations.push(json!({
        "samplers": [{"input": times, "output": output}],
        "channels": [{"sampler": 0, "target": {"node": node, "path": "rotation"}}]
    }));
    let shot = read(&b.glb());
    assert_eq!(shot.animation_names(), ["animation 0"]);
    let forward = shot.forward(shot.node("N").unwrap()).position(1.0);
    // max(23170/32767, −1) for both components: exactly 45° each way → 90°.
    assert!(
        close(forward, DVec3::new(-1.0, 0.0, 0.0), 1e-12),
        "{forward}"
    );
}

#[test]
fn cubic_spline_rotations_are_normalised_with_exact_derivatives() {
    let mut b = Builder::default();
    let node = b.node(json!({"name": "Spin", "children": [1]}));
    b.node(json!({"name": "Arm", "translation": [0.0, 0.0, -2.0]}));
    let q1 = DQuat::from_rotation_y(1.0);
    let q1 = [q1.x as f32, q1.y as f32, q1.z as f32, q1.w as f32];
    // Per key: in-tangent, value, out-tangent.
    let outputs: [[f32; 4]; 6] = [
        [0.0, 0.3, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [0.0, 0.4, 0.1, 0.0],
        [0.0, 0.2, 0.0, -0.1],
        q1,
        [0.0, 0.0, 0.0, 0.0],
    ];
    let values = outputs.concat();
    b.animation(
        "spin",
        &[Channel {
            node,
            path: "rotation",
            interpolation: "CUBICSPLINE",
            times: &[0.0, 1.5],
            values: &values,
        }],
    );
    let shot = read(&b.glb());
    let arm = shot.position(shot.node("Arm").unwrap());
    let forward = shot.forward(shot.node("Spin").unwrap());
    for t in [0.2, 0.75, 1.3] {
        let h = 1e-5;
        for path in [&arm, &forward] {
            let k = path.kinematics(t);
            let v = (path.position(t + h) - path.position(t - h)) / (2.0 * h);
            let a =
                (path.position(t + h) - 2.0 * path.position(t) + path.position(t - h)) / (h * h);
            assert!((k.velocity - v).length() < 1e-8, "{t}: {} {v}", k.velocity);
            assert!(
                (k.acceleration - a).length() < 1e-4,
                "{t}: {} {a}",
                k.acceleration
            );
        }
        assert!((forward.position(t).length() - 1.0).abs() < 1e-15);
        // The spec: the Hermite cubic of the quaternions, then normalised.
        let v = |k: usize| glam::DVec4::from(outputs[k].map(f64::from));
        let (h, s) = (1.5f64, t / 1.5);
        let p = v(1) * (2.0 * s.powi(3) - 3.0 * s * s + 1.0)
            + v(2) * (h * (s.powi(3) - 2.0 * s * s + s))
            + v(4).normalize() * (-2.0 * s.powi(3) + 3.0 * s * s)
            + v(3) * (h * (s.powi(3) - s * s));
        let q = DQuat::from_vec4(p.normalize());
        assert!(
            close(forward.position(t), z_up(q * DVec3::NEG_Z), 1e-12),
            "{t}"
        );
        assert!(close(
            arm.position(t),
            z_up(q * DVec3::new(0.0, 0.0, -2.0)),
            1e-12
        ));
    }
}

/// A file with a bit of everything moving, for the bounds.
fn busy() -> Builder {
    let mut b = Builder::default();
    let leaf =
        b.node(json!({"name": "Leaf", "translation": [0.5, -1.0, 2.0], "scale": [1.0, 2.0, 0.5]}));
    let mid = b.node(
        json!({"name": "Mid", "children": [leaf], "rotation": [0.0, 0.0, 0.38268343, 0.9238795]}),
    );
    let root = b.node(json!({"name": "Root", "children": [mid]}));
    let out = cubic_outputs();
    let q = |a: f64| {
        let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), a);
        [q.x as f32, q.y as f32, q.z as f32, q.w as f32]
    };
    let rotations: Vec<f32> = [0.0, 2.0, -1.0].into_iter().flat_map(q).collect();
    b.animation(
        "busy",
        &[
            Channel {
                node: root,
                path: "translation",
                interpolation: "CUBICSPLINE",
                times: &TIMES,
                values: &out,
            },
            Channel {
                node: mid,
                path: "rotation",
                interpolation: "LINEAR",
                times: &TIMES,
                values: &rotations,
            },
            Channel {
                node: mid,
                path: "scale",
                interpolation: "LINEAR",
                times: &[0.0, 2.0],
                values: &[1.0, 1.0, 1.0, 0.5, 2.0, 1.5],
            },
            Channel {
                node: leaf,
                path: "translation",
                interpolation: "STEP",
                times: &[1.0, 2.0],
                values: &[0.5, -1.0, 2.0, 1.0, 1.0, 1.0],
            },
        ],
    );
    b
}

#[test]
fn bounds_hold_every_position_and_max_speed_every_speed() {
    let shot = read(&busy().glb());
    for name in ["Root", "Mid", "Leaf"] {
        let node = shot.node(name).unwrap();
        for path in [
            shot.position(node),
            shot.forward(node),
            shot.up(node),
            shot.angular_velocity(node),
        ] {
            let (lo, hi) = path.bounds();
            let top = path.max_speed();
            assert!(
                top.is_finite() || path.detail().starts_with("angular"),
                "{}",
                path.detail()
            );
            let mut fastest: f64 = 0.0;
            for i in 0..=4000 {
                let t = -0.5 + i as f64 * 0.001;
                let k = path.kinematics(t);
                assert!(
                    k.position.cmpge(lo).all() && k.position.cmple(hi).all(),
                    "{} at {t}",
                    path.detail()
                );
                assert!(
                    k.velocity.length() <= top,
                    "{} at {t}: {} > {top}",
                    path.detail(),
                    k.velocity.length()
                );
                fastest = fastest.max(k.velocity.length());
            }
            // A bound, but not a useless one.
            assert!(
                top < 50.0 * fastest.max(0.1) || !top.is_finite(),
                "{} {top} {fastest}",
                path.detail()
            );
        }
    }
}

#[test]
fn descriptions_tell_files_nodes_and_quantities_apart() {
    let describe = |path: &dyn Trajectory| {
        let mut d = Description::new();
        path.describe(&mut d);
        d
    };
    let glb = busy().glb();
    let (a, b) = (read(&glb), read(&glb));
    let node = a.node("Leaf").unwrap();
    assert_eq!(describe(&*a.position(node)), describe(&*b.position(node)));
    assert_ne!(describe(&*a.position(node)), describe(&*a.forward(node)));
    assert_ne!(
        describe(&*a.position(node)),
        describe(&*a.position(a.node("Mid").unwrap()))
    );
    let mut other = busy();
    other.bin[0] ^= 1;
    let c = read(&other.glb());
    assert_ne!(a.content_hash(), c.content_hash());
    assert_ne!(describe(&*a.position(node)), describe(&*c.position(node)));
    assert_eq!(a.content_hash(), b.content_hash());
}

#[test]
fn one_animation_by_name() {
    let mut b = busy();
    let extra = b.node(json!({"name": "Other"}));
    b.animation(
        "other",
        &[Channel {
            node: extra,
            path: "translation",
            interpolation: "LINEAR",
            times: &[0.0, 9.0],
            values: &[0.0; 6],
        }],
    );
    let glb = b.glb();
    let all = read(&glb);
    assert_eq!(all.animation_names(), ["busy", "other"]);
    assert_eq!(all.duration(), 9.0);
    let options = ShotOptions {
        animation: Some("busy".into()),
    };
    let one = Shot::read(&glb, &mut no_files, &options).unwrap();
    assert_eq!(one.animation_names(), ["busy"]);
    assert_eq!(one.duration(), 3.5);
    let err = read_err(
        &glb,
        &ShotOptions {
            animation: Some("walk".into()),
        },
    );
    assert_eq!(err.to_string(), "the file has no animation \"walk\"");
    assert_eq!(err.help(), "the file's animations are: \"busy\", \"other\"");
}

#[test]
fn meshes_merge_primitives_and_strips_become_triangles() {
    let mut b = Builder::default();
    // A unit square in glTF's XY plane as a strip of 4 vertices.
    let mesh = b.mesh(
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0],
        None,
        5,
    );
    let node = b.node(json!({"name": "Wall", "mesh": mesh, "scale": [2.0, 2.0, 2.0]}));
    b.animation(
        "slide",
        &[Channel {
            node,
            path: "translation",
            interpolation: "LINEAR",
            times: &[0.0, 1.0],
            values: &[0.0, 0.0, 0.0, 10.0, 0.0, 0.0],
        }],
    );
    let shot = read(&b.glb());
    let wall = shot.node("Wall").unwrap();
    let m = shot.mesh(wall).unwrap();
    // Strip triangle i is {i, i+1+i%2, i+2−i%2} (glTF 2.0 §3.7.2.1).
    assert_eq!(m.triangles, [[0, 1, 2], [1, 3, 2]]);
    assert_eq!(m.vertices[3], DVec3::new(1.0, 0.0, 1.0));
    let (lo, hi) = shot.mesh_bounds(wall, 0.5).unwrap();
    assert_eq!(
        (lo, hi),
        (DVec3::new(5.0, 0.0, 0.0), DVec3::new(7.0, 0.0, 2.0))
    );
    assert!(shot.mesh(shot.node("Wall").unwrap()).is_some());
}

#[test]
fn a_gltf_with_an_external_and_an_inline_buffer() {
    let b = busy();
    let json = b.json(Some("shot.bin")).to_string();
    let mut asked = Vec::new();
    let mut reader = |uri: &str| {
        asked.push(uri.to_string());
        if uri == "shot.bin" {
            Ok(b.bin.clone())
        } else {
            Err("no such file".to_string())
        }
    };
    let external = Shot::read(json.as_bytes(), &mut reader, &ShotOptions::default()).unwrap();
    assert_eq!(asked, ["shot.bin"]);
    let glb = read(&b.glb());
    let node = glb.node("Leaf").unwrap();
    for t in [0.0, 1.1, 2.7] {
        assert_eq!(
            external.position(node).position(t),
            glb.position(node).position(t)
        );
    }
    use base64::Engine as _;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&b.bin)
    );
    let inline = b.json(Some(&uri)).to_string();
    let shot = Shot::read(inline.as_bytes(), &mut no_files, &ShotOptions::default()).unwrap();
    assert_eq!(
        shot.position(node).position(2.7),
        glb.position(node).position(2.7)
    );
}

// Errors: each names what is wrong, with a help line.

fn one_channel(interpolation: &str, times: &[f32], values: &[f32]) -> Vec<u8> {
    let mut b = Builder::default();
    let node = b.node(json!({"name": "N"}));
    b.animation(
        "a",
        &[Channel {
            node,
            path: "translation",
            interpolation,
            times,
            values,
        }],
    );
    b.glb()
}

#[test]
fn not_gltf_truncated_or_invalid_json() {
    let default = ShotOptions::default();
    let err = read_err(b"RIFF0000WAVEfmt ", &default);
    assert!(matches!(err, MotionError::Parse { .. }), "{err}");
    let glb = busy().glb();
    let err = read_err(&glb[..glb.len() - 40], &default);
    assert!(matches!(err, MotionError::Parse { .. }), "{err}");
    assert!(
        err.to_string().starts_with("not a readable glTF file: "),
        "{err}"
    );
    let err = read_err(&pack_glb("{\"asset\": ", &[]), &default);
    assert!(matches!(err, MotionError::Parse { .. }), "{err}");
    let diag = err.diag(timbre_ir::Span::new(3, 9));
    assert_eq!(diag.span(), Some(timbre_ir::Span::new(3, 9)));
}

#[test]
fn a_missing_or_short_buffer() {
    let b = busy();
    let json = b.json(Some("shot.bin")).to_string();
    let err = read_err(json.as_bytes(), &ShotOptions::default());
    assert_eq!(
        err,
        MotionError::Resource {
            buffer: 0,
            uri: "shot.bin".into(),
            message: "no file shot.bin".into()
        }
    );
    assert!(err.help().contains("\"shot.bin\""));
    let short = b.bin[..b.bin.len() - 8].to_vec();
    let err = Shot::read(
        json.as_bytes(),
        &mut |_| Ok(short.clone()),
        &ShotOptions::default(),
    )
    .unwrap_err();
    assert_eq!(
        err,
        MotionError::ShortBuffer {
            buffer: 0,
            expected: b.bin.len(),
            actual: b.bin.len() - 8
        }
    );
}

#[test]
fn sampler_counts_must_agree() {
    let err = read_err(
        &one_channel("LINEAR", &[0.0, 1.0, 2.0], &[0.0; 6]),
        &ShotOptions::default(),
    );
    assert_eq!(
        err,
        MotionError::SamplerCounts {
            animation: "a".into(),
            sampler: 0,
            keys: 3,
            outputs: 2,
            expected: 3
        }
    );
    let err = read_err(
        &one_channel("CUBICSPLINE", &[0.0, 1.0], &[0.0; 12]),
        &ShotOptions::default(),
    );
    assert_eq!(
        err,
        MotionError::SamplerCounts {
            animation: "a".into(),
            sampler: 0,
            keys: 2,
            outputs: 4,
            expected: 6
        }
    );
    assert!(err.help().contains("three for CUBICSPLINE"));
}

#[test]
fn times_must_increase() {
    let err = read_err(
        &one_channel("LINEAR", &[0.0, 1.0, 1.0], &[0.0; 9]),
        &ShotOptions::default(),
    );
    assert_eq!(
        err,
        MotionError::TimesNotIncreasing {
            animation: "a".into(),
            sampler: 0,
            index: 2,
            previous: 1.0,
            time: 1.0
        }
    );
}

#[test]
fn values_must_be_finite() {
    let mut values = [0.0f32; 6];
    values[4] = f32::NAN;
    let err = read_err(
        &one_channel("LINEAR", &[0.0, 1.0], &values),
        &ShotOptions::default(),
    );
    assert_eq!(
        err,
        MotionError::NonFinite {
            what: "a translation of animation \"a\"".into()
        }
    );
    let err = read_err(
        &one_channel("LINEAR", &[0.0, f32::INFINITY], &[0.0; 6]),
        &ShotOptions::default(),
    );
    assert!(matches!(err, MotionError::NonFinite { .. }), "{err}");
}

#[test]
fn two_animations_may_not_drive_one_property() {
    let mut b = Builder::default();
    let node = b.node(json!({"name": "Car"}));
    for name in ["drive", "park"] {
        b.animation(
            name,
            &[Channel {
                node,
                path: "translation",
                interpolation: "LINEAR",
                times: &[0.0, 1.0],
                values: &[0.0; 6],
            }],
        );
    }
    let glb = b.glb();
    let err = read_err(&glb, &ShotOptions::default());
    assert_eq!(
        err,
        MotionError::ConflictingChannels {
            node: "Car".into(),
            property: "translation",
            first: "drive".into(),
            second: "park".into()
        }
    );
    assert!(Shot::read(
        &glb,
        &mut no_files,
        &ShotOptions {
            animation: Some("park".into())
        }
    )
    .is_ok());
}

#[test]
fn accessors_outside_their_buffer_and_files_over_the_limits() {
    let mut b = busy();
    b.views[0]["byteLength"] = json!(b.bin.len() + 4);
    let err = read_err(&b.glb(), &ShotOptions::default());
    assert_eq!(
        err.to_string(),
        "accessor 0: reaches past the end of its buffer"
    );
    let mut b = Builder::default();
    for _ in 0..(1 << 16) + 1 {
        b.node(json!({}));
    }
    let err = read_err(&b.glb(), &ShotOptions::default());
    assert_eq!(
        err,
        MotionError::TooLarge {
            what: "nodes",
            count: (1 << 16) + 1,
            limit: 1 << 16
        }
    );
}

#[test]
fn a_matrix_is_applied_as_written_even_when_degenerate() {
    let mut b = Builder::default();
    let child = b.node(json!({"name": "Child", "translation": [1.0, 2.0, 0.0]}));
    // Column-major: x → y, y → −x, then translated by (5, 6, 7).
    let matrix = [
        0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 5.0, 6.0, 7.0, 1.0,
    ];
    b.node(json!({"name": "Parent", "children": [child], "matrix": matrix}));
    // Scaled to nothing (a hidden object): no decomposition, still read.
    let mut flat = [0.0f64; 16];
    flat[15] = 1.0;
    b.node(json!({"name": "Hidden", "matrix": flat}));
    let shot = read(&b.glb());
    let p = shot.position(shot.node("Child").unwrap());
    assert_eq!(p.position(0.0), z_up(DVec3::new(3.0, 7.0, 7.0)));
    assert_eq!(p.max_speed(), 0.0);
    assert_eq!(p.bounds(), (p.position(0.0), p.position(0.0)));
    assert_eq!(
        shot.position(shot.node("Hidden").unwrap()).position(1.0),
        DVec3::ZERO
    );
}

#[test]
fn a_missing_binary_chunk_or_a_bad_data_uri() {
    let b = busy();
    let json = b.json(None).to_string();
    let err = read_err(json.as_bytes(), &ShotOptions::default());
    assert_eq!(err, MotionError::MissingBinaryChunk { buffer: 0 });
    let json = b
        .json(Some("data:application/octet-stream;base64,@@@"))
        .to_string();
    let err = read_err(json.as_bytes(), &ShotOptions::default());
    assert!(
        matches!(err, MotionError::DataUri { buffer: 0, .. }),
        "{err}"
    );
}

#[test]
fn every_truncation_and_every_flipped_byte_is_an_error_or_a_shot_never_a_panic() {
    let glb = busy().glb();
    for end in 0..glb.len() {
        assert!(Shot::read(&glb[..end], &mut no_files, &ShotOptions::default()).is_err());
    }
    for at in 0..glb.len() {
        let mut bad = glb.clone();
        bad[at] ^= 0x5a;
        let _ = Shot::read(&bad, &mut no_files, &ShotOptions::default());
    }
    // Every number of the JSON made large or zero: indices, counts, offsets, types.
    let mut b = busy();
    let mesh = b.mesh(
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        Some(&[0, 1, 2]),
        4,
    );
    b.nodes[0]["mesh"] = json!(mesh);
    let json = b.json(None).to_string();
    for (at, c) in json.char_indices() {
        if c.is_ascii_digit() {
            for digits in ["99", "0", "7"] {
                let bad = format!("{}{digits}{}", &json[..at], &json[at + 1..]);
                let _ = Shot::read(
                    &pack_glb(&bad, &b.bin),
                    &mut no_files,
                    &ShotOptions::default(),
                );
            }
        }
    }
}

#[test]
fn scale_keys_scale_the_node_and_its_children() {
    let mut b = Builder::default();
    let child = b.node(json!({"name": "Tip", "translation": [0.0, 1.0, 0.0]}));
    let node = b.node(json!({"name": "Grow", "children": [child]}));
    b.animation(
        "grow",
        &[Channel {
            node,
            path: "scale",
            interpolation: "LINEAR",
            times: &[0.0, 2.0],
            values: &[1.0, 1.0, 1.0, 3.0, 5.0, 1.0],
        }],
    );
    let shot = read(&b.glb());
    let (grow, tip) = (shot.node("Grow").unwrap(), shot.node("Tip").unwrap());
    // At 0.5 s: scale (1.5, 2, 1) in glTF axes; timbre's order is x, −z, y.
    let scale = shot.scale(grow).kinematics(0.5);
    assert_eq!(scale.position, DVec3::new(1.5, 1.0, 2.0));
    // Linear keys: x grows by 2 and y by 4 over 2 s (glTF axes), z stays.
    assert_eq!(scale.velocity, DVec3::new(1.0, 0.0, 2.0));
    assert_eq!(scale.acceleration, DVec3::ZERO);
    let kin = shot.position(tip).kinematics(0.5);
    assert_eq!(kin.position, z_up(DVec3::new(0.0, 2.0, 0.0)));
    assert_eq!(kin.velocity, z_up(DVec3::new(0.0, 2.0, 0.0)));
}
