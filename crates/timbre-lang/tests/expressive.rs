//! The expressive nodes (Hahn et al. 1995 §4.2): `gain-db`, `pan`, `importance`,
//! `inverse-importance`, `energetic` and `sputter`, rendered from text.

use timbre_ir::op::frac;
use timbre_ir::{Interpreter, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};

fn render(text: &str, seconds: f64, sr: f64, block_size: usize) -> Vec<f64> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let program = compile_str(text, &options).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    let config = RenderConfig {
        sample_rate: sr,
        block_size,
    };
    let mut voice = Interpreter::new(&program.graph, program.root.unwrap(), config);
    let mut out = vec![0.0; (seconds * sr).round() as usize];
    voice.render(&mut out);
    out
}

fn compile_error(text: &str) -> String {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    match compile_str(text, &options) {
        Ok(_) => panic!("{text} compiled"),
        Err(d) => format!("{d:?}"),
    }
}

#[test]
fn gain_db_scales_by_ten_to_the_db_over_20() {
    let y = render("(gain-db -6 (+ 1 (* 0 t)))", 0.01, 8000.0, 64);
    let expected = 10f64.powf(-6.0 / 20.0);
    assert!(y.iter().all(|v| (v - expected).abs() < 1e-15), "{}", y[0]);
    let y = render("(gain-db (* 20 t) 0.5)", 1.0, 100.0, 7);
    for (n, v) in y.iter().enumerate() {
        let db = 20.0 * n as f64 / 100.0;
        assert!((v - 0.5 * 10f64.powf(db / 20.0)).abs() < 1e-12, "{n}");
    }
}

#[test]
fn pan_is_equal_power_and_clamped() {
    for (p, left, right) in [
        (-1.0, 1.0, 0.0),
        (0.0, 0.5f64.sqrt(), 0.5f64.sqrt()),
        (1.0, 0.0, 1.0),
        (-3.0, 1.0, 0.0),
        (7.0, 0.0, 1.0),
    ] {
        let l = render(&format!("(index (pan {p} 0.5) 0)"), 0.001, 8000.0, 4);
        let r = render(&format!("(index (pan {p} 0.5) 1)"), 0.001, 8000.0, 4);
        assert!((l[0] - 0.5 * left).abs() < 1e-12, "{p}: {}", l[0]);
        assert!((r[0] - 0.5 * right).abs() < 1e-12, "{p}: {}", r[0]);
    }
    // A moving position keeps the power: left² + right² = x² at every sample.
    let text = "(let ((s (pan (sine (* t 3)) 0.8))) (+ (* (index s 0) (index s 0)) (* (index s 1) (index s 1))))";
    for v in render(text, 1.0, 1000.0, 33) {
        assert!((v - 0.64).abs() < 1e-12, "{v}");
    }
}

#[test]
fn importance_weights_sum_to_one_at_every_sample() {
    // With every sound at 1 the mix is the sum of the normalised weights: 1, for
    // keyframe-like moving weights, a weight going negative, and all weights 0.
    let text = "(importance (vector 1 1 1 1)
                   (vector (+ 1 (sine (* t 3))) (* 4 t) (- 0.5 t) (* 0 t)))";
    let y = render(text, 2.0, 1000.0, 17);
    assert!(y.iter().all(|v| (v - 1.0).abs() < 1e-12), "{y:?}");
    // The weights themselves: lane i of the sounds picks weight i.
    let y = render(
        "(importance (vector 1 0 0) (vector 2 -1 6))",
        0.01,
        1000.0,
        3,
    );
    assert!(y.iter().all(|v| (v - 0.25).abs() < 1e-15));
    let y = render(
        "(importance (vector 1 0 0) (vector 0 -1 0))",
        0.01,
        1000.0,
        3,
    );
    assert!(y.iter().all(|v| (v - 1.0 / 3.0).abs() < 1e-15));
    // The locked weights of Fig. 8.
    let y = render(
        "(importance (vector 0 0 0 1) (importance-locked 4 67 20 10))",
        0.01,
        1000.0,
        3,
    );
    assert!(y.iter().all(|v| (v - 0.03).abs() < 1e-12), "{}", y[0]);
}

