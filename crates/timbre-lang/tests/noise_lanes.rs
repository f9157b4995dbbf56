//! Noises of several lanes: `(noise x :lanes n)`, `(pink :lanes n)`,
//! `(markov rate :lanes n)`, and a noise of a wide argument, give each lane a noise
//! of its own seed (lane k has seed s + k), measured on long renders: the lanes do
//! not correlate, each is the one-lane noise's level, and lane 0 is the one-lane
//! noise itself.

mod common;

use common::*;
use timbre_testkit::rms;

/// Pearson's correlation of two signals.
fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        let (a, b) = (a - mx, b - my);
        sxy += a * b;
        sxx += a * a;
        syy += b * b;
    }
    sxy / (sxx * syy).sqrt()
}

/// Lane `k` of `form`, rendered alone.
fn lane(form: &str, k: usize, seconds: f64) -> Vec<f64> {
    render_seeded(&format!("(index {form} {k})"), &[], seconds, 5)
}

/// The largest pairwise |correlation| of `lanes`.
fn worst_correlation(lanes: &[Vec<f64>]) -> f64 {
    let mut worst: f64 = 0.0;
    for (a, x) in lanes.iter().enumerate() {
        for y in &lanes[a + 1..] {
            worst = worst.max(correlation(x, y).abs());
        }
    }
    worst
}

/// Every lane of `form` (of `n` lanes) uncorrelated with the others and at the level
/// of `single`, the one-lane noise, within 15 %.
fn assert_independent_lanes(form: &str, n: usize, single: &str, seconds: f64) -> Vec<Vec<f64>> {
    let lanes: Vec<Vec<f64>> = (0..n).map(|k| lane(form, k, seconds)).collect();
    let worst = worst_correlation(&lanes);
    let level = rms(&render_seeded(single, &[], seconds, 5));
    let levels: Vec<f64> = lanes.iter().map(|x| rms(x) / level).collect();
    eprintln!("{form}: worst |correlation| {worst:.3}, lane rms / one-lane rms {levels:.3?}");
    assert!(worst < 0.2, "{form}: lanes correlate ({worst:.3})");
    for (k, ratio) in levels.iter().enumerate() {
        assert!(
            (ratio - 1.0).abs() < 0.15,
            "{form}: lane {k} at {ratio:.3} of the one-lane level"
        );
    }
    lanes
}

#[test]
fn noise_lanes_are_independent_gradient_noises() {
    let form = "(noise (* t 20) :lanes 6)";
    let lanes = assert_independent_lanes(form, 6, "(noise (* t 20))", 30.0);
    // Lane 0 is the one-lane noise of the same seed, sample for sample.
    assert_eq!(
        lanes[0],
        render_seeded("(noise (* t 20))", &[], 30.0, 5),
        "{form}: lane 0"
    );
    // Each lane is still gradient noise: zero at every lattice point (t = k/20).
    for x in &lanes {
        for k in 1..100 {
            assert!(x[k * 2400].abs() < 1e-9, "not zero at lattice point {k}");
        }
    }
}

/// An argument of several lanes gives each lane its own seed too: the lanes of
/// `(noise (* t (vector 20 20 20 20)))` were one noise four times before.
#[test]
fn a_wide_argument_gives_each_lane_its_own_noise() {
    assert_independent_lanes(
        "(noise (* t (vector 20 20 20 20)))",
        4,
        "(noise (* t 20))",
        30.0,
    );
    // `:lanes` equal to the argument's width is the same node.
    assert_eq!(
        render("(combine (noise (* t (vector 20 30)) :lanes 2))", &[], 0.5),
        render("(combine (noise (* t (vector 20 30))))", &[], 0.5)
    );
}

#[test]
fn pink_lanes_are_independent_pink_noises() {
    let lanes = assert_independent_lanes("(pink :lanes 4)", 4, "(pink)", 10.0);
    assert_eq!(lanes[0], render_seeded("(pink)", &[], 10.0, 5), "lane 0");
}

#[test]
fn markov_lanes_are_independent_markov_noises() {
    let lanes = assert_independent_lanes("(markov 20 :lanes 4)", 4, "(markov 20)", 60.0);
    assert_eq!(
        lanes[0],
        render_seeded("(markov 20)", &[], 60.0, 5),
        "lane 0"
    );
    assert_independent_lanes("(markov (vector 20 20 20))", 3, "(markov 20)", 60.0);
}

/// `:seed` and the scene seed reach every lane, and lane 0 keeps the seed `:seed`
/// gives the one-lane noise.
#[test]
fn lane_seeds_follow_the_node_seed() {
    for (wide, one) in [
        (
            "(noise (* t 50) :lanes 3 :seed 9)",
            "(noise (* t 50) :seed 9)",
        ),
        ("(pink :lanes 3 :seed 9)", "(pink :seed 9)"),
        ("(markov 50 :lanes 3 :seed 9)", "(markov 50 :seed 9)"),
    ] {
        assert_eq!(
            lane(wide, 0, 1.0),
            render_seeded(one, &[], 1.0, 5),
            "{wide}"
        );
        let other_scene = render_seeded(&format!("(index {wide} 2)"), &[], 1.0, 6);
        assert_ne!(lane(wide, 2, 1.0), other_scene, "{wide}: scene seed");
    }
}

/// `examples/swarm.tt`, the paper's swarm written with `:lanes`: each bee's pitch
/// wobble (its frequency's deviation, 12 · wobble) is its own, over a long flight.
#[test]
fn the_swarms_bees_wobble_each_in_their_own_way() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/swarm.tt");
    let text = std::fs::read_to_string(path).unwrap();
    // The definitions, without the sound (the file's last top-level form).
    let cut = text.rfind("\n(").unwrap();
    assert!(!text[cut..].starts_with("\n(define"), "the sound is last");
    let definitions = &text[..cut];
    let deviation = |k: usize| {
        let source = format!("{definitions}\n(index (* 12 wobble) {k})");
        let program = compile_with(&source, &[], 1).unwrap_or_else(|e| panic!("{e:?}"));
        render_program(&program, 200.0, 256)
    };
    let bees: Vec<Vec<f64>> = (0..8).map(deviation).collect();
    let worst = worst_correlation(&bees);
    let spread: Vec<f64> = bees.iter().map(|x| rms(x)).collect();
    eprintln!("swarm: worst |correlation| of the bees' wobble {worst:.3}, rms Hz {spread:.2?}");
    assert!(worst < 0.2, "the bees wobble together ({worst:.3})");
    // Each wobbles by a few Hz, as the one bee does.
    assert!(spread.iter().all(|s| (2.0..8.0).contains(s)), "{spread:?}");
}
