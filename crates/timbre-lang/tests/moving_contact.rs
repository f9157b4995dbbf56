//! A sustained contact strikes an object's modes where the contact is at each key:
//! a steel stylus slides along a free steel bar from its centre to near its end. The
//! gains the lowering writes are the model's at each key's point, and the bar's
//! second bending mode (odd about the centre) is silent while the stylus is at the
//! centre and sounds once it nears the end.

#[path = "../../timbre-motion/tests/builder/mod.rs"]
mod builder;

use std::f64::consts::PI;

use builder::{Builder, Channel};
use glam::DVec3;
use serde_json::json;
use timbre_ir::op::Op;
use timbre_ir::{Diagnostics, Interpreter, RenderConfig, SourceFile};
use timbre_lang::{compile, CompileOptions, Compiled, Registry, SandboxLoader};
use timbre_modal::model::{Model, Strike};
use timbre_motion::contacts::{find_contacts, Body, ContactKind, ContactOptions, Contacts};
use timbre_motion::{to_gltf, Shot, ShotOptions};

const SR: f64 = 48_000.0;
const FPS: f64 = 24.0;
/// The bar: x from −0.2 to 0.2 m, 4 cm wide, 2 cm deep, its top at z = 0.
const LENGTH: f64 = 0.4;
const WIDTH: f64 = 0.04;
const DEPTH: f64 = 0.02;
/// The stylus slides from x = 0 at this speed (m/s) for [`SLIDE`] seconds.
const SPEED: f64 = 0.2;
const SLIDE: f64 = 0.9;
/// Scene time of the shot's time 0: the contact's keys are read on the scene's
/// timeline, not the instance's.
const START: f64 = 0.5;

fn gltf(v: DVec3) -> [f32; 3] {
    to_gltf(v).as_vec3().to_array()
}

/// Positions (glTF axes) and outward-wound triangles of a convex solid given by its
/// corners (timbre axes) and faces (corner indices, counter-clockwise from outside).
fn solid(corners: &[DVec3], faces: &[&[u16]]) -> (Vec<f32>, Vec<u16>) {
    let positions = corners.iter().flat_map(|&p| gltf(p)).collect();
    let triangles = faces
        .iter()
        .flat_map(|f| (1..f.len() - 1).flat_map(|k| [f[0], f[k], f[k + 1]]))
        .collect();
    (positions, triangles)
}

/// The bar, a box with corners `lo` and `hi`.
fn bar() -> (Vec<f32>, Vec<u16>) {
    let (lo, hi) = (
        DVec3::new(-LENGTH / 2.0, -WIDTH / 2.0, -DEPTH),
        DVec3::new(LENGTH / 2.0, WIDTH / 2.0, 0.0),
    );
    let corners: Vec<DVec3> = (0..8)
        .map(|k| {
            DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    let faces: [&[u16]; 6] = [
        &[0, 2, 3, 1],
        &[4, 5, 7, 6],
        &[0, 1, 5, 4],
        &[2, 6, 7, 3],
        &[0, 4, 6, 2],
        &[1, 3, 7, 5],
    ];
    solid(&corners, &faces)
}

/// A stylus: an octahedron of half-diagonal 1 cm, touching with its lowest corner.
fn stylus() -> (Vec<f32>, Vec<u16>) {
    let r = 0.01;
    let corners = [
        DVec3::new(r, 0.0, 0.0),
        DVec3::new(0.0, r, 0.0),
        DVec3::new(-r, 0.0, 0.0),
        DVec3::new(0.0, -r, 0.0),
        DVec3::new(0.0, 0.0, r),
        DVec3::new(0.0, 0.0, -r),
    ];
    let faces: [&[u16]; 8] = [
        &[0, 1, 4],
        &[1, 2, 4],
        &[2, 3, 4],
        &[3, 0, 4],
        &[1, 0, 5],
        &[2, 1, 5],
        &[3, 2, 5],
        &[0, 3, 5],
    ];
    solid(&corners, &faces)
}

/// The shot: the bar still, the stylus's lowest corner on its top, sliding along +x
/// from the centre, sampled at 24 frames a second.
fn slide_shot() -> Vec<u8> {
    let mut b = Builder::default();
    let (p, i) = bar();
    let mesh = b.mesh(&p, Some(&i), 4);
    b.node(json!({"name": "Bar", "mesh": mesh}));
    let (p, i) = stylus();
    let mesh = b.mesh(&p, Some(&i), 4);
    let node = b.node(json!({"name": "Stylus", "mesh": mesh}));
    let frames = (SLIDE * FPS).round() as usize;
    let times: Vec<f32> = (0..=frames).map(|k| (k as f64 / FPS) as f32).collect();
    let translations: Vec<f32> = times
        .iter()
        .flat_map(|&t| gltf(DVec3::new(SPEED * t as f64, 0.0, 0.01)))
        .collect();
    b.animation(
        "Slide",
        &[Channel {
            node,
            path: "translation",
            interpolation: "LINEAR",
            times: &times,
            values: &translations,
        }],
    );
    b.glb()
}

fn compile_shot(text: &str, glb: &[u8]) -> Result<Compiled, Diagnostics> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("slide.glb"), glb).unwrap();
    let sandbox = SandboxLoader::new([dir.path()]).unwrap();
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &sandbox);
    let source = SourceFile::new(dir.path().join("scene.tt").display().to_string(), text);
    compile(source, Some(dir.path()), &options)
}