#[test]
fn inversion_ramps_over_the_transition() {
    // Sound 1 alone is heard: its effective weight 3/4, then 1/4 after the
    // switch at 0.5 s, moving linearly over 0.25 s.
    let text = "(inverse-importance (vector 1 0) (vector 3 1) (>= t 0.5) :transition 0.25)";
    let sr = 1000.0;
    let y = render(text, 1.0, sr, 19);
    assert!(y[..500].iter().all(|v| (v - 0.75).abs() < 1e-12));
    for (k, v) in y[500..750].iter().enumerate() {
        let a = (k + 1) as f64 / 250.0;
        assert!((v - (0.75 - 0.5 * a)).abs() < 1e-9, "{k}: {v}");
    }
    assert!(y[750..].iter().all(|v| (v - 0.25).abs() < 1e-12));
    // No transition: a jump; switched on from the start: no ramp at the start.
    let y = render(
        "(inverse-importance (vector 1 0) (vector 3 1) (>= t 0.5) :transition 0)",
        1.0,
        sr,
        19,
    );
    assert_eq!((y[499], y[500]), (0.75, 0.25));
    let y = render(
        "(inverse-importance (vector 1 0 0) (vector 6 3 1) 1)",
        0.1,
        sr,
        19,
    );
    assert!(y.iter().all(|v| (v - 0.1).abs() < 1e-12), "{}", y[0]);
}

#[test]
fn inversion_weights_sum_to_one_while_moving() {
    let text = "(inverse-importance (vector 1 1 1 1) (vector 67 20 10 3)
                   (square (* t 3)) :transition 0.2)";
    for v in render(text, 2.0, 1000.0, 64) {
        assert!((v - 1.0).abs() < 1e-12, "{v}");
    }
}

#[test]
fn energetic_replays_at_speed() {
    // At speed 2 a 100 Hz sine is a 200 Hz one; at speed 0.5, 50 Hz. Interpolated
    // sample by sample: close to the exact sine, exact at whole positions.
    let sr = 8000.0;
    let y = render("(energetic 2 (sine (* t 100)))", 0.5, sr, 37);
    for (n, v) in y.iter().enumerate() {
        let exact = (std::f64::consts::TAU * 200.0 * n as f64 / sr).sin();
        assert!((v - exact).abs() < 1e-12, "{n}: {v} vs {exact}");
    }
    let y = render("(energetic 0.5 (sine (* t 100)))", 0.5, sr, 37);
    // (Between samples 0 and 1 the sample before the start counts as 0.)
    for (n, v) in y.iter().enumerate().skip(2) {
        let exact = (std::f64::consts::TAU * 50.0 * n as f64 / sr).sin();
        assert!((v - exact).abs() < 1e-4, "{n}: {v} vs {exact}");
    }
    // Half the length: a sound of 0.5 s ends after 0.25 s.
    let y = render("(energetic 2 (* (< t 0.5) (+ 1 (* 0 t))))", 1.0, sr, 100);
    assert!(y[..2000].iter().all(|v| *v == 1.0));
    assert!(y[2002..].iter().all(|v| *v == 0.0), "{:?}", &y[1995..2005]);
}

#[test]
fn energetic_does_not_depend_on_the_block_size() {
    let text =
        "(energetic (+ 1 (* 0.7 (sine (* t 2)))) (+ (sine (* t 330)) (lowpass (white) 800)))";
    let reference = render(text, 0.3, 8000.0, 1);
    for block in [2, 7, 64, 256, 1000] {
        assert_eq!(render(text, 0.3, 8000.0, block), reference, "{block}");
    }
}

