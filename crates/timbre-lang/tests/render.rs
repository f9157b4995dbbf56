//! Measured behaviour of rendered trees: frequencies, decay rates, long-run phase,
//! modal spectra, determinism.

mod common;

use common::*;
use timbre_ir::RenderConfig;
use timbre_testkit::{peak, slope, spectral_peaks, spectrum, zero_crossing_frequency};

const BELL: &str = "(combine (* (sine (* t (rvector n_f base_f max_f)))
            (damp (* t (* damp_ratio (rvector n_f base_f max_f))))))";

const BEE: &str = "(sawtooth (+ (* t (+ nominal-freq (* 12 (noise (* t LF-noise)))))
             (* 0.25 (noise (* t HF-noise)))))";

#[test]
fn sine_frequency_is_exact() {
    for f in [27.5, 440.0, 1000.0, 3951.07] {
        let x = render("(sine (* t f))", &[("f", f)], 4.0);
        let measured = zero_crossing_frequency(&x, SR);
        assert!((measured - f).abs() < 0.01, "{f} Hz measured as {measured}");
    }
}

#[test]
fn sine_stays_clean_for_ten_minutes() {
    let x = render("(sine (* t 1000))", &[], 600.0);
    // Exact phase from integer arithmetic: n·1000/48000 cycles = (n mod 48) / 48.
    let mut worst = 0.0f64;
    for (n, y) in x.iter().enumerate() {
        let exact = (std::f64::consts::TAU * ((n as u64 * 1000) % 48_000) as f64 / 48_000.0).sin();
        worst = worst.max((y - exact).abs());
    }
    // A phase error of e cycles moves a sample by at most 2π·e.
    let phase_error = worst / std::f64::consts::TAU;
    assert!(phase_error < 1e-6, "phase error {phase_error} cycles");
    let last_second = &x[x.len() - 48_000..];
    assert!((zero_crossing_frequency(last_second, SR) - 1000.0).abs() < 0.01);
}

#[test]
fn damp_decays_at_the_given_rate() {
    for rate in [0.5, 3.0, 20.0] {
        let x = render("(damp (* t rate))", &[("rate", rate)], 1.0);
        let points: Vec<(f64, f64)> = x
            .iter()
            .enumerate()
            .step_by(100)
            .map(|(i, y)| (i as f64 / SR, y.ln()))
            .collect();
        let measured = -slope(&points);
        assert!(
            (measured / rate - 1.0).abs() < 1e-3,
            "rate {rate} measured {measured}"
        );
    }
    // And as the envelope of a mode: peaks of each cycle decay at the rate.
    let x = render("(* (sine (* t 200)) (damp (* t 4)))", &[], 1.0);
    let points: Vec<(f64, f64)> = x
        .chunks(240)
        .enumerate()
        .map(|(c, chunk)| {
            let (i, v) = chunk.iter().enumerate().fold((0, 0.0f64), |m, (i, v)| {
                if v.abs() > m.1 {
                    (i, v.abs())
                } else {
                    m
                }
            });
            ((c * 240 + i) as f64 / SR, v.ln())
        })
        .collect();
    let measured = -slope(&points);
    assert!(
        (measured / 4.0 - 1.0).abs() < 1e-3,
        "envelope rate {measured}"
    );
}

fn bell_bindings(n: f64) -> Vec<(&'static str, f64)> {
    vec![
        ("n_f", n),
        ("base_f", 300.0),
        ("max_f", 3000.0),
        ("damp_ratio", 0.0005),
    ]
}

fn modes(n: usize, seed: u64) -> Vec<f64> {
    let b = bell_bindings(n as f64);
    let mut modes: Vec<f64> = (0..n)
        .map(|i| constant(&format!("(index (rvector n_f base_f max_f) {i})"), &b, seed))
        .collect();
    modes.sort_by(f64::total_cmp);
    modes
}

#[test]
fn modal_tree_peaks_sit_at_the_rvector_values() {
    let n = 8;
    let expected = modes(n, 11);
    assert!(expected.iter().all(|f| (300.0..3000.0).contains(f)));
    let x = render_seeded(BELL, &bell_bindings(n as f64), 2.0, 11);
    let mut found = spectral_peaks(&x, SR, n);
    found.sort_by(f64::total_cmp);
    for (e, f) in expected.iter().zip(&found) {
        assert!(
            (e - f).abs() < 0.5,
            "mode {e} Hz found at {f} Hz (all: {found:?})"
        );
    }
}

