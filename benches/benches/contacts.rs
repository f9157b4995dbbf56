//! Contact reconstruction at scale: 100 cubes over 250 frames at 24 fps, each dropped
//! onto one floor from its own height and bouncing (restitution 0.6) while it turns,
//! so there are flights, impacts and resting contacts to find. The shot is written
//! here as a glTF file and read as a user's would be; the bench times
//! `find_contacts` alone, on one thread.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::{DQuat, DVec3};
use timbre_motion::contacts::{find_contacts, Body, ContactOptions};
use timbre_motion::{to_gltf, Shot, ShotOptions};

const CUBES: usize = 100;
const FRAMES: usize = 250;
const FPS: f64 = 24.0;
const G: f64 = 9.80665;

/// A box's 8 corners and 12 outward triangles.
fn cuboid(half: f64) -> (Vec<f32>, Vec<u16>) {
    let corner = |k: usize| {
        let s = |bit: usize| if k & bit == 0 { -half } else { half };
        to_gltf(DVec3::new(s(1), s(2), s(4))).as_vec3().to_array()
    };
    let points = (0..8).flat_map(corner).collect();
    let faces: [[u16; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let indices = faces
        .iter()
        .flat_map(|&[a, b, c, d]| [a, b, c, a, c, d])
        .collect();
    (points, indices)
}

/// Height of a cube's lowest point above the floor: dropped from `h`, bouncing with
/// restitution 0.6 until its hops are under a millimetre.
fn height(h: f64, t: f64) -> f64 {
    let (mut start, mut speed) = (0.0, 0.0);
    let mut top = h;
    loop {
        // This flight: from `top` at rest (the first), or up from the floor.
        let fall = if start == 0.0 {
            (2.0 * h / G).sqrt()
        } else {
            2.0 * speed / G
        };
        if t < start + fall || top < 1e-3 {
            let s = t - start;
            return if start == 0.0 {
                h - 0.5 * G * s * s
            } else {
                (speed * s - 0.5 * G * s * s).max(0.0)
            };
        }
        let landing = if start == 0.0 { G * fall } else { speed };
        start += fall;
        speed = 0.6 * landing;
        top = speed * speed / (2.0 * G);
    }
}

/// The shot as a `.glb`: a floor and 100 animated cubes.
fn shot() -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bytes: Vec<u8>, component: u32, kind: &str, count: usize, bounds: String| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{}}}"#,
            bin.len(),
            bytes.len()
        ));
        bin.extend(bytes);
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":{component},"type":"{kind}","count":{count}{bounds}}}"#,
            views.len() - 1
        ));
        accessors.len() - 1
    };
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let minmax = |v: &[f32], width: usize| {
        let column = |k: usize| v.iter().skip(k).step_by(width).copied();
        let lo: Vec<String> = (0..width)
            .map(|k| column(k).fold(f32::INFINITY, f32::min).to_string())
            .collect();
        let hi: Vec<String> = (0..width)
            .map(|k| column(k).fold(f32::NEG_INFINITY, f32::max).to_string())
            .collect();
        format!(r#","min":[{}],"max":[{}]"#, lo.join(","), hi.join(","))
    };
    let mut mesh = |half: f64| {
        let (points, indices) = cuboid(half);
        let position = push(floats(&points), 5126, "VEC3", 8, minmax(&points, 3));
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let index = push(bytes, 5123, "SCALAR", indices.len(), String::new());
        (position, index)
    };
    let floor = mesh(20.0);
    let cube = mesh(0.1);
    let meshes = [floor, cube].map(|(p, i)| {
        format!(r#"{{"primitives":[{{"attributes":{{"POSITION":{p}}},"indices":{i}}}]}}"#)
    });
    let mut nodes = vec![r#"{"name":"Floor","mesh":0,"translation":[0,-20,0]}"#.to_string()];
    let times: Vec<f32> = (0..FRAMES).map(|k| (k as f64 / FPS) as f32).collect();
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let input = push(floats(&times), 5126, "SCALAR", FRAMES, minmax(&times, 1));
    for c in 0..CUBES {
        let (x, y) = ((c % 10) as f64 - 4.5, (c / 10) as f64 - 4.5);
        let drop = 0.3 + 0.02 * c as f64;
        let mut translation = Vec::new();
        let mut rotation = Vec::new();
        for &t in &times {
            let t = t as f64;
            let p = DVec3::new(x, y, 0.1 + height(drop, t));
            translation.extend(to_gltf(p).as_vec3().to_array());
            let q = DQuat::from_rotation_z((1.0 + 0.01 * c as f64) * t);
            let axis = to_gltf(DVec3::new(q.x, q.y, q.z));
            rotation.extend([axis.x as f32, axis.y as f32, axis.z as f32, q.w as f32]);
        }
        let node = nodes.len();
        nodes.push(format!(r#"{{"name":"Cube{c}","mesh":1}}"#));
        for (path, values, kind) in [
            ("translation", translation, "VEC3"),
            ("rotation", rotation, "VEC4"),
        ] {
            let width = if kind == "VEC3" { 3 } else { 4 };
            let output = push(floats(&values), 5126, kind, FRAMES, minmax(&values, width));
            samplers.push(format!(
                r#"{{"input":{input},"output":{output},"interpolation":"LINEAR"}}"#
            ));
            channels.push(format!(
                r#"{{"sampler":{},"target":{{"node":{node},"path":"{path}"}}}}"#,
                samplers.len() - 1
            ));
        }
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[]}}],"nodes":[{}],"meshes":[{}],"animations":[{{"name":"drop","samplers":[{}],"channels":[{}]}}],"buffers":[{{"byteLength":{}}}],"bufferViews":[{}],"accessors":[{}]}}"#,
        nodes.join(","),
        meshes.join(","),
        samplers.join(","),
        channels.join(","),
        bin.len(),
        views.join(","),
        accessors.join(",")
    );
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(bin);
    glb
}

fn contacts(c: &mut Criterion) {
    let shot = Shot::read(
        &shot(),
        &mut |uri| Err(uri.to_owned()),
        &ShotOptions::default(),
    )
    .expect("the bench's shot reads");
    let mut bodies = vec![Body {
        name: "Floor".into(),
        node: shot.node("Floor").expect("a floor"),
        density: 2400.0,
        mass: None,
    }];
    bodies.extend((0..CUBES).map(|k| Body {
        name: format!("Cube{k}"),
        node: shot.node(&format!("Cube{k}")).expect("a cube"),
        density: 700.0,
        mass: None,
    }));
    let options = ContactOptions::default();
    let found = find_contacts(&shot, &bodies, &options).expect("contacts");
    println!(
        "contacts of {CUBES} cubes over {FRAMES} frames: {} impacts, {} sustained contacts",
        found.impacts.len(),
        found.sustained.len()
    );
    let mut group = c.benchmark_group("contacts");
    group.sample_size(10);
    group.bench_function("100 cubes x 250 frames", |b| {
        b.iter(|| find_contacts(&shot, &bodies, &options).expect("contacts"))
    });
    group.finish();
}

criterion_group!(benches, contacts);
criterion_main!(benches);
