//! `tube-modes`: the modal frequencies of a hollow tube (Hahn et al. 1995, after
//! Fletcher and Rossing). The lanes are the formula's, computed here independently;
//! a rendered chime has its spectral peaks at them; bad tubes are diagnostics with
//! exact codes, messages and spans.

mod common;

use std::f64::consts::PI;

use common::{compile_with, constant, render, SR};
use timbre_testkit::{spectral_peaks, strongest_peak_in};

/// The formula, written out: (π K / (8 L²)) · √(E/ρ) · m², K = √(d_o² + d_i²)/4,
/// m = 3.011, 5, 7, 9, …
fn expected(n: usize, length: f64, outer: f64, inner: f64, youngs: f64, density: f64) -> Vec<f64> {
    let k = (outer * outer + inner * inner).sqrt() / 4.0;
    let factor = PI * k / (8.0 * length * length) * (youngs / density).sqrt();
    (1..=n)
        .map(|i| {
            let m = if i == 1 { 3.011 } else { (2 * i + 1) as f64 };
            factor * m * m
        })
        .collect()
}

/// The lanes of a call of `tube-modes` that folds to a constant: lane by lane, with
/// `index` (a sound must be one lane).
fn lanes(call: &str, bindings: &[(&str, f64)]) -> Vec<f64> {
    let n = constant(&format!("(lanes {call})"), bindings, 0) as usize;
    (0..n)
        .map(|i| constant(&format!("(index {call} {i})"), bindings, 0))
        .collect()
}

fn assert_within(measured: &[f64], expected: &[f64], relative: f64, what: &str) {
    assert_eq!(measured.len(), expected.len(), "{what}");
    for (k, (m, e)) in measured.iter().zip(expected).enumerate() {
        assert!(
            ((m - e) / e).abs() <= relative,
            "{what}: mode {} is {m} Hz, expected {e} Hz",
            k + 1
        );
    }
}

#[test]
fn lanes_follow_the_formula() {
    // Aluminium by default: E = 69 GPa, ρ = 2700 kg/m³.
    let chime = lanes("(tube-modes 5 0.3 0.025 0.022)", &[]);
    assert_within(
        &chime,
        &expected(5, 0.3, 0.025, 0.022, 69e9, 2700.0),
        1e-3,
        "aluminium",
    );
    // About 1665 Hz, 4590 Hz, 9000 Hz, …: a small chime.
    assert!((chime[0] - 1665.0).abs() < 2.0, "{chime:?}");

    // The ratios are the paper's, whatever the tube.
    let m1 = 3.011f64 * 3.011;
    for (r, want) in [(1, 25.0 / m1), (2, 49.0 / m1), (3, 81.0 / m1)] {
        let ratio = chime[r] / chime[0];
        assert!(
            ((ratio - want) / want).abs() < 1e-3,
            "f{}/f1 = {ratio}",
            r + 1
        );
    }

    // Other materials and tubes, by keyword and by position, and a solid rod.
    let cases = [
        (
            "(tube-modes 3 0.5 0.03 0.026 :youngs 200e9 :density 7850)",
            [3.0, 0.5, 0.03, 0.026, 200e9, 7850.0],
        ),
        (
            "(tube-modes 4 0.8 0.04 0.034 100e9 8500)",
            [4.0, 0.8, 0.04, 0.034, 100e9, 8500.0],
        ),
        (
            "(tube-modes :inner 0.05 :outer 0.06 :n 2 :length 1.2 :density 700 :youngs 18e9)",
            [2.0, 1.2, 0.06, 0.05, 18e9, 700.0],
        ),
        (
            "(tube-modes 6 0.2 0.01 0)",
            [6.0, 0.2, 0.01, 0.0, 69e9, 2700.0],
        ),
        (
            "(tube-modes 1 (* 2 0.25) (/ 1 40) 0.02)",
            [1.0, 0.5, 0.025, 0.02, 69e9, 2700.0],
        ),
    ];
    for (call, [n, l, o, i, e, rho]) in cases {
        let got = lanes(call, &[]);
        assert_within(&got, &expected(n as usize, l, o, i, e, rho), 1e-3, call);
    }

    // Parameters bound with --set fold like numbers.
    let bound = lanes("(tube-modes 3 len 0.025 0.022)", &[("len", 0.4)]);
    assert_within(
        &bound,
        &expected(3, 0.4, 0.025, 0.022, 69e9, 2700.0),
        1e-3,
        "--set",
    );
}

