//! Each rewrite of `timbre_ir::optimise` renders what the tree as written renders,
//! within 1e-5 of full scale at every sample, and actually fires.

mod common;

use common::*;
use timbre_ir::optimise::optimise;
use timbre_ir::{Interpreter, RenderConfig};
use timbre_testkit::assert_close;

/// Renders `text` as written and optimised, asserts that the two agree within `tol`
/// at every sample, and returns the number of rotator nodes (damped sines and modal
/// banks) the optimiser made.
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
        .filter(|n| ["damped-sine", "modal-bank"].contains(&graph.node(**n).op.kind()))
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

/// Kinds of the optimised tree's nodes.
fn optimised_kinds(text: &str) -> Vec<&'static str> {
    let program = compile_with(text, &[], 5).unwrap();
    let (graph, root) = optimise(&program.graph, program.root.unwrap());
    graph
        .schedule(root)
        .iter()
        .map(|n| graph.node(*n).op.kind())
        .collect()
}

#[test]
fn a_sum_of_damped_sines_becomes_one_modal_bank() {
    // Constant amplitudes (per mode and overall) join the bank; a one-lane envelope,
    // the same for every mode, multiplies its sum.
    for text in [
        "(combine (* (sine (* t (rvector 100 200 8000))) (damp (* t 3))))",
        "(combine (* (rvector 8 0 1) 0.5 (sine (* (mod t 0.3) (rvector 8 200 800))) (damp (* (mod t 0.3) 0.01 (rvector 8 200 800)))))",
        "(combine (* (sine (* t (vector 300 500 700))) (vector 0.2 0.3 0.1) (- 1 (* 0.5 t)) (damp (* t 2))))",
    ] {
        assert_eq!(compare(text, 1.0, 1e-9), 1, "{text}");
        let kinds = optimised_kinds(text);
        assert!(kinds.contains(&"modal-bank"), "{text}: {kinds:?}");
        assert!(!kinds.contains(&"combine"), "{text}: {kinds:?}");
    }
    // A factor that differs between modes and is not constant stays a product.
    let text = "(combine (* (sine (* t (vector 300 500))) (vector t (* t t))))";
    compare(text, 0.5, 1e-9);
    let kinds = optimised_kinds(text);
    assert!(
        !kinds.contains(&"modal-bank") && kinds.contains(&"damped-sine"),
        "{kinds:?}"
    );
}

#[test]
fn a_vector_of_white_noises_becomes_one_noise_of_lanes() {
    let text = "(combine (* (iota 5) (vector (white :seed 7) (white :seed 3) (white :seed 9 :lanes 2) (white))))";
    // Exactly the same samples.
    compare(text, 0.2, 0.0);
    let kinds = optimised_kinds(text);
    assert_eq!(
        kinds.iter().filter(|k| **k == "white").count(),
        1,
        "{kinds:?}"
    );
    assert!(!kinds.contains(&"vector"), "{kinds:?}");
    // A vector of anything else stays as written.
    let kinds = optimised_kinds("(combine (vector (white :seed 7) (sine (* t 9))))");
    assert!(kinds.contains(&"vector"), "{kinds:?}");
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

// ------------------------------------------------------------- very deep graphs

use timbre_ir::op::{BinaryOp, Op, UnaryOp};
use timbre_ir::{Graph, NodeId};

/// Nodes in each deep chain: what a 1 KB file of doubling definitions builds.
const DEEP: usize = 1 << 20;

/// Optimises `root` of a deep graph (which must not overflow the stack) and renders a
/// few samples of both: they agree within `tolerance`. Returns the rotators made.
fn deep_agrees(graph: &Graph, root: NodeId, tolerance: f64) -> usize {
    assert!(graph.len() >= DEEP, "only {} nodes", graph.len());
    let (optimised, new_root) = optimise(graph, root);
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 16,
    };
    let render = |g: &Graph, r: NodeId| {
        let mut voice = Interpreter::new(g, r, config);
        let mut out = vec![0.0; 40];
        voice.render(&mut out);
        out
    };
    let (plain, fast) = (render(graph, root), render(&optimised, new_root));
    assert!(plain.iter().all(|x| x.is_finite()));
    assert!(plain.iter().any(|x| *x != 0.0), "a silent test");
    for (i, (a, b)) in plain.iter().zip(&fast).enumerate() {
        assert!(
            (a - b).abs() <= tolerance,
            "sample {i}: {a} as written, {b} optimised"
        );
    }
    optimised
        .schedule(new_root)
        .iter()
        .filter(|n| optimised.node(**n).op.kind() == "damped-sine")
        .count()
}

