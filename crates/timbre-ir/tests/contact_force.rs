//! The `scrape` and `roll` kernels measured: a groove of wavelength λ sounds at v/λ,
//! the force scales with the normal force and is 0 at rest, micro-impacts are a
//! Poisson process of rate `impacts`·v, and the rolling force is the profile low-passed
//! by the Hertz patch, whose half-width is Johnson's closed form.

use timbre_ir::dsp::contact_force::{ContactForce, Motion, Roller, Surface};
use timbre_ir::dsp::materials::{Material, OAK, STEEL};
use timbre_testkit::{band_power, spectrum, strongest_peak};

const SR: f64 = 48_000.0;

/// The documented defaults of `scrape`.
fn surface() -> Surface {
    Surface {
        roughness: 1e-6,
        grain: 1e-4,
        period: 0.0,
        impacts: 200.0,
        hold: 100.0,
        seed: 7,
    }
}

fn roller(radius: f64, a: &Material, b: &Material) -> Roller {
    Roller {
        radius,
        youngs_a: a.youngs,
        poisson_a: a.poisson,
        youngs_b: b.youngs,
        poisson_b: b.poisson,
    }
}

fn scrape(surface: Surface) -> ContactForce {
    ContactForce::new(surface, Motion::Scrape).expect("a good surface")
}

fn constant(x: f64, n: usize) -> Vec<f64> {
    vec![x; n]
}

#[test]
fn a_groove_of_wavelength_lambda_sounds_at_speed_over_lambda() {
    let lambda = 1e-3;
    let kernel = scrape(Surface {
        period: lambda,
        ..surface()
    });
    let n = 1 << 16;
    for v in [0.05, 0.2, 1.0] {
        let y = kernel.render(&constant(v, n), &constant(2.0, n), SR);
        let measured = strongest_peak(&y, SR);
        let expected = v / lambda;
        println!("v {v} m/s: peak {measured:.3} Hz, v/λ {expected} Hz");
        assert!((measured / expected - 1.0).abs() < 0.02, "{v}: {measured}");
    }
}

#[test]
fn the_force_scales_with_the_normal_force_and_is_zero_at_rest() {
    let kernel = scrape(Surface {
        period: 2e-3,
        ..surface()
    });
    let n = 48_000;
    let speed: Vec<f64> = (0..n)
        .map(|i| 0.3 + 0.2 * (i as f64 / 5000.0).sin())
        .collect();
    let one = kernel.render(&speed, &constant(1.5, n), SR);
    let double = kernel.render(&speed, &constant(3.0, n), SR);
    assert!(one.iter().any(|y| *y != 0.0));
    // Twice the force: exactly twice the samples (a power of two scales exactly).
    assert!(one.iter().zip(&double).all(|(a, b)| 2.0 * a == *b));
    let seven = kernel.render(&speed, &constant(10.5, n), SR);
    for (a, b) in one.iter().zip(&seven) {
        assert!(
            (7.0 * a - b).abs() <= 1e-12 * b.abs().max(1e-300),
            "{a} {b}"
        );
    }
    // No force, or no speed (either sign of zero): exact zeros.
    let none = kernel.render(&speed, &constant(0.0, n), SR);
    assert!(none.iter().all(|y| *y == 0.0));
    for rest in [0.0, -0.0] {
        let still = kernel.render(&constant(rest, n), &constant(5.0, n), SR);
        assert!(still.iter().all(|y| *y == 0.0));
    }
    // A negative speed slides as fast the other way: the same force.
    let back: Vec<f64> = speed.iter().map(|v| -v).collect();
    assert_eq!(kernel.render(&back, &constant(1.5, n), SR), one);
}

#[test]
fn the_same_seed_gives_the_same_bits_and_another_seed_others() {
    let n = 24_000;
    let (v, f) = (constant(0.4, n), constant(2.0, n));
    let a = scrape(surface()).render(&v, &f, SR);
    let b = scrape(surface()).render(&v, &f, SR);
    let other = scrape(Surface {
        seed: 8,
        ..surface()
    })
    .render(&v, &f, SR);
    assert_eq!(a, b);
    let differ = a.iter().zip(&other).filter(|(x, y)| x != y).count();
    assert!(differ > n / 2, "{differ} samples differ");
}