#[test]
fn the_node_is_a_constant_vector() {
    let program = compile_with("(combine (tube-modes 7 0.3 0.025 0.022))", &[], 0).unwrap();
    let root = program.root.unwrap();
    let sum = program.graph.scalar(root).expect("folded to a constant");
    let want: f64 = expected(7, 0.3, 0.025, 0.022, 69e9, 2700.0).iter().sum();
    assert!((sum - want).abs() < 1e-9 * want, "{sum} against {want}");
}

#[test]
fn the_material_table_of_nodes_md_is_the_rust_one() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../lang-spec/nodes.md");
    let doc = std::fs::read_to_string(path).unwrap();
    for material in timbre_ir::dsp::tube::MATERIALS {
        let row = doc
            .lines()
            .find(|l| l.starts_with(&format!("| {}", material.name)))
            .unwrap_or_else(|| panic!("nodes.md has no row for {}", material.name));
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let number = |cell: &str| cell.trim_matches('`').parse::<f64>().unwrap();
        assert_eq!(number(cells[2]), material.youngs, "{row}");
        assert_eq!(number(cells[3]), material.density, "{row}");
        assert_eq!(number(cells[4]), material.bar_speed().round(), "{row}");
        // And each is what `:youngs` and `:density` give.
        let call = format!(
            "(tube-modes 2 0.3 0.025 0.022 :youngs {} :density {})",
            cells[2].trim_matches('`'),
            cells[3].trim_matches('`')
        );
        let want = expected(2, 0.3, 0.025, 0.022, material.youngs, material.density);
        assert_within(&lanes(&call, &[]), &want, 1e-12, &call);
    }
    // The default is aluminium.
    let default = lanes("(tube-modes 2 0.3 0.025 0.022)", &[]);
    let aluminium = lanes(
        "(tube-modes 2 0.3 0.025 0.022 :youngs 69e9 :density 2700)",
        &[],
    );
    assert_eq!(default, aluminium);
}

/// The catalogue's example: five modes of a 0.3 m aluminium tube, struck.
const CHIME: &str =
    "(* 0.1 (combine (* (sine (* t (tube-modes 5 0.3 0.025 0.022))) (damp (* t 3)))))";

#[test]
fn a_rendered_chime_rings_at_its_modes() {
    let example = timbre_lang::catalogue::lookup("tube-modes")
        .unwrap()
        .example;
    assert_eq!(example, CHIME);
    let out = render(CHIME, &[], 1.0);
    assert_eq!(out.len(), 48_000);
    assert!(out.iter().all(|y| y.is_finite()));
    let modes = expected(5, 0.3, 0.025, 0.022, 69e9, 2700.0);
    assert!(modes[4] < SR / 2.0, "every mode below Nyquist: {modes:?}");

    // The five strongest peaks of the whole spectrum are the five modes.
    let mut peaks = spectral_peaks(&out, SR, 5);
    peaks.sort_by(f64::total_cmp);
    let errors: Vec<f64> = peaks
        .iter()
        .zip(&modes)
        .map(|(p, m)| 100.0 * (p - m) / m)
        .collect();
    println!("modes {modes:?}\npeaks {peaks:?}\nerrors (%) {errors:?}");
    assert_within(&peaks, &modes, 0.005, "the five strongest peaks");

    // And each mode is the strongest peak within ±5 % of itself.
    for m in &modes {
        let peak = strongest_peak_in(&out, SR, 0.95 * m, 1.05 * m);
        assert!(
            ((peak - m) / m).abs() <= 0.005,
            "{peak} Hz for the mode at {m} Hz"
        );
    }
}

