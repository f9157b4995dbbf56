//! Contacts found in motion written from closed forms: a ball bouncing with a known
//! restitution, sampled at 24 frames a second as an animator's export would be; a box
//! at rest, a box sliding to a stop under Coulomb friction, a ball rolling. Each is
//! checked against the formula it was written from.

mod builder;

use std::f64::consts::PI;

use builder::{Builder, Channel};
use glam::{DQuat, DVec3};
use serde_json::json;
use timbre_motion::contacts::{
    find_contacts, Body, ContactError, ContactKind, ContactOptions, Contacts, ShapeKind,
};
use timbre_motion::{to_gltf, Shot, ShotOptions};

const G: f64 = 9.80665;
const FPS: f64 = 24.0;

fn gltf(v: DVec3) -> [f32; 3] {
    to_gltf(v).as_vec3().to_array()
}

/// A UV sphere of radius `r` with its poles on the z axis (timbre), outward winding.
fn sphere(r: f64, rings: usize, segments: usize) -> (Vec<f32>, Vec<u16>) {
    let mut points = vec![DVec3::new(0.0, 0.0, r)];
    for i in 1..rings {
        let theta = PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = 2.0 * PI * j as f64 / segments as f64;
            points.push(
                r * DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ),
            );
        }
    }
    points.push(DVec3::new(0.0, 0.0, -r));
    let ring = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as u16;
    let bottom = (points.len() - 1) as u16;
    let mut indices = Vec::new();
    for j in 0..segments {
        indices.extend([0, ring(1, j), ring(1, j + 1)]);
        indices.extend([bottom, ring(rings - 1, j + 1), ring(rings - 1, j)]);
        for i in 1..rings - 1 {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            indices.extend([a, c, b, b, c, d]);
        }
    }
    (points.iter().flat_map(|&p| gltf(p)).collect(), indices)
}