fn mul(g: &mut Graph, a: NodeId, k: f64) -> NodeId {
    let k = g.constant(k);
    g.add(Op::Binary(BinaryOp::Mul), vec![a, k])
}

fn sine(g: &mut Graph, a: NodeId) -> NodeId {
    g.add(Op::Unary(UnaryOp::Sine), vec![a])
}

#[test]
fn a_chain_of_a_million_sines_and_products_is_optimised_without_recursion() {
    // x ← (sine (* t 1.0001)), then x ← (* x 0.1), x ← (sine (+ x 0.25)) alternately: a
    // contraction (|d/dx| ≤ 0.2π), so rounding differences die out along the chain.
    let mut g = Graph::new();
    let t = g.add(Op::Time, vec![]);
    let f = mul(&mut g, t, 1.0001);
    let mut x = sine(&mut g, f);
    let quarter = g.constant(0.25);
    while g.len() < DEEP {
        x = mul(&mut g, x, 0.1);
        x = g.add(Op::Binary(BinaryOp::Add), vec![x, quarter]);
        x = sine(&mut g, x);
    }
    // The first sine is a rotator; the others read a sine.
    assert_eq!(deep_agrees(&g, x, 1e-9), 1);
}

#[test]
fn a_product_of_a_million_factors_is_kept_as_written() {
    // (* (* (* (sine (* t 440)) k) k′) …): too many factors to flatten at the top.
    let mut g = Graph::new();
    let t = g.add(Op::Time, vec![]);
    let f = mul(&mut g, t, 440.0);
    let mut p = sine(&mut g, f);
    let mut i = 0;
    while g.len() < DEEP {
        p = mul(
            &mut g,
            p,
            if i % 2 == 0 { 1.000_000_1 } else { 0.999_999_9 },
        );
        i += 1;
    }
    assert_eq!(deep_agrees(&g, p, 1e-9), 1);
}

#[test]
fn a_time_shifted_a_million_times_is_still_a_time() {
    // τ = t + c − c + c − … : time-like through a million additions.
    let mut g = Graph::new();
    let mut tau = g.add(Op::Time, vec![]);
    let c = g.constant(1e-9);
    while g.len() < DEEP {
        tau = g.add(Op::Binary(BinaryOp::Add), vec![tau, c]);
        tau = g.add(Op::Binary(BinaryOp::Sub), vec![tau, c]);
    }
    let f = mul(&mut g, tau, 440.0);
    let root = sine(&mut g, f);
    assert_eq!(deep_agrees(&g, root, 1e-9), 1);
}

#[test]
fn a_time_scaled_a_million_times_is_still_linear_in_time() {
    // (* (* (* t k) 1/k) …) 440: linear in time through a million products.
    let mut g = Graph::new();
    let mut x = g.add(Op::Time, vec![]);
    let mut i = 0;
    while g.len() < DEEP {
        x = mul(&mut g, x, if i % 2 == 0 { 1.0001 } else { 1.0 / 1.0001 });
        i += 1;
    }
    let f = mul(&mut g, x, 440.0);
    let root = sine(&mut g, f);
    assert_eq!(deep_agrees(&g, root, 1e-9), 1);
}