#[test]
fn a_contact_that_ramps_in_and_out_starts_and_ends_at_zero() {
    // Force and speed rise from 0 and fall back to 0 over 0.1 s: no step anywhere, and
    // without micro-impacts the force never exceeds the normal force.
    let kernel = scrape(Surface {
        impacts: 0.0,
        ..surface()
    });
    let n = 48_000;
    let ramp: Vec<f64> = (0..n)
        .map(|i| (i.min(n - 1 - i) as f64 / 4800.0).min(1.0))
        .collect();
    let force: Vec<f64> = ramp.iter().map(|r| 5.0 * r).collect();
    let speed: Vec<f64> = ramp.iter().map(|r| 2.0 * r).collect();
    let y = kernel.render(&speed, &force, SR);
    assert_eq!(y[0], 0.0);
    assert_eq!(y[n - 1], 0.0);
    assert!(y.iter().zip(&force).all(|(y, f)| y.abs() <= *f));
    // The first 10 ms (force under 0.5 N, speed under 0.2 m/s) stay under 1 % of the
    // full force: v²·κ/hold is small there.
    let early = y[..480].iter().fold(0.0f64, |m, y| m.max(y.abs()));
    assert!(early < 0.05, "{early}");
    assert!(y.iter().any(|y| y.abs() > 0.5));
}

#[test]
fn micro_impacts_are_a_poisson_process_of_rate_density_times_speed() {
    // A smooth surface: only the micro-impacts sound.
    let kernel = scrape(Surface {
        roughness: 0.0,
        ..surface()
    });
    let seconds = 100;
    for v in [0.25, 1.0] {
        let mut slide = kernel.start();
        let mut per_second = vec![];
        let mut nonzero = 0;
        for _ in 0..seconds {
            let before = slide.impacts();
            for _ in 0..SR as usize {
                let y = kernel.step(&mut slide, v, 3.0, SR);
                nonzero += usize::from(y != 0.0);
                assert!(y >= 0.0);
            }
            per_second.push((slide.impacts() - before) as f64);
        }
        let count = slide.impacts() as f64;
        let expected = 200.0 * v * seconds as f64;
        let sd = expected.sqrt();
        println!("v {v}: {count} impacts, expected {expected} ± {sd:.1}");
        assert!((count - expected).abs() < 4.0 * sd, "{v}: {count}");
        // Two in one sample are rare at these rates: nearly every impact is a sample.
        assert!(count - nonzero as f64 <= 0.01 * count, "{nonzero}");
        // A Poisson count's variance equals its mean (sd of the ratio ≈ √(2/99)).
        let mean = per_second.iter().sum::<f64>() / seconds as f64;
        let variance =
            per_second.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (seconds - 1) as f64;
        let dispersion = variance / mean;
        println!("  dispersion {dispersion:.3}");
        assert!((0.6..1.4).contains(&dispersion), "{dispersion}");
    }
}

#[test]
fn the_patch_half_width_is_hertz() {
    // Johnson (Contact Mechanics, §4.2): δ = (9·P²/(16·R·E*²))^(1/3) and a = √(R·δ),
    // here for a steel ball of radius 1 cm on steel and on oak under 1, 10 and 100 N.
    for (plate, label) in [(&STEEL, "steel"), (&OAK, "oak")] {
        let r = roller(0.01, &STEEL, plate);
        let e = 1.0
            / ((1.0 - STEEL.poisson.powi(2)) / STEEL.youngs
                + (1.0 - plate.poisson.powi(2)) / plate.youngs);
        for p in [1.0, 10.0, 100.0] {
            let delta = (9.0 * p * p / (16.0 * 0.01 * e * e)).cbrt();
            let expected = (0.01 * delta).sqrt();
            let a = r.half_width(p);
            println!("steel on {label}, {p} N: a = {a:.6e} m (closed form {expected:.6e})");
            assert!((a / expected - 1.0).abs() < 1e-12);
        }
    }
}

/// Band powers of `y` (at `rate`) in bands `width` Hz wide from 0 to `top` Hz.
fn bands(y: &[f64], rate: f64, width: f64, top: f64) -> Vec<f64> {
    let mag = spectrum(y);
    let bin_hz = rate / y.len() as f64;
    let count = (top / width) as usize;
    (0..count)
        .map(|k| band_power(&mag, bin_hz, k as f64 * width, (k + 1) as f64 * width))
        .collect()
}

fn sinc(z: f64) -> f64 {
    if z == 0.0 {
        1.0
    } else {
        z.sin() / z
    }
}