/// A box with corners `lo` and `hi` (timbre axes), outward winding.
fn cuboid(lo: DVec3, hi: DVec3) -> (Vec<f32>, Vec<u16>) {
    let corner = |k: usize| {
        DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let points: Vec<f32> = (0..8).flat_map(|k| gltf(corner(k))).collect();
    let faces: [[u16; 4]; 6] = [
        [0, 2, 3, 1], // −z
        [4, 5, 7, 6], // +z
        [0, 1, 5, 4], // −y
        [2, 6, 7, 3], // +y
        [0, 4, 6, 2], // −x
        [1, 3, 7, 5], // +x
    ];
    let indices = faces
        .iter()
        .flat_map(|&[a, b, c, d]| [a, b, c, a, c, d])
        .collect();
    (points, indices)
}

/// A motion sampled at 24 fps: position and rotation (timbre axes) at time t.
type Motion<'a> = &'a dyn Fn(f64) -> (DVec3, DQuat);

struct Scene {
    builder: Builder,
}

impl Scene {
    fn new() -> Self {
        Scene {
            builder: Builder::default(),
        }
    }

    /// A still floor: the box 20 × 20 m, its top at z = 0.
    fn floor(&mut self) {
        let (p, i) = cuboid(DVec3::new(-10.0, -10.0, -0.5), DVec3::new(10.0, 10.0, 0.0));
        let mesh = self.builder.mesh(&p, Some(&i), 4);
        self.builder.node(json!({"name": "Floor", "mesh": mesh}));
    }

    fn body(&mut self, name: &str, mesh: (Vec<f32>, Vec<u16>), seconds: f64, motion: Motion) {
        let mesh = self.builder.mesh(&mesh.0, Some(&mesh.1), 4);
        let node = self.builder.node(json!({"name": name, "mesh": mesh}));
        let frames = (seconds * FPS).round() as usize;
        let times: Vec<f32> = (0..=frames).map(|k| (k as f64 / FPS) as f32).collect();
        let mut translations = Vec::new();
        let mut rotations = Vec::new();
        for &t in &times {
            let (p, q) = motion(t as f64);
            translations.extend(gltf(p));
            let axis = to_gltf(DVec3::new(q.x, q.y, q.z));
            rotations.extend([axis.x as f32, axis.y as f32, axis.z as f32, q.w as f32]);
        }
        let channel = |path, values| Channel {
            node,
            path,
            interpolation: "LINEAR",
            times: &times,
            values,
        };
        self.builder.animation(
            name,
            &[
                channel("translation", &translations),
                channel("rotation", &rotations),
            ],
        );
    }

    fn contacts(&self, names: &[(&str, f64)]) -> Contacts {
        let shot = Shot::read(
            &self.builder.glb(),
            &mut |uri| Err(format!("no external buffers ({uri})")),
            &ShotOptions::default(),
        )
        .unwrap();
        let bodies: Vec<Body> = names
            .iter()
            .map(|&(name, density)| Body {
                name: name.to_string(),
                node: shot.node(name).unwrap(),
                density,
                mass: None,
            })
            .collect();
        find_contacts(&shot, &bodies, &ContactOptions::default()).unwrap()
    }
}

/// A ball of radius 0.1 m dropped with its lowest point 1 m above the floor, moving
/// sideways at 0.7 m/s and spinning about the vertical (so its lowest point stays the
/// mesh's pole), bouncing with restitution `e`: the bounce times and the speeds it
/// meets the floor with, and its position at any time.
struct Bounce {
    e: f64,
    times: Vec<f64>,
    speeds: Vec<f64>,
}

const RADIUS: f64 = 0.1;

impl Bounce {
    fn new(e: f64, until: f64) -> Self {
        let mut times = vec![(2.0 / G).sqrt()];
        let mut speeds = vec![G * times[0]];
        while *times.last().unwrap() < until {
            let v = e * speeds.last().unwrap();
            times.push(times.last().unwrap() + 2.0 * v / G);
            speeds.push(v);
        }
        Bounce { e, times, speeds }
    }

    fn height(&self, t: f64) -> f64 {
        let k = self.times.partition_point(|&b| b <= t);
        if k == 0 {
            return 1.0 - 0.5 * G * t * t;
        }
        let s = t - self.times[k - 1];
        self.e * self.speeds[k - 1] * s - 0.5 * G * s * s
    }

    fn pose(&self, t: f64) -> (DVec3, DQuat) {
        (
            DVec3::new(0.7 * t, 0.0, RADIUS + self.height(t).max(0.0)),
            DQuat::from_rotation_z(2.0 * t),
        )
    }
}

#[test]
fn a_bouncing_ball_sampled_at_24_fps_gives_each_bounce_within_a_sample_and_its_speed_within_2_percent(
) {
    let bounce = Bounce::new(0.8, 3.0);
    let mut scene = Scene::new();
    scene.floor();
    scene.body("Ball", sphere(RADIUS, 32, 32), 3.0, &|t| bounce.pose(t));
    let found = scene.contacts(&[("Ball", 1100.0), ("Floor", 2400.0)]);
    // A UV sphere stands for the ball it approximates.
    assert_eq!(found.bodies[0].kind, ShapeKind::Sphere);
    assert!(found.bodies[1].mass.is_infinite());

    // A bounce is resolvable when the flight before it spans three keys.
    let mut resolvable = 0;
    for (k, (&time, &speed)) in bounce.times.iter().zip(&bounce.speeds).enumerate() {
        let flight_start = if k == 0 { 0.0 } else { bounce.times[k - 1] };
        let keys_before = ((time * FPS).ceil() - (flight_start * FPS).ceil()) as i64;
        if time > 3.0 || keys_before < 3 {
            continue;
        }
        resolvable += 1;
        let impact = found
            .impacts
            .iter()
            .find(|i| (i.time - time).abs() < 0.01)
            .unwrap_or_else(|| panic!("bounce {k} at {time:.5} s not found: {:#?}", found.impacts));
        assert!(
            (impact.time - time).abs() < 1.0 / 48_000.0,
            "bounce {k}: found at {} s, is at {time} s",
            impact.time
        );
        assert!(
            (impact.normal_speed - speed).abs() < 0.02 * speed,
            "bounce {k}: normal speed {} m/s, is {speed} m/s",
            impact.normal_speed
        );
        // It met the floor sideways at 0.7 m/s, and left at e times the speed.
        assert!((impact.tangential_speed - 0.7).abs() < 0.02, "{impact:?}");
        assert!(
            (impact.rebound_speed - bounce.e * speed).abs() < 0.03 * speed,
            "{impact:?}"
        );
        let mass = 1100.0 * found.bodies[0].volume;
        let impulse = mass * (1.0 + bounce.e) * speed;
        assert!(
            (impact.impulse - impulse).abs() < 0.03 * impulse,
            "{impact:?}"
        );
        // At the ball's pole, the floor below it; the ball's radius there.
        assert!((impact.point_a - DVec3::new(0.0, 0.0, -RADIUS)).length() < 1e-3);
        assert!((impact.normal - DVec3::NEG_Z).length() < 1e-6);
        assert!(
            (impact.radius_a - RADIUS).abs() < 0.02 * RADIUS,
            "{impact:?}"
        );
    }
    assert!(resolvable >= 5, "only {resolvable} bounces to check");
    // Nothing else: every impact found is a bounce.
    for impact in &found.impacts {
        assert!(
            bounce.times.iter().any(|&b| (b - impact.time).abs() < 1e-3),
            "an impact at {} s where the ball does not bounce",
            impact.time
        );
    }
}

#[test]
fn a_box_at_rest_makes_no_impact_and_presses_with_its_weight() {
    let mut scene = Scene::new();
    scene.floor();
    let half = 0.1;
    scene.body(
        "Box",
        cuboid(DVec3::splat(-half), DVec3::splat(half)),
        2.0,
        &|_| (DVec3::new(0.0, 0.0, half), DQuat::IDENTITY),
    );
    let found = scene.contacts(&[("Box", 700.0), ("Floor", 2400.0)]);
    assert!(found.impacts.is_empty(), "{:?}", found.impacts);
    assert_eq!(found.sustained.len(), 1);
    let weight = 700.0 * 0.2f64.powi(3) * G;
    for sample in &found.sustained[0].samples {
        assert_eq!(sample.kind, ContactKind::Rest);
        assert!(
            (sample.normal_force - weight).abs() < 1e-6 * weight,
            "{sample:?}"
        );
    }
}

#[test]
fn a_box_sliding_to_a_stop_slides_at_its_speed_then_rests() {
    // Coulomb friction μ = 0.4 from 2 m/s: v(t) = 2 − μ·g·t until it stops.
    let (v0, mu) = (2.0, 0.4);
    let stop = v0 / (mu * G);
    let x = |t: f64| {
        let t = t.min(stop);
        v0 * t - 0.5 * mu * G * t * t
    };
    let mut scene = Scene::new();
    scene.floor();
    scene.body(
        "Box",
        cuboid(DVec3::splat(-0.1), DVec3::splat(0.1)),
        1.5,
        &|t| (DVec3::new(x(t), 0.0, 0.1), DQuat::IDENTITY),
    );
    let found = scene.contacts(&[("Box", 700.0), ("Floor", 2400.0)]);
    assert!(found.impacts.is_empty(), "{:?}", found.impacts);
    let samples = &found.sustained[0].samples;
    let mut slid = 0;
    for s in samples {
        let speed = (v0 - mu * G * s.time).max(0.0);
        // Keys a frame away from the stop see it in their quadratic.
        if (s.time - stop).abs() < 1.5 / FPS {
            continue;
        }
        if speed > 0.0 {
            assert_eq!(s.kind, ContactKind::Slide, "{s:?}");
            assert!((s.slip_speed - speed).abs() < 0.01 * v0, "{s:?} {speed}");
            assert!(s.rolling_speed < 1e-6);
            slid += 1;
        } else {
            assert_eq!(s.kind, ContactKind::Rest, "{s:?}");
        }
    }
    assert!(slid > 8);
}

#[test]
fn a_ball_rolling_without_slipping_rolls_at_its_speed() {
    let v = 1.5;
    let mut scene = Scene::new();
    scene.floor();
    scene.body("Ball", sphere(RADIUS, 32, 32), 1.0, &|t| {
        (
            DVec3::new(v * t, 0.0, RADIUS),
            // Rolling along +x turns about +y at v/R.
            DQuat::from_rotation_y(v * t / RADIUS),
        )
    });
    let found = scene.contacts(&[("Ball", 1100.0), ("Floor", 2400.0)]);
    assert!(found.impacts.is_empty(), "{:?}", found.impacts);
    let samples = &found.sustained[0].samples;
    assert!(samples.len() > 20);
    for s in samples {
        assert_eq!(s.kind, ContactKind::Roll, "{s:?}");
        assert!((s.rolling_speed - v).abs() < 0.01 * v, "{s:?}");
        assert!(s.slip_speed < 0.05 * v, "{s:?}");
    }
}

#[test]
fn a_node_without_a_mesh_and_a_mass_that_is_not_positive_are_errors() {
    let mut scene = Scene::new();
    scene.floor();
    scene.builder.node(json!({"name": "Empty"}));
    let shot = Shot::read(
        &scene.builder.glb(),
        &mut |_| Err(String::new()),
        &ShotOptions::default(),
    )
    .unwrap();
    let body = |name: &str, mass| Body {
        name: name.into(),
        node: shot.node(name).unwrap(),
        density: 1000.0,
        mass,
    };
    let options = ContactOptions::default();
    let error = find_contacts(&shot, &[body("Empty", None)], &options).unwrap_err();
    assert_eq!(
        error,
        ContactError::NoMesh {
            name: "Empty".into()
        }
    );
    let error = find_contacts(&shot, &[body("Floor", Some(-1.0))], &options).unwrap_err();
    assert_eq!(
        error.to_string(),
        "\"Floor\" has a mass of -1 kg; a mass must be above 0 and finite"
    );
}

#[test]
fn an_open_mesh_stands_in_by_its_hull_with_a_warning_and_materials_are_read() {
    let mut scene = Scene::new();
    scene.floor();
    // A box without its top: two triangles short of closed.
    let (points, mut indices) = cuboid(DVec3::splat(-0.1), DVec3::splat(0.1));
    indices.drain(6..12);
    scene.body("Cup", (points, indices), 1.0, &|t| {
        (DVec3::new(0.0, 0.0, 0.1 + 0.5 * t), DQuat::IDENTITY)
    });
    let mut json = scene.builder.json(None);
    json["materials"] = json!([{"name": "Clay"}]);
    json["meshes"][1]["primitives"][0]["material"] = json!(0);
    let glb = builder::pack_glb(&json.to_string(), &scene.builder.bin);
    let shot = Shot::read(&glb, &mut |_| Err(String::new()), &ShotOptions::default()).unwrap();
    let cup = shot.node("Cup").unwrap();
    assert_eq!(shot.mesh(cup).unwrap().materials, ["Clay"]);
    let bodies = [("Cup", cup), ("Floor", shot.node("Floor").unwrap())].map(|(name, node)| Body {
        name: name.into(),
        node,
        density: 1000.0,
        mass: None,
    });
    let found = find_contacts(&shot, &bodies, &ContactOptions::default()).unwrap();
    assert_eq!(found.bodies[0].kind, ShapeKind::Hull);
    assert!(
        (found.bodies[0].volume - 0.008).abs() < 1e-9,
        "the hull's volume"
    );
    assert_eq!(
        found.warnings,
        ["the mesh of \"Cup\" is not closed: its convex hull stands in for it"]
    );
    assert_eq!(found.bodies[1].kind, ShapeKind::Convex);
}