fn scene() -> String {
    format!(
        "(scene :sample-rate 48000)\n(motion shot \"slide.glb\" :start {START})\n\
         (contacts shot :materials ((\"Bar\" steel) (\"Stylus\" steel)) :modal (\"Bar\") :modes 12)"
    )
}

/// The scene compiled, the bar's model, and the contacts `timbre_motion` finds in
/// the shot as the lowering does.
fn slide() -> (Compiled, Model, Shot, Contacts) {
    let glb = slide_shot();
    let program = compile_shot(&scene(), &glb).unwrap_or_else(|e| panic!("{e:?}"));
    let model = (*program.contacts[0].shapes[0].1).clone();
    let shot = Shot::read(
        &glb,
        &mut |_| Err("no resources".into()),
        &ShotOptions::default(),
    )
    .unwrap();
    let bodies = ["Bar", "Stylus"].map(|name| Body {
        name: name.into(),
        node: shot.node(name).unwrap(),
        density: 7850.0,
        mass: None,
    });
    let contacts = find_contacts(&shot, &bodies, &ContactOptions::default()).unwrap();
    (program, model, shot, contacts)
}

/// The instance of the bar's sliding sound.
fn bar_sliding(program: &Compiled) -> &timbre_ir::Instance {
    program
        .instances
        .iter()
        .find(|i| i.stem.object.as_deref() == Some("Bar") && i.name.contains("sliding"))
        .expect("the bar slides")
}

/// Each mode's gain (its pressure at 1 m per N·s) at each key of the sustained
/// contact, as the lowering wrote it: the lanes of the vector that scales the
/// force into the bar's resonators, each a keyframe track or a constant.
fn written_gains(program: &Compiled, modes: usize, keys: usize) -> Vec<Vec<f64>> {
    let graph = &program.graph;
    let nodes = graph.schedule(bar_sliding(program).root);
    let lane = |n: timbre_ir::NodeId| -> Option<Vec<f64>> {
        match &graph.node(n).op {
            Op::Keyframe(track) => Some(track.values().to_vec()),
            Op::Const(v) if v.len() == 1 => Some(vec![v[0]; keys]),
            _ => None,
        }
    };
    let gains = nodes
        .iter()
        .find(|&&n| {
            let node = graph.node(n);
            matches!(node.op, Op::Concat)
                && node.width == modes
                && node
                    .args
                    .iter()
                    .any(|&a| matches!(graph.node(a).op, Op::Keyframe(_)))
        })
        .expect("a vector of the bar's gains");
    graph
        .node(*gains)
        .args
        .iter()
        .map(|&a| lane(a).expect("a track or a constant"))
        .collect()
}

