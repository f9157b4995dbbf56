//! An instance's start costs the size of its own tree, not of the scene's graph: a
//! scene of thousands of instances holds them all in one graph, and each start
//! optimises its instance's tree for the compiled engine.

use std::sync::Arc;
use timbre_ir::op::{BinaryOp, Op, UnaryOp};
use timbre_ir::optimise::optimise;
use timbre_ir::{dump, Graph, NodeId};
use timbre_testkit::heap;

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

/// `(combine (* (sine (* t modes)) (damp (* t rates))))`, a modal instance's tree.
fn modal(graph: &mut Graph, base: f64) -> NodeId {
    let constant =
        |graph: &mut Graph, values: Vec<f64>| graph.add(Op::Const(Arc::from(values)), vec![]);
    let t = graph.add(Op::Time, vec![]);
    let modes = constant(graph, (1..=10).map(|k| base * k as f64).collect());
    let rates = constant(graph, (1..=10).map(|k| 0.05 * base * k as f64).collect());
    let phase = graph.add(Op::Binary(BinaryOp::Mul), vec![t, modes]);
    let sine = graph.add(Op::Unary(UnaryOp::Sine), vec![phase]);
    let decay = graph.add(Op::Binary(BinaryOp::Mul), vec![t, rates]);
    let damp = graph.add(Op::Unary(UnaryOp::Damp), vec![decay]);
    let product = graph.add(Op::Binary(BinaryOp::Mul), vec![sine, damp]);
    graph.add(Op::Combine, vec![product])
}

#[test]
fn optimising_an_instance_costs_its_own_tree_not_the_scene_s() {
    // The instance's tree alone, and after 25 000 other instances (200 000 nodes;
    // none shares a constant with it, so its nodes come in the same order).
    let mut alone = Graph::new();
    let root_alone = modal(&mut alone, 300.0);
    let mut scene = Graph::new();
    for k in 0..25_000 {
        modal(&mut scene, 10_000.0 + k as f64);
    }
    assert!(scene.len() > 150_000, "{} nodes", scene.len());
    let root = modal(&mut scene, 300.0);

    let before = heap::allocated_bytes();
    let (optimised, new_root) = optimise(&scene, root);
    let allocated = heap::allocated_bytes() - before;
    // The same tree as optimising it alone: one modal bank.
    let (expected, expected_root) = optimise(&alone, root_alone);
    assert_eq!(
        dump(&optimised, &[new_root]),
        dump(&expected, &[expected_root])
    );
    assert!(dump(&optimised, &[new_root]).contains("modal-bank"));
    // A pass over the scene's graph would allocate a few bytes a node (over a
    // megabyte here); the tree's own is some kilobytes.
    assert!(allocated < 64 << 10, "{allocated} bytes allocated");
}