#[test]
fn the_same_seed_gives_identical_samples_and_another_seed_other_modes() {
    let b = bell_bindings(40.0);
    let a = render_seeded(BELL, &b, 0.5, 3);
    let again = render_seeded(BELL, &b, 0.5, 3);
    assert!(a
        .iter()
        .zip(&again)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
    let other = render_seeded(BELL, &b, 0.5, 4);
    assert!(a.iter().zip(&other).any(|(x, y)| x != y));
    assert_ne!(modes(8, 3), modes(8, 4));
}

#[test]
fn output_does_not_depend_on_the_block_size() {
    let text = format!(
        "(+ {BELL} (lowpass (white) 2000) (delay (pink) (+ 0.01 (* 0.005 (sine t))) 0.02) (phasor 3) (markov 5)
            (conv (white :seed 1) (damp (* t 300)) :length 0.05) (adsr (< t 0.1) 0.01 0.02 0.5 0.05))"
    );
    let program = compile_with(&text, &bell_bindings(20.0), 1).unwrap();
    let reference = render_program(&program, 0.3, 256);
    for block in [1, 7, 64, 1000] {
        let other = render_program(&program, 0.3, block);
        assert!(
            reference
                .iter()
                .zip(&other)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "block size {block}"
        );
    }
}

#[test]
fn a_render_split_into_calls_equals_one_call() {
    let program = compile_with(
        BEE,
        &[
            ("nominal-freq", 220.0),
            ("LF-noise", 3.0),
            ("HF-noise", 400.0),
        ],
        0,
    )
    .unwrap();
    let whole = render_program(&program, 0.5, 256);
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 256,
    };
    let mut voice = timbre_ir::Interpreter::new(&program.graph, program.root.unwrap(), config);
    let mut parts = vec![0.0; whole.len()];
    let (a, b) = parts.split_at_mut(12_345);
    voice.render(a);
    voice.render(b);
    assert_eq!(whole, parts);
}

#[test]
fn the_bee_buzzes_near_its_nominal_frequency() {
    // The paper's tree multiplies t by a drifting frequency, so the instantaneous
    // frequency also gains t·d(noise)/dt: look at the first quarter second, where the
    // drift stays within about ±20 Hz.
    let x = render(
        BEE,
        &[
            ("nominal-freq", 220.0),
            ("LF-noise", 3.0),
            ("HF-noise", 400.0),
        ],
        0.25,
    );
    assert!(peak(&x) <= 1.0);
    let mag = spectrum(&x);
    let bin = SR / x.len() as f64;
    let (best, _) = mag
        .iter()
        .enumerate()
        .take((400.0 / bin) as usize)
        .skip(1)
        .fold((0, 0.0), |m, (i, v)| if *v > m.1 { (i, *v) } else { m });
    let f = best as f64 * bin;
    assert!((f - 220.0).abs() < 20.0, "fundamental at {f}");
}

/// Forty named trees, each calling the one before twice: 2⁴⁰ expansions written
/// out, forty with expansions memoised on their arguments.
fn doubling_definitions(levels: usize) -> String {
    let mut text = String::from("(define d0 (x) (sine x))\n");
    for k in 1..=levels {
        text += &format!(
            "(define d{k} (x) (* 0.5 (+ (d{j} x) (d{j} x))))\n",
            j = k - 1
        );
    }
    text + &format!("(d{levels} (* t 440))\n")
}

#[test]
fn expansions_are_memoised_on_their_arguments() {
    let start = std::time::Instant::now();
    let program = compile_with(&doubling_definitions(40), &[], 0).expect("compiles");
    let elapsed = start.elapsed();
    // t, 440, their product, the sine, 0.5, and per level one sum and one product.
    assert!(program.graph.len() < 100, "{} nodes", program.graph.len());
    // Without memoising this would not finish; with it, it is instant. (The bound
    // is loose: it guards against a regression, not a benchmark.)
    assert!(elapsed.as_secs_f64() < 5.0, "{elapsed:?}");
    let y = render_program(&program, 0.01, 256);
    let expected = render("(sine (* t 440))", &[], 0.01);
    assert_eq!(y, expected);
}