#[test]
fn rolling_low_passes_the_profile_by_the_contact_patch() {
    // A steel ball of 1 cm rolling on steel under 100 N: a = 190 µm. The rolling force
    // is the profile's curvature averaged over the patch, the sliding one's (the same
    // surface) over ±h, one table spacing (12.5 µm here), so the rolling spectrum over
    // the sliding one is sinc(z)/sinc(z·h/a), z = 2π·f·a/v: −6 dB at z ≈ 1.8955
    // (f ≈ 0.6034·v/(2a)), the first null at v/(2a). A linear hold and no
    // micro-impacts keep both linear in the profile; 192 kHz keeps the images of the
    // table's interpolation (above 30 kHz at 0.5 m/s) from aliasing onto the band
    // measured. Bands of 25 Hz, a thirtieth of the −6 dB point at the lower speed,
    // locate the crossing by linear interpolation to within about 1 %; 3 % is allowed.
    let rate = 192_000.0;
    let surface = Surface {
        grain: 50e-6,
        impacts: 0.0,
        hold: 1e12,
        ..surface()
    };
    let ball = roller(0.01, &STEEL, &STEEL);
    let force = 100.0;
    let a = ball.half_width(force);
    let rolling = ContactForce::new(surface, Motion::Roll(ball)).unwrap();
    let sliding = scrape(surface);
    assert_eq!(rolling.probe_half_width(force), a);
    let h = sliding.probe_half_width(force);
    // The z at which sinc(z)/sinc(z·h/a) = 1/2, by bisection.
    let (mut lo, mut hi) = (1.0, 2.5);
    for _ in 0..60 {
        let z = 0.5 * (lo + hi);
        if sinc(z) / sinc(z * h / a) > 0.5 {
            lo = z;
        } else {
            hi = z;
        }
    }
    let n = 1 << 18;
    let width = 25.0;
    for v in [0.5, 1.0] {
        let f = constant(force, n);
        let roll = bands(
            &rolling.render(&constant(v, n), &f, rate),
            rate,
            width,
            8000.0,
        );
        let slide = bands(
            &sliding.render(&constant(v, n), &f, rate),
            rate,
            width,
            8000.0,
        );
        let gain: Vec<f64> = roll
            .iter()
            .zip(&slide)
            .map(|(r, s)| (r / s).sqrt())
            .collect();
        let centre = |k: usize| (k as f64 + 0.5) * width;
        let k = (1..gain.len()).find(|&k| gain[k] < 0.5).expect("a fall");
        let t = (gain[k - 1] - 0.5) / (gain[k - 1] - gain[k]);
        let measured = centre(k - 1) + t * width;
        let predicted = lo * v / (std::f64::consts::TAU * a);
        let null = v / (2.0 * a);
        println!(
            "v {v} m/s, a {a:.4e} m: −6 dB at {measured:.1} Hz, predicted {predicted:.1} Hz \
             (0.6034·v/(2a) = {:.1} Hz); v/(2a) = {null:.1} Hz",
            0.6034 * null
        );
        assert!((measured / predicted - 1.0).abs() < 0.03, "{v}: {measured}");
        // Well below the patch the gain is near 1, as predicted; around v/(2a) the
        // rolling force is more than 20 dB down.
        let low = (0.2 * predicted / width) as usize;
        let z = std::f64::consts::TAU * centre(low) * a / v;
        let expected = sinc(z) / sinc(z * h / a);
        assert!(
            (gain[low] - expected).abs() < 0.05,
            "{} {expected}",
            gain[low]
        );
        let near_null = (null / width) as usize;
        assert!(gain[near_null] < 0.1, "{}", gain[near_null]);
    }
}

#[test]
fn bad_surfaces_and_rollers_are_refused_in_order() {
    use timbre_ir::dsp::contact_force::{OutOfRange, Quantity};
    let refused = |s: Surface, m: Motion| ContactForce::new(s, m).err();
    assert_eq!(
        refused(
            Surface {
                roughness: -1e-6,
                ..surface()
            },
            Motion::Scrape
        ),
        Some(OutOfRange(Quantity::Roughness, -1e-6))
    );
    assert_eq!(
        refused(
            Surface {
                grain: 0.0,
                period: f64::NAN,
                ..surface()
            },
            Motion::Scrape
        ),
        Some(OutOfRange(Quantity::Grain, 0.0))
    );
    let period = refused(
        Surface {
            period: f64::INFINITY,
            ..surface()
        },
        Motion::Scrape,
    );
    assert_eq!(period, Some(OutOfRange(Quantity::Period, f64::INFINITY)));
    let flat = Roller {
        radius: f64::INFINITY,
        ..roller(0.01, &STEEL, &OAK)
    };
    assert_eq!(
        refused(surface(), Motion::Roll(flat)),
        Some(OutOfRange(Quantity::Radius, f64::INFINITY))
    );
    assert!(refused(surface(), Motion::Roll(roller(0.01, &STEEL, &OAK))).is_none());
}
