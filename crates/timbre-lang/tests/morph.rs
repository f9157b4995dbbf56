//! `morph`: parameters interpolated by a position, logarithmically for frequencies
//! unless told otherwise, and two trees crossfaded, measured from rendered output.

mod common;

use common::{compile_with, render, SR};

const TONES: &str = "(define-sound tone (f amp) (* amp (sine (phasor f))))
(define-sound buzz (f amp) (* amp (square (phasor f))))\n";

/// The mean frequency over `from..to` seconds, from upward zero crossings.
fn frequency(x: &[f64], from: f64, to: f64) -> f64 {
    let (a, b) = ((from * SR) as usize, (to * SR) as usize);
    let ups: Vec<f64> = (a..b)
        .filter(|&k| x[k - 1] < 0.0 && x[k] >= 0.0)
        .map(|k| k as f64 - x[k] / (x[k] - x[k - 1]))
        .collect();
    (ups.len() - 1) as f64 * SR / (ups[ups.len() - 1] - ups[0])
}

#[test]
fn a_frequency_moves_by_equal_intervals_and_a_level_linearly() {
    // x goes from 0 to 1 over 2 s: halfway, 220 → 880 is at their geometric mean.
    let source = format!("{TONES}(morph (tone 220 0.2) (tone 880 0.6) (/ t 2))");
    let x = render(&source, &[], 2.0);
    let halfway = frequency(&x, 0.95, 1.05);
    assert!((halfway / 440.0 - 1.0).abs() < 0.01, "{halfway} Hz");
    let quarter = frequency(&x, 0.45, 0.55);
    assert!((quarter / 311.13 - 1.0).abs() < 0.01, "{quarter} Hz");
    // The level (below 20) moves linearly: 0.4 halfway.
    let peak = x[(0.95 * SR) as usize..(1.05 * SR) as usize]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    assert!((peak - 0.4).abs() < 0.01, "{peak}");
}

#[test]
fn linear_and_log_can_be_chosen() {
    let source = format!("{TONES}(morph (tone 220 0.5) (tone 880 0.5) (/ t 2) :linear (f))");
    let halfway = frequency(&render(&source, &[], 2.0), 0.95, 1.05);
    assert!((halfway / 550.0 - 1.0).abs() < 0.01, "{halfway} Hz");
    let source = format!("{TONES}(morph (tone 1 0.5) (tone 4 0.5) 0.5 :log (amp f))");
    let program = compile_with(&source, &[], 0).unwrap();
    assert!(program.root.is_some());
}

#[test]
fn two_trees_with_the_same_parameters_are_crossfaded() {
    let at = |x: f64| {
        render(
            &format!("{TONES}(morph (tone 300 0.5) (buzz 300 0.5) {x})"),
            &[],
            0.1,
        )
    };
    assert_eq!(at(0.0), render(&format!("{TONES}(tone 300 0.5)"), &[], 0.1));
    assert_eq!(at(1.0), render(&format!("{TONES}(buzz 300 0.5)"), &[], 0.1));
    // Past the ends, the position is held there.
    assert_eq!(at(7.0), at(1.0));
}

#[test]
fn ends_that_do_not_match_are_refused() {
    let source = format!(
        "{TONES}(define-sound other (g amp) (* amp (sine (phasor g))))\n(morph (tone 220 0.5) (other 440 0.5) 0.5)"
    );
    let errors = compile_with(&source, &[], 0).unwrap_err();
    assert_eq!(errors.0[0].code, "timbre::morph-mismatch");
    let errors = compile_with(&format!("{TONES}(morph (tone 220 0.5) 3 0.5)"), &[], 0).unwrap_err();
    assert_eq!(errors.0[0].code, "timbre::bad-morph");
    let errors = compile_with(
        &format!("{TONES}(morph (tone 220 0.5) (tone 1 1) 0.5 :log (g))"),
        &[],
        0,
    )
    .unwrap_err();
    assert_eq!(errors.0[0].code, "timbre::unknown-keyword");
}
