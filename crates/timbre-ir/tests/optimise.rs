//! Each rewrite of `timbre_ir::optimise` renders what the tree as written renders,
//! within 1e-5 of full scale at every sample, and actually fires.

mod common;

use common::*;
use timbre_ir::optimise::optimise;
use timbre_ir::{Interpreter, RenderConfig};
use timbre_testkit::assert_close;

/// Renders `text` as written and optimised, asserts that the two agree within `tol`
/// at every sample, and returns the number of damped-sine nodes the optimiser made.
#[track_caller]
fn compare(text: &str, seconds: f64, tol: f64) -> usize {
    let program = compile_with(text, &[], 5).unwrap();
    let root = program.root.unwrap();
    let plain = render_program(&program, seconds, 64);
    let (graph, new_root) = optimise(&program.graph, root);
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 64,
    };
    let mut voice = Interpreter::new(&graph, new_root, config);
    let mut fast = vec![0.0; plain.len()];
    voice.render(&mut fast);
    let rotators = graph
        .schedule(new_root)
        .iter()
        .filter(|n| graph.node(**n).op.kind() == "damped-sine")
        .count();
    assert_close(
        &plain,
        &fast,
        tol,
        &format!("{text} as written vs optimised"),
    );
    rotators
}

#[test]
fn the_modal_tree_becomes_rotators() {
    let rotators = compare(
        "(* 0.01 (combine (* (sine (* t (rvector 100 200 8000))) (damp (* t 0.002 (rvector 100 200 8000))))))",
        3.0,
        1e-9,
    );
    assert_eq!(rotators, 1);
}

#[test]
fn factors_in_any_order_and_amplitudes_are_kept() {
    for text in [
        "(* (damp (* t 3)) 0.5 (sine (* 440 t)))",
        "(* (vector 0.2 0.3) (damp (* (vector 2 5) t)) (sine (* t (vector 300 500))) (+ 1 (* 0.1 (sine (* t 2)))))",
        "(combine (* (sine (* t 100 (iota 4))) (damp (* t 1))))",
    ] {
        let text = if text.starts_with("(combine") { text.to_string() } else { format!("(combine {text})") };
        let rotators = compare(&text, 1.0, 1e-9);
        assert!(rotators >= 1, "{text}: not rewritten");
    }
}

#[test]
fn undamped_sines_stay_exact_over_long_renders() {
    // Re-anchored every block: no drift after minutes of a high partial.
    // After 1.2 million cycles t·F itself is only exact to ~1e-10 cycles in the plain
    // tree, so the two agree to ~1e-9, far inside the 1e-5 the engines promise.
    let rotators = compare("(sine (* t 9876.5))", 120.0, 1e-7);
    assert_eq!(rotators, 1);
}

#[test]
fn sines_of_varying_phase_are_left_alone() {
    for text in [
        "(sine (* t (+ 440 (sine t))))",
        "(sine (phasor 440))",
        "(* (sine (* t 440)) (damp (sine t)))",
    ] {
        compare(text, 0.5, 1e-9);
    }
    // The first is not linear in t, the second has no t at all.
    assert_eq!(
        compare("(sine (* t (+ 440 (sine t))))", 0.1, 1e-9),
        1,
        "only the inner (sine t)"
    );
    assert_eq!(compare("(sine (phasor 440))", 0.1, 1e-9), 0);
}

#[test]
fn a_bell_re_struck_every_second_becomes_rotators() {
    let rotators = compare(
        "(let ((tau (mod t 1))) (* 0.01 (combine (* (sine (* tau (rvector 100 200 2000))) (damp (* tau 0.02 (rvector 100 200 2000)))))))",
        3.5,
        1e-9,
    );
    assert_eq!(rotators, 1);
    // A time shifted by a start, as a scene instance's is.
    let rotators = compare(
        "(* (sine (* (- t 0.25) 300)) (damp (* (- t 0.25) 3)))",
        1.0,
        1e-9,
    );
    assert_eq!(rotators, 1);
}

#[test]
fn a_damp_of_another_time_stays_a_separate_factor() {
    let rotators = compare("(* (sine (* t 300)) (damp (* (mod t 0.5) 3)))", 1.2, 1e-9);
    assert_eq!(rotators, 1);
}