#[test]
fn a_steel_rod_rings_at_its_modes() {
    // A solid steel rod of 12 mm, 0.4 m long: its first two modes.
    let tree = "(* 0.2 (combine (* (sine (* t (tube-modes 2 0.4 0.012 0 :youngs 200e9 :density 7850))) (damp (* t 4)))))";
    let out = render(tree, &[], 1.0);
    let modes = expected(2, 0.4, 0.012, 0.0, 200e9, 7850.0);
    let mut peaks = spectral_peaks(&out, SR, 2);
    peaks.sort_by(f64::total_cmp);
    println!("steel rod: modes {modes:?}, peaks {peaks:?}");
    assert_within(&peaks, &modes, 0.005, "steel rod");
}

/// (source, code, message, underlined text, help)
const BAD: &[(&str, &str, &str, &str, &str)] = &[
    (
        "(combine (tube-modes 2.5 0.3 0.025 0.022))",
        "timbre::bad-count",
        "the number of modes must be a whole number ≥ 1, not 2.5",
        "2.5",
        "write e.g. 50",
    ),
    (
        "(combine (tube-modes 0 0.3 0.025 0.022))",
        "timbre::bad-count",
        "the number of modes must be a whole number ≥ 1, not 0",
        "0",
        "write e.g. 50",
    ),
    (
        "(combine (tube-modes 70000 0.3 0.025 0.022))",
        "timbre::too-wide",
        "70000 lanes is too many",
        "70000",
        "a node may have at most 65536 lanes",
    ),
    (
        "(combine (tube-modes 5 (+ 0.3 t) 0.025 0.022))",
        "timbre::not-constant",
        "the tube's length must be a constant number",
        "(+ 0.3 t)",
        "use a number, or an expression of numbers and bound parameters",
    ),
    (
        "(combine (tube-modes 5 0.3 0.025 0.022 :youngs (sine t)))",
        "timbre::not-constant",
        "Young's modulus must be a constant number",
        "(sine t)",
        "use a number, or an expression of numbers and bound parameters",
    ),
    (
        "(combine (tube-modes 5 (vector 0.3 0.4) 0.025 0.022))",
        "timbre::width-mismatch",
        "the tube's length must be one lane, not 2",
        "(vector 0.3 0.4)",
        "pick one lane with (index …) or sum them with (combine …)",
    ),
    (
        "(combine (tube-modes 5 0 0.025 0.022))",
        "timbre::bad-tube",
        "the tube's length must be above 0, not 0",
        "0",
        "lengths and diameters are in metres: (tube-modes 5 0.3 0.025 0.022)",
    ),
    (
        "(combine (tube-modes 5 0.3 -0.025 0.022))",
        "timbre::bad-tube",
        "the tube's outer diameter must be above 0, not -0.025",
        "-0.025",
        "lengths and diameters are in metres: (tube-modes 5 0.3 0.025 0.022)",
    ),
    (
        "(combine (tube-modes 5 0.3 0.025 -0.01))",
        "timbre::bad-tube",
        "the tube's inner diameter must be 0 (a solid rod) or more, not -0.01",
        "-0.01",
        "lengths and diameters are in metres: (tube-modes 5 0.3 0.025 0.022)",
    ),
    (
        "(combine (tube-modes 5 0.3 0.022 0.025))",
        "timbre::bad-tube",
        "the tube's inner diameter 0.025 m is not less than its outer diameter 0.022 m",
        "0.025",
        "the inner diameter is the bore: less than the outer one, or 0 for a solid rod",
    ),
    (
        "(combine (tube-modes 5 0.3 0.025 0.0250))",
        "timbre::bad-tube",
        "the tube's inner diameter 0.025 m is not less than its outer diameter 0.025 m",
        "0.0250",
        "the inner diameter is the bore: less than the outer one, or 0 for a solid rod",
    ),
    (
        "(combine (tube-modes 5 0.3 0.025 0.022 :youngs 0))",
        "timbre::bad-tube",
        "Young's modulus must be above 0, not 0",
        "0",
        "Young's modulus is in pascals and the density in kg/m³: aluminium is :youngs 69e9 :density 2700",
    ),
    (
        "(combine (tube-modes 5 0.3 0.025 0.022 :density -2700))",
        "timbre::bad-tube",
        "the density must be above 0, not -2700",
        "-2700",
        "Young's modulus is in pascals and the density in kg/m³: aluminium is :youngs 69e9 :density 2700",
    ),
    (
        "(combine (tube-modes 5 1e-160 0.025 0.022 :youngs 1e300))",
        "timbre::bad-tube",
        "the tube's mode 1 is inf Hz: the quantities are out of range",
        "(tube-modes 5 1e-160 0.025 0.022 :youngs 1e300)",
        "lengths and diameters are in metres: (tube-modes 5 0.3 0.025 0.022); \
         Young's modulus is in pascals and the density in kg/m³: aluminium is :youngs 69e9 :density 2700",
    ),
];

