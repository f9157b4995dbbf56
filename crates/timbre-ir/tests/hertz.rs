//! The `impact` kernel's force pulse against Hertz's closed forms (K. L. Johnson,
//! *Contact Mechanics*, 1985, §11.4), computed here from the materials' constants, not
//! from the kernel's own derived figures: the peak force, the contact time (as 2.94·
//! δ_max/v and as Johnson's 2.87·(m*²/(R*·E*²·v))^(1/5)), the impulse 2·m*·v, and
//! τ ∝ v^(−1/5).

use timbre_ir::dsp::impact::{
    universal_node, universal_speed, Bodies, ImpactError, Quantity, DURATION, HALF_DURATION,
};
use timbre_ir::dsp::materials::{Material, OAK, RUBBER, STEEL};

/// A ball of `ball` (radius r) dropped on a flat, immovable plate of `plate`.
fn ball_on_plate(ball: &Material, plate: &Material, r: f64, speed: f64) -> Bodies {
    Bodies {
        youngs_a: ball.youngs,
        poisson_a: ball.poisson,
        youngs_b: plate.youngs,
        poisson_b: plate.poisson,
        radius_a: r,
        radius_b: f64::INFINITY,
        mass_a: ball.density * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3),
        mass_b: f64::INFINITY,
        speed,
    }
}

/// The closed forms for `bodies` as Johnson writes them: (E*, R*, m*, δ_max, F_max,
/// τ = 2.94·δ_max/v, Johnson's τ = 2.87·(m*²/(R*·E*²·v))^(1/5)).
struct ClosedForm {
    mass: f64,
    max_compression: f64,
    peak: f64,
    duration: f64,
    johnson_duration: f64,
}

fn closed_form(b: &Bodies) -> ClosedForm {
    let e =
        1.0 / ((1.0 - b.poisson_a.powi(2)) / b.youngs_a + (1.0 - b.poisson_b.powi(2)) / b.youngs_b);
    let r = 1.0 / (1.0 / b.radius_a + 1.0 / b.radius_b);
    let m = if b.mass_b.is_finite() {
        b.mass_a * b.mass_b / (b.mass_a + b.mass_b)
    } else {
        b.mass_a
    };
    let v = b.speed;
    let max_compression = (15.0 * m * v * v / (16.0 * e * r.sqrt())).powf(0.4);
    ClosedForm {
        mass: m,
        max_compression,
        peak: 4.0 / 3.0 * e * r.sqrt() * max_compression.powf(1.5),
        duration: 2.9432 * max_compression / v,
        johnson_duration: 2.87 * (m * m / (r * e * e * v)).powf(0.2),
    }
}