#[test]
fn energetic_clamps_its_speed() {
    // A speed of 0 or less holds the source at a crawl: nothing non-finite, no
    // hang at an infinite speed.
    for speed in ["0", "-3", "(/ 0 0)", "(/ 1 0)"] {
        let y = render(
            &format!("(energetic {speed} (sine (+ 0.25 (* t 50))))"),
            0.05,
            8000.0,
            64,
        );
        assert!(y.iter().all(|v| v.is_finite()), "{speed}");
    }
    let slowest = render("(energetic 0.001 (+ 1 t))", 0.01, 1000.0, 4);
    assert_eq!(render("(energetic 0 (+ 1 t))", 0.01, 1000.0, 4), slowest);
    assert!((slowest[9] - 1.0).abs() < 0.01, "{}", slowest[9]);
}

/// Upward zero crossings of y − 0.5 (the start of each cycle after the first).
fn cycle_starts(y: &[f64]) -> Vec<usize> {
    (1..y.len()).filter(|&n| y[n] > y[n - 1] + 0.25).collect()
}

#[test]
fn sputter_sweeps_its_rate() {
    let sr = 8000.0;
    // Linear 12 → 1 Hz in 4 s: φ(t) = 12t − 11t²/8, 26 cycles by 4 s, then 1 Hz.
    let y = render("(sputter 12 1 4 :curve 0)", 6.0, sr, 50);
    assert_eq!(y[0], 1.0);
    let starts = cycle_starts(&y);
    // (The sum of the rates runs ahead of the integral by about 11/(2·sr): the
    // 26th cycle starts a sample or two before 4 s.)
    assert_eq!(starts.iter().filter(|&&n| n < 31900).count(), 25);
    assert_eq!(starts.iter().filter(|&&n| n <= 32000).count(), 26);
    let phase = |t: f64| 12.0 * t - 11.0 * t * t / 8.0;
    assert!(
        (y[16000] - (1.0 - frac(phase(2.0)))).abs() < 2e-3,
        "{}",
        y[16000]
    );
    // After the sweep: one cycle per second.
    let late: Vec<&usize> = starts.iter().filter(|&&n| n > 32000).collect();
    assert_eq!(late.len(), 2);
    assert!((late[1] - late[0]) as f64 - sr <= 1.0);
    // The first cycle lasts about 1/12 s.
    assert!(
        (starts[0] as f64 / sr - 0.0841).abs() < 1e-3,
        "{}",
        starts[0]
    );
    // Exponential (the default): 44/ln 12 = 17.7 cycles.
    let y = render("(sputter 12 1 4)", 4.0, sr, 50);
    assert_eq!(cycle_starts(&y).len(), 17);
    let exact = 48.0 / 12f64.ln() * (1.0 - 12f64.powf(-0.5));
    assert!(
        (y[16000] - (1.0 - frac(exact))).abs() < 2e-3,
        "{}",
        y[16000]
    );
    assert!(y.iter().all(|v| *v > 0.0 && *v <= 1.0));
}

#[test]
fn bad_input_is_a_diagnostic() {
    for (text, code) in [
        ("(importance-locked 4 67 40)", "timbre::bad-importance"),
        ("(importance-locked 1 50 50)", "timbre::bad-importance"),
        ("(importance-locked 2 30 30)", "timbre::bad-importance"),
        ("(importance-locked 2 (* t 3))", "timbre::not-constant"),
        (
            "(importance (vector 1 2) (vector 1 2 3))",
            "timbre::width-mismatch",
        ),
        ("(pan 0 (vector 1 2))", "timbre::width-mismatch"),
        ("(energetic 2 (vector 1 2))", "timbre::width-mismatch"),
        ("(energetic (vector 1 2) 1)", "timbre::width-mismatch"),
        ("(sputter 12 1 4 :curve 2)", "timbre::bad-sputter"),
        (
            "(inverse-importance (vector 1 2) (vector 1 2) (vector 0 1))",
            "timbre::width-mismatch",
        ),
    ] {
        let diagnostics = compile_error(text);
        assert!(diagnostics.contains(code), "{text}: {diagnostics}");
    }
}