#[test]
fn bad_tubes_give_exact_diagnostics() {
    let mut failures = vec![];
    for (source, code, message, underlined, help) in BAD {
        let diags = match compile_with(source, &[], 0) {
            Ok(_) => {
                failures.push(format!("{source:?}: compiled without error"));
                continue;
            }
            Err(d) => d,
        };
        assert_eq!(diags.0.len(), 1, "{source:?}: one cause, one diagnostic");
        let first = &diags.0[0];
        let span = first.span().expect("every diagnostic points somewhere");
        let actual = &source[span.start..span.end];
        if first.code != *code
            || first.message != *message
            || actual != *underlined
            || first.help.as_deref() != Some(*help)
        {
            failures.push(format!(
                "{source:?}: got {} / {:?} at {actual:?} / {:?}\n  expected {code} / {message:?} at {underlined:?} / {help:?}",
                first.code, first.message, first.help
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn an_inner_diameter_not_below_the_outer_points_at_both() {
    let source = "(combine (tube-modes 5 0.3 0.022 0.025))";
    let diags = compile_with(source, &[], 0).unwrap_err();
    let labels: Vec<(&str, &str)> = diags.0[0]
        .labels
        .iter()
        .map(|(span, text)| (&source[span.start..span.end], text.as_str()))
        .collect();
    assert_eq!(
        labels,
        [
            ("0.025", "the inner diameter"),
            ("0.022", "the outer diameter")
        ]
    );
}

#[test]
fn a_material_by_name_is_its_table_row() {
    for material in timbre_ir::dsp::tube::MATERIALS {
        let named = lanes(
            &format!("(tube-modes 3 0.4 0.03 0.026 :material {})", material.name),
            &[],
        );
        let expected_modes = expected(3, 0.4, 0.03, 0.026, material.youngs, material.density);
        assert_within(&named, &expected_modes, 1e-12, material.name);
    }
    let error = |source: &str| {
        let diags = compile_with(source, &[], 0).unwrap_err();
        let first = &diags.0[0];
        let span = first.span().unwrap();
        (
            first.code.to_string(),
            first.message.clone(),
            source[span.start..span.end].to_owned(),
            first.help.clone().unwrap_or_default(),
        )
    };
    assert_eq!(
        error("(combine (tube-modes 3 0.4 0.03 0.026 :material gold))"),
        (
            "timbre::bad-tube".to_owned(),
            "unknown material `gold`".to_owned(),
            "gold".to_owned(),
            "the materials are aluminium, steel, brass, bamboo; or give :youngs and :density"
                .to_owned()
        )
    );
    let (code, message, at, _) =
        error("(combine (tube-modes 3 0.4 0.03 0.026 :material steel :density 7800))");
    assert_eq!(
        (code.as_str(), message.as_str(), at.as_str()),
        (
            "timbre::duplicate-argument",
            "the material is given twice",
            "steel"
        )
    );
}