/// The kernel's samples at `sample_rate` until the pulse is over (and 100 more).
fn pulse(bodies: &Bodies, sample_rate: f64) -> Vec<f64> {
    let impact = bodies.impact().expect("a good impact");
    let mut out = vec![];
    let mut zeros = 0;
    for i in 0.. {
        let y = impact.sample(i, sample_rate);
        out.push(y);
        zeros = if y == 0.0 { zeros + 1 } else { 0 };
        if zeros > 100 && i > 10 {
            break;
        }
    }
    out
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// (steel ball 1 cm on steel, rubber ball 2 cm on oak) at 0.1, 1 and 10 m/s.
fn cases() -> Vec<(&'static str, Bodies)> {
    let mut cases = vec![];
    for v in [0.1, 1.0, 10.0] {
        cases.push(("steel on steel", ball_on_plate(&STEEL, &STEEL, 0.01, v)));
        cases.push(("rubber on oak", ball_on_plate(&RUBBER, &OAK, 0.02, v)));
    }
    cases
}

#[test]
fn the_pulse_has_hertz_peak_duration_and_impulse() {
    for (name, bodies) in cases() {
        let expected = closed_form(&bodies);
        // At least 2000 samples across the contact, so a sample's mean is its force.
        let sample_rate = 2000.0 / expected.duration;
        let y = pulse(&bodies, sample_rate);
        let peak = y.iter().copied().fold(0.0, f64::max);
        let first = y.iter().position(|y| *y != 0.0).unwrap();
        let last = y.iter().rposition(|y| *y != 0.0).unwrap();
        let impulse: f64 = y.iter().sum::<f64>() / sample_rate;
        let samples = (last - first) as f64;
        let v = bodies.speed;
        println!(
            "{name} at {v} m/s: δ_max {:.4e} m, peak {peak:.6e} N (closed form {:.6e}), \
             {samples} samples ({:.2} expected), τ {:.6e} s, Johnson {:.6e} s",
            expected.max_compression,
            expected.peak,
            expected.duration * sample_rate,
            expected.duration,
            expected.johnson_duration
        );
        assert!(relative(peak, expected.peak) < 0.005, "{name} {v}: peak");
        assert_eq!(first, 0, "{name} {v}: starts at the instance's t = 0");
        assert!(
            (samples - expected.duration * sample_rate).abs() <= 1.0,
            "{name} {v}: duration"
        );
        assert!(
            relative(samples / sample_rate, expected.johnson_duration) < 0.02,
            "{name} {v}: Johnson's duration"
        );
        assert!(
            relative(impulse, 2.0 * expected.mass * v) < 0.005,
            "{name} {v}: impulse"
        );
        // Every sample is a force: none negative.
        assert!(y.iter().all(|y| *y >= 0.0), "{name} {v}");
    }
}

#[test]
fn a_contact_shorter_than_a_sample_still_delivers_its_impulse() {
    // Steel on steel at 48 kHz: about 3 samples of a 70 µs contact.
    let bodies = ball_on_plate(&STEEL, &STEEL, 0.01, 1.0);
    let expected = closed_form(&bodies);
    let y = pulse(&bodies, 48_000.0);
    let nonzero = y.iter().filter(|y| **y != 0.0).count();
    assert!((3..=5).contains(&nonzero), "{nonzero} samples");
    let impulse: f64 = y.iter().sum::<f64>() / 48_000.0;
    assert!(relative(impulse, 2.0 * expected.mass) < 1e-9, "{impulse}");
}

#[test]
fn the_duration_goes_as_the_speed_to_the_minus_one_fifth() {
    for (material, plate, r) in [(&STEEL, &STEEL, 0.01), (&RUBBER, &OAK, 0.02)] {
        let measured = |v: f64| {
            let bodies = ball_on_plate(material, plate, r, v);
            let sample_rate = 2000.0 / closed_form(&bodies).duration;
            let y = pulse(&bodies, sample_rate);
            y.iter().rposition(|y| *y != 0.0).unwrap() as f64 / sample_rate
        };
        let speeds = [0.1, 0.3, 1.0, 3.0, 10.0];
        let durations: Vec<f64> = speeds.iter().map(|v| measured(*v)).collect();
        for k in 1..speeds.len() {
            let exponent = (durations[k] / durations[0]).ln() / (speeds[k] / speeds[0]).ln();
            assert!(
                (exponent + 0.2).abs() < 0.002,
                "{} {exponent}",
                material.name
            );
        }
        // The exponent fitted by least squares to log τ over log v, all five speeds.
        let points: Vec<(f64, f64)> = speeds
            .iter()
            .zip(&durations)
            .map(|(v, tau)| (v.ln(), tau.ln()))
            .collect();
        let fitted = timbre_testkit::slope(&points);
        println!("{}: τ ∝ v^{fitted:.5}", material.name);
        assert!((fitted + 0.2).abs() < 0.001, "{} {fitted}", material.name);
    }
}

#[test]
fn two_finite_masses_and_two_curvatures_combine_as_effective_ones() {
    // Two equal steel balls head on: m* = m/2, R* = r/2.
    let mut bodies = ball_on_plate(&STEEL, &STEEL, 0.01, 1.0);
    bodies.radius_b = 0.01;
    bodies.mass_b = bodies.mass_a;
    let expected = closed_form(&bodies);
    assert!(relative(expected.mass, bodies.mass_a / 2.0) < 1e-15);
    let sample_rate = 2000.0 / expected.duration;
    let y = pulse(&bodies, sample_rate);
    let impulse: f64 = y.iter().sum::<f64>() / sample_rate;
    assert!(relative(impulse, bodies.mass_a) < 1e-9);
    let peak = y.iter().copied().fold(0.0, f64::max);
    assert!(relative(peak, expected.peak) < 0.005);
}

#[test]
fn the_universal_curve_turns_at_its_closed_form_time() {
    // u(s_half) = 1, u'(s_half) = 0 for s_half = (2/5)·B(2/5, 1/2), and the energy
    // u'² + u^(5/2) = 1 holds at every node of the table.
    let mut j = 0;
    while let Some((s, u, w)) = universal_node(j) {
        assert!(
            (w * w + u.powf(2.5) - 1.0).abs() < 1e-12,
            "node {j} at s {s}"
        );
        j += 1;
    }
    let (s, u, w) = universal_node(j - 1).unwrap();
    assert!((s - HALF_DURATION).abs() < 1e-15);
    assert!((u - 1.0).abs() < 1e-12 && w.abs() < 1e-9, "u {u}, u' {w}");
    // The speed runs from 1 to −1, odd about the turn, and between the nodes too.
    assert_eq!(universal_speed(0.0), 1.0);
    assert_eq!(universal_speed(DURATION), -1.0);
    for s in [0.1234, 0.777, 1.3, 1.47] {
        let w = universal_speed(s);
        assert!((universal_speed(DURATION - s) + w).abs() < 1e-14);
        // u from the energy, then u'' = −(5/4)·u^(3/2) against a central difference.
        let u = (1.0 - w * w).powf(0.4);
        let h = 1e-5;
        let accel = (universal_speed(s + h) - universal_speed(s - h)) / (2.0 * h);
        assert!((accel + 1.25 * u.powf(1.5)).abs() < 1e-8, "s {s}");
    }
}

#[test]
fn bad_bodies_are_refused_in_order() {
    let good = ball_on_plate(&STEEL, &OAK, 0.01, 1.0);
    assert!(good.impact().is_ok());
    let with = |f: fn(&mut Bodies)| {
        let mut b = good;
        f(&mut b);
        b.impact()
    };
    use ImpactError::OutOfRange;
    assert_eq!(
        with(|b| b.youngs_a = 0.0),
        Err(OutOfRange(Quantity::YoungsA, 0.0))
    );
    assert_eq!(
        with(|b| b.youngs_b = -1.0),
        Err(OutOfRange(Quantity::YoungsB, -1.0))
    );
    assert_eq!(
        with(|b| b.poisson_a = 0.6),
        Err(OutOfRange(Quantity::PoissonA, 0.6))
    );
    assert_eq!(
        with(|b| b.poisson_b = -1.0),
        Err(OutOfRange(Quantity::PoissonB, -1.0))
    );
    assert_eq!(
        with(|b| b.radius_a = f64::INFINITY),
        Err(OutOfRange(Quantity::RadiusA, f64::INFINITY))
    );
    assert_eq!(
        with(|b| b.radius_b = 0.0),
        Err(OutOfRange(Quantity::RadiusB, 0.0))
    );
    assert_eq!(
        with(|b| b.mass_a = -0.1),
        Err(OutOfRange(Quantity::MassA, -0.1))
    );
    assert!(
        matches!(with(|b| b.mass_b = f64::NAN), Err(OutOfRange(Quantity::MassB, x)) if x.is_nan())
    );
    assert_eq!(
        with(|b| b.speed = 0.0),
        Err(OutOfRange(Quantity::Speed, 0.0))
    );
    assert_eq!(
        with(|b| (b.speed, b.mass_a) = (0.0, 0.0)),
        Err(OutOfRange(Quantity::MassA, 0.0))
    );
    assert_eq!(with(|b| b.speed = 1e300), Err(ImpactError::NotFinite));
    assert_eq!(with(|b| b.mass_a = 1e-320), Err(ImpactError::NotFinite));
}
