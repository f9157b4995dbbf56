//! `scrape` and `roll` from text: the groove's frequency at a scene's rate, exact
//! scaling with the normal force, exact zeros at rest, seeds, materials by name,
//! printing back, and the diagnostics of bad surfaces and rollers.

use timbre_ir::{Interpreter, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};
use timbre_testkit::strongest_peak;

const SR: f64 = 48_000.0;

fn render_blocks(text: &str, samples: usize, block_size: usize) -> Vec<f64> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let program = compile_str(text, &options).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut voice = Interpreter::new(&program.graph, program.root.unwrap(), config);
    let mut out = vec![0.0; samples];
    voice.render(&mut out);
    out
}

fn render(text: &str, samples: usize) -> Vec<f64> {
    render_blocks(text, samples, 64)
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
fn a_groove_sounds_at_speed_over_its_wavelength() {
    // A 0.5 mm groove scraped at 0.25 m/s: 500 Hz.
    let y = render("(scrape 0.25 3 :period 0.0005 :seed 2)", 1 << 15);
    let peak = strongest_peak(&y, SR);
    assert!((peak / 500.0 - 1.0).abs() < 0.02, "{peak}");
    // The same at any block size.
    assert_eq!(
        render_blocks("(scrape 0.25 3 :period 0.0005 :seed 2)", 1 << 15, 7),
        y
    );
}

#[test]
fn the_force_scales_with_the_normal_force_and_rests_at_zero() {
    let n = 24_000;
    let speed = "(+ 0.3 (* 0.1 (sine (* t 3))))";
    let one = render(&format!("(scrape {speed} 1.25 :seed 3)"), n);
    let two = render(&format!("(scrape {speed} 2.5 :seed 3)"), n);
    assert!(one.iter().any(|y| *y != 0.0));
    assert!(one.iter().zip(&two).all(|(a, b)| 2.0 * a == *b));
    for text in [
        "(scrape 0 2 :seed 3)",
        "(scrape 0.3 0 :seed 3)",
        "(roll 0 5 :radius 0.01)",
        "(roll 0.4 0 :radius 0.01 :impacts 100)",
    ] {
        assert!(render(text, n).iter().all(|y| *y == 0.0), "{text}");
    }
}

#[test]
fn seeds_give_the_same_or_other_surfaces() {
    let n = 12_000;
    let a = render("(scrape 0.5 2 :seed 1)", n);
    assert_eq!(render("(scrape 0.5 2 :seed 1)", n), a);
    let b = render("(scrape 0.5 2 :seed 2)", n);
    assert!(a.iter().zip(&b).filter(|(x, y)| x != y).count() > n / 2);
    let r = render("(roll 0.5 2 :radius 0.01 :seed 1)", n);
    assert_eq!(render("(roll 0.5 2 :radius 0.01 :seed 1)", n), r);
    assert_ne!(render("(roll 0.5 2 :radius 0.01 :seed 2)", n), r);
}

#[test]
fn materials_by_name_are_their_constants() {
    let n = 12_000;
    let named = render("(roll 0.5 4 :radius 0.02 :a steel :b oak :seed 5)", n);
    let numbers = render(
        "(roll 0.5 4 :radius 0.02 :youngs 200e9 :poisson 0.29 \
         :youngs-b 12e9 :poisson-b 0.35 :seed 5)",
        n,
    );
    assert_eq!(named, numbers);
    // Steel on steel is the default.
    assert_eq!(
        render("(roll 0.5 4 :radius 0.02 :seed 5)", n),
        render("(roll 0.5 4 :radius 0.02 :a steel :b steel :seed 5)", n)
    );
    // A softer surface widens the patch: a duller force.
    assert_ne!(named, render("(roll 0.5 4 :radius 0.02 :seed 5)", n));
}

#[test]
fn contacts_print_back_as_their_constants_and_read_the_same() {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    for text in [
        "(scrape (* 0.5 t) 2 :period 0.001 :seed 9)",
        "(roll 0.3 (* 4 t) :radius 0.01 :a glass :b stone :grain 0.0005)",
    ] {
        let program = compile_str(text, &options).unwrap();
        let printed = timbre_lang::print_tree(&program.graph, program.root.unwrap(), &[]).unwrap();
        println!("{printed}");
        assert!(printed.contains(":seed-bits"), "{printed}");
        let again = render(&printed, 4800);
        assert_eq!(again, render(text, 4800));
        assert!(again.iter().any(|y| *y != 0.0));
    }
}

#[test]
fn bad_contacts_are_diagnosed_at_the_form() {
    let cases = [
        (
            "(scrape 0.3 2 :roughness -1e-6)",
            "timbre::bad-contact-force",
            "`scrape`: the surface's roughness must be 0 or more and finite, not -0.000001",
        ),
        (
            "(scrape 0.3 2 :grain 0)",
            "timbre::bad-contact-force",
            "`scrape`: the surface's grain must be above 0 and finite, not 0",
        ),
        (
            "(scrape 0.3 2 :period (/ 1 0))",
            "timbre::bad-contact-force",
            "`scrape`: the surface's period must be 0 (none) or more and finite, not inf",
        ),
        (
            "(scrape 0.3 2 :impacts -5)",
            "timbre::bad-contact-force",
            "`scrape`: the micro-impacts per metre must be 0 or more and finite, not -5",
        ),
        (
            "(roll 0.3 2 :radius -0.01)",
            "timbre::bad-contact-force",
            "`roll`: the rolling body's radius must be above 0 and finite, not -0.01",
        ),
        (
            "(roll 0.3 2 :radius (/ 1 0))",
            "timbre::bad-contact-force",
            "`roll`: the rolling body's radius must be above 0 and finite, not inf",
        ),
        (
            "(roll 0.3 2 :radius 0.01 :youngs-b 1e9 :poisson-b 0.7)",
            "timbre::bad-contact-force",
            "`roll`: the Poisson's ratio of the surface must be above −1 and at most 0.5, not 0.7",
        ),
        (
            "(roll 0.3 2 :radius 0.01 :a oak :b stel)",
            "timbre::unknown-material",
            "did you mean `steel`?",
        ),
        (
            "(roll 0.3 2 :radius 0.01 :a steel :youngs 1e9)",
            "timbre::duplicate-argument",
            "the material of body a is given twice",
        ),
        (
            "(scrape 0.3 2 :grain (* t 2))",
            "timbre::not-constant",
            "must be a constant number",
        ),
        (
            "(roll 0.3 2 :a steel :b oak)",
            "timbre::arity",
            "missing argument: radius",
        ),
        (
            "(scrape (vector 0.3 0.4) 2)",
            "timbre::width-mismatch",
            "the slip speed",
        ),
    ];
    for (text, code, message) in cases {
        let error = compile_error(text);
        assert!(error.contains(code), "{text}: {error}");
        assert!(error.contains(message), "{text}: {error}");
    }
}
