//! `impact` from text: the Hertz pulse rendered at a scene's rate against the closed
//! forms (Johnson, *Contact Mechanics*, §11.4), materials by name, and its diagnostics.

use timbre_ir::{Interpreter, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};

fn render(text: &str, samples: usize, sr: f64, block_size: usize) -> Vec<f64> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let program = compile_str(text, &options).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    let config = RenderConfig {
        sample_rate: sr,
        block_size,
    };
    let mut voice = Interpreter::new(&program.graph, program.root.unwrap(), config);
    let mut out = vec![0.0; samples];
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

/// E*, R*, m* and v to Hertz's peak force, duration and impulse.
fn closed_form(e: f64, r: f64, m: f64, v: f64) -> (f64, f64, f64) {
    let max_compression = (15.0 * m * v * v / (16.0 * e * r.sqrt())).powf(0.4);
    let peak = 4.0 / 3.0 * e * r.sqrt() * max_compression.powf(1.5);
    (peak, 2.9432 * max_compression / v, 2.0 * m * v)
}

#[test]
fn a_rubber_ball_on_oak_at_48_khz_is_hertz() {
    // Rubber (E 5 MPa, ν 0.49) on oak (E 12 GPa, ν 0.35), R 2 cm, m 36.9 g, 1 m/s.
    let (m, v, sr) = (0.0369, 1.0, 48_000.0);
    let e = 1.0 / ((1.0 - 0.49f64.powi(2)) / 5e6 + (1.0 - 0.35f64.powi(2)) / 12e9);
    let (peak, duration, impulse) = closed_form(e, 0.02, m, v);
    let text = format!("(impact :a rubber :b oak :radius 0.02 :mass {m} :speed {v})");
    let y = render(&text, 4800, sr, 64);
    let measured_peak = y.iter().copied().fold(0.0, f64::max);
    let last = y.iter().rposition(|y| *y != 0.0).unwrap();
    println!(
        "peak {measured_peak} N of {peak}, {last} samples of {}",
        duration * sr
    );
    assert!((measured_peak / peak - 1.0).abs() < 0.005);
    assert_ne!(y[0], 0.0, "the contact starts at the instance's t = 0");
    assert!((last as f64 - duration * sr).abs() <= 1.0);
    let sum: f64 = y.iter().sum::<f64>() / sr;
    assert!((sum / impulse - 1.0).abs() < 1e-9, "{sum} N·s of {impulse}");
    // The same at any block size.
    assert_eq!(render(&text, 4800, sr, 7), y);
}

#[test]
fn two_steel_balls_meet_with_their_effective_mass_and_radius() {
    // Equal balls: m* = m/2 and R* = R/2, so the impulse is m·v.
    let text = "(impact :a steel :b steel :radius 0.05 :radius-b 0.05 :mass 4 :mass-b 4 :speed 2)";
    let y = render(text, 480, 48_000.0, 64);
    let sum: f64 = y.iter().sum::<f64>() / 48_000.0;
    assert!((sum - 8.0).abs() < 1e-9, "{sum}");
    // Numbers in place of the names give the same bits.
    let numbers = "(impact :youngs 200e9 :poisson 0.29 :youngs-b 200e9 :poisson-b 0.29 \
                   :radius 0.05 :radius-b 0.05 :mass 4 :mass-b 4 :speed 2)";
    assert_eq!(render(numbers, 480, 48_000.0, 64), y);
}

#[test]
fn bad_impacts_are_diagnosed_at_the_form() {
    let good = ":radius 0.01 :mass 0.03 :speed 1";
    let cases = [
        (
            format!("(impact :a stel :b oak {good})"),
            "timbre::unknown-material",
            "did you mean `steel`?",
        ),
        (
            format!("(impact :a steel :b \"oak\" {good})"),
            "timbre::unknown-material",
            "a material is a name",
        ),
        (
            "(impact :a steel :b oak :radius 0.01 :mass 0 :speed 1)".into(),
            "timbre::bad-impact",
            "the mass of body a must be above 0 and finite, not 0",
        ),
        (
            "(impact :a steel :b oak :radius -0.01 :mass 0.03 :speed 1)".into(),
            "timbre::bad-impact",
            "the radius of body a must be above 0 and finite, not -0.01",
        ),
        (
            "(impact :a steel :b oak :radius 0.01 :mass 0.03 :speed (/ 1 0))".into(),
            "timbre::bad-impact",
            "the impact speed must be above 0 and finite, not inf",
        ),
        (
            format!("(impact :a steel :b oak :mass-b -2 {good})"),
            "timbre::bad-impact",
            "the mass of body b must be above 0, not -2",
        ),
        (
            format!("(impact :youngs 0 :poisson 0.3 :b oak {good})"),
            "timbre::bad-impact",
            "the Young's modulus of body a must be above 0 and finite, not 0",
        ),
        (
            format!("(impact :a steel :youngs-b 1e9 :poisson-b 0.7 {good})"),
            "timbre::bad-impact",
            "the Poisson's ratio of body b must be above −1 and at most 0.5, not 0.7",
        ),
        (
            "(impact :a steel :b oak :radius 0.01 :mass 0.03)".into(),
            "timbre::bad-impact",
            "`impact` needs the normal speed",
        ),
        (
            format!("(impact :b oak {good})"),
            "timbre::bad-impact",
            "`impact` needs the material of body a",
        ),
        (
            format!("(impact :a steel :b oak :youngs 1e9 {good})"),
            "timbre::duplicate-argument",
            "the material of body a is given twice",
        ),
        (
            "(impact :a steel :b oak :radius (* t 2) :mass 0.03 :speed 1)".into(),
            "timbre::not-constant",
            "the radius of body a must be a constant number",
        ),
    ];
    for (text, code, message) in cases {
        let error = compile_error(&text);
        assert!(error.contains(code), "{text}: {error}");
        assert!(error.contains(message), "{text}: {error}");
    }
}

#[test]
fn an_impact_prints_back_as_its_constants_and_reads_the_same() {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let text = "(impact :a glass :b stone :radius 0.004 :mass 0.002 :speed 3)";
    let program = compile_str(text, &options).unwrap();
    let printed = timbre_lang::print_tree(&program.graph, program.root.unwrap(), &[]).unwrap();
    println!("{printed}");
    assert!(
        printed.contains(":youngs 70000000000 :poisson 0.22"),
        "{printed}"
    );
    assert!(!printed.contains("radius-b"), "{printed}");
    let again = render(&printed, 480, 48_000.0, 64);
    assert_eq!(again, render(text, 480, 48_000.0, 64));
    assert!(again.iter().any(|y| *y > 0.0));
}