/// The lowering's tracks are the model's gains at each key's point and along its
/// normal in the bar's frame, mode for mode; they move (a lowering that kept the
/// first key's strike would write constants).
#[test]
fn a_sliding_contact_strikes_the_bar_where_it_is_at_each_key() {
    let (program, model, shot, contacts) = slide();
    assert_eq!(model.modes.len(), 12);
    assert!(contacts.impacts.is_empty(), "{:?}", contacts.impacts);
    let contact = &contacts.sustained[0];
    let samples = &contact.samples;
    assert!(samples.len() > 15, "{}", samples.len());
    assert!(samples[1..samples.len() - 1]
        .iter()
        .all(|s| s.kind == ContactKind::Slide));
    // The keys of the force's tracks: a ramp's before the first and after the last.
    let keys = samples.len() + 2;
    let written = written_gains(&program, model.modes.len(), keys);
    let bar = shot.node("Bar").unwrap();
    let scale = shot.pose(bar, 0.0).scale;
    let mut expected: Vec<Vec<f64>> = vec![vec![]; model.modes.len()];
    let mut keyed = vec![&samples[0]];
    keyed.extend(samples);
    keyed.push(&samples[samples.len() - 1]);
    for s in keyed {
        // The normal points from a toward b: the force on a is along −n.
        let (local, push) = if contact.a == 0 {
            (s.point_a, -s.normal)
        } else {
            (s.point_b, s.normal)
        };
        let strike = Strike {
            point: (local * scale).to_array(),
            direction: (shot.pose(bar, s.time).rotation.inverse() * push).to_array(),
        };
        for (mode, g) in model.gains(&strike, 1.0).0.into_iter().enumerate() {
            expected[mode].push(g);
        }
    }
    let loudest = expected
        .iter()
        .flatten()
        .fold(0.0f64, |m, g| m.max(g.abs()));
    for (mode, (w, e)) in written.iter().zip(&expected).enumerate() {
        assert_eq!(w.len(), e.len(), "mode {mode}");
        for (k, (w, e)) in w.iter().zip(e).enumerate() {
            assert!(
                (w - e).abs() <= 1e-9 * loudest,
                "mode {mode} key {k}: written {w}, model {e}"
            );
        }
    }
    // The contact moves on the bar: the gains of most modes change from key to key.
    let moving = written
        .iter()
        .filter(|w| w.iter().any(|g| (g - w[0]).abs() > 1e-3 * loudest))
        .count();
    assert!(moving >= 6, "{moving} of {} modes move", written.len());
}

/// The bar's lowest two vertical bending modes (Euler–Bernoulli, free–free:
/// β·L = 4.7300 and 7.8532, f = (βL)²/(2πL²)·√(EI/(ρA)) with I/A = h²/12): the
/// indices of the model's modes nearest them, each within 10 % (this only names
/// them: at L/h = 20 shear and rotary inertia lower the second by a few per cent, and
/// the grid of a shot's object is coarse; the beam's own accuracy is `timbre-modal`'s
/// test).
fn bending_modes(model: &Model) -> [usize; 2] {
    let stiffness = (200e9 * DEPTH * DEPTH / 12.0 / 7850.0).sqrt();
    [4.7300f64, 7.8532].map(|beta| {
        let f = beta * beta / (2.0 * PI * LENGTH * LENGTH) * stiffness;
        let (index, mode) = model
            .modes
            .iter()
            .enumerate()
            .min_by(|a, b| {
                (a.1.frequency - f)
                    .abs()
                    .total_cmp(&(b.1.frequency - f).abs())
            })
            .unwrap();
        assert!(
            (mode.frequency / f - 1.0).abs() < 0.1,
            "{} Hz for {f} Hz",
            mode.frequency
        );
        index
    })
}

/// The bar's sliding sound from its instance's start to scene time `until`.
fn render_until(program: &Compiled, until: f64) -> Vec<f64> {
    let instance = bar_sliding(program);
    let mut out = vec![0.0; ((until - instance.start) * SR) as usize];
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 256,
    };
    Interpreter::new(&program.graph, instance.root, config).render(&mut out);
    out
}

/// Power between `lo` and `hi` Hz of `x` (Hann window).
fn band(x: &[f64], lo: f64, hi: f64) -> f64 {
    let mag = timbre_testkit::spectrum(x);
    timbre_testkit::band_power(&mag, SR / x.len() as f64, lo, hi)
}

/// The second bending mode is odd about the bar's centre: the stylus at the centre
/// leaves it silent, near the end it sounds. Measured on the bar's rendered sound, in
/// a band of ±3 % about each mode (no other mode within 10 % of the odd one): the
/// odd mode's power over the first key's interval of the slide (the stylus within
/// 8.3 mm of the centre, where the mode's gain grows in proportion to the distance,
/// so the power it gathers as the cube of the time) against the last 0.15 s (the
/// stylus beyond 15 cm, near the free end, after it has crossed the mode's largest
/// swing between the centre and its node). Near the end the odd mode is louder than
/// the even one (its gain there is ten times the even one's; a strike kept where the
/// contact starts gives it none, and leaves in its band only the other modes' skirts,
/// 22 dB under the even mode), and the even mode, largest at the centre, sounds from
/// the first key (the force's tracks read on the scene's timeline, from the shot's
/// `:start`; read on the instance's own time they would start 0.5 s late).
#[test]
fn an_odd_mode_is_silent_while_the_contact_is_at_the_centre_and_sounds_near_the_end() {
    let (program, model, _, contacts) = slide();
    let [first, second] = bending_modes(&model);
    let f2 = model.modes[second].damped_frequency();
    for (k, m) in model.modes.iter().enumerate() {
        assert!(
            k == second || (m.damped_frequency() / f2 - 1.0).abs() > 0.1,
            "mode {k} at {} Hz beside {f2} Hz",
            m.frequency
        );
    }
    let instance = bar_sliding(&program);
    let samples = &contacts.sustained[0].samples;
    let (from, until) = (
        samples[0].time + START,
        samples[samples.len() - 1].time + START,
    );
    // Touching from the first frame to the last.
    let last_frame = (SLIDE * FPS).round() / FPS;
    assert!(
        (until - from - last_frame).abs() < 1e-6,
        "{from} to {until}"
    );
    let out = render_until(&program, until);
    // The same scene, the same bits.
    let again = render_until(&slide().0, until);
    assert!(out
        .iter()
        .zip(&again)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    let at = |t: f64| ((t - instance.start) * SR) as usize;
    let early = &out[at(from)..at(from + 1.0 / FPS)];
    let late = &out[out.len() - (0.15 * SR) as usize..];
    let db = |a: f64, b: f64| 10.0 * (a / b).log10();
    let odd = |x: &[f64]| band(x, 0.97 * f2, 1.03 * f2);
    let f1 = model.modes[first].damped_frequency();
    let even = |x: &[f64]| band(x, 0.97 * f1, 1.03 * f1);
    let rise = db(odd(late), odd(early));
    let beside = db(odd(late), even(late));
    let start = db(even(early), even(late));
    eprintln!(
        "odd mode {f2:.1} Hz rises {rise:.1} dB, ends {beside:.1} dB re the even one at \
         {f1:.1} Hz, which starts {start:.1} dB re its end"
    );
    assert!(rise > 20.0, "the odd mode rises {rise} dB");
    assert!(
        beside > 0.0,
        "the odd mode is {beside} dB under the even one"
    );
    assert!(
        start > -40.0,
        "the even mode starts {start} dB under its end"
    );
}
