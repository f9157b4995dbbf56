//! Rewrites a tree into a faster one that renders the same sound within the engines'
//! tolerance (1e-5 of full scale). The reference interpreter renders trees as
//! written; compiled engines render them optimised. Every rewrite has a test that
//! compares the two.
//!
//! Rewrites:
//! - **Damped sines as rotators.** A product with factors `(sine (* τ F))` and
//!   optionally `(damp (* τ D))`, F and D constants (one lane or one per lane) and τ a
//!   time (`t`, or `t` shifted or wrapped: `(mod t 1)` re-strikes every second), is
//!   rewritten to `DampedSine(τ, F, D)` times the other factors: per lane a complex
//!   multiply per sample instead of a sine and an exponential. A lone
//!   `(sine (* τ F))` becomes `DampedSine(τ, F, 0)`. This is the modal tree's inner
//!   loop.

use std::sync::Arc;

use crate::dsp::rotator::DampedSine;
use crate::graph::{Graph, NodeId};
use crate::op::{BinaryOp, ImpulseResponse, Op, UnaryOp};

/// An optimised copy of what `root` needs of `graph`, and where `root` is in it.
pub fn optimise(graph: &Graph, root: NodeId) -> (Graph, NodeId) {
    let needed = reachable(graph, root);
    let mut out = Graph::new();
    let mut map: Vec<NodeId> = vec![NodeId(0); graph.len()];
    for (id, node) in graph.nodes() {
        if !needed[id.index()] {
            continue;
        }
        let new = match damped_sine(graph, &mut out, &map, id) {
            Some(rewritten) => rewritten,
            None => {
                let args = node.args.iter().map(|a| map[a.index()]).collect();
                let op = match &node.op {
                    Op::Conv(ImpulseResponse::Tree { root, seconds }) => {
                        Op::Conv(ImpulseResponse::Tree {
                            root: map[root.index()],
                            seconds: *seconds,
                        })
                    }
                    op => op.clone(),
                };
                out.add(op, args)
            }
        };
        map[id.index()] = new;
    }
    (out, map[root.index()])
}

/// The nodes `root` depends on, through arguments and impulse-response trees.
fn reachable(graph: &Graph, root: NodeId) -> Vec<bool> {
    let mut needed = vec![false; graph.len()];
    needed[root.index()] = true;
    // Children have smaller ids: one backwards sweep.
    for i in (0..=root.index()).rev() {
        if !needed[i] {
            continue;
        }
        let node = graph.node(NodeId(i as u32));
        for arg in &node.args {
            needed[arg.index()] = true;
        }
        if let Op::Conv(ImpulseResponse::Tree { root, .. }) = &node.op {
            needed[root.index()] = true;
        }
    }
    needed
}

/// Whether `id` is a time: a one-lane value that advances by one sample period per
/// sample except at occasional jumps (`t`, `(mod t 1)`, `(- t 0.5)`, `(frac t)` …).
fn is_time_like(graph: &Graph, id: NodeId) -> bool {
    let node = graph.node(id);
    match node.op {
        Op::Time => true,
        Op::Binary(BinaryOp::Mod | BinaryOp::Add | BinaryOp::Sub) => {
            is_time_like(graph, node.args[0]) && graph.scalar(node.args[1]).is_some()
        }
        Op::Unary(UnaryOp::Frac) => is_time_like(graph, node.args[0]),
        _ => false,
    }
}

/// If `id` is `τ·K` with τ time-like and K constant: τ and K (lane by lane).
fn linear_in_time(graph: &Graph, id: NodeId) -> Option<(NodeId, Vec<f64>)> {
    if is_time_like(graph, id) {
        return Some((id, vec![1.0]));
    }
    let node = graph.node(id);
    let Op::Binary(BinaryOp::Mul) = node.op else {
        return None;
    };
    let (a, b) = (node.args[0], node.args[1]);
    let ((time, k), c) = match (linear_in_time(graph, a), graph.const_value(b)) {
        (Some(lin), Some(c)) => (lin, c.to_vec()),
        _ => (linear_in_time(graph, b)?, graph.const_value(a)?.to_vec()),
    };
    Some((time, broadcast(&k, &c, |x, y| x * y)))
}

fn broadcast(a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    let width = a.len().max(b.len());
    let lane = |v: &[f64], l: usize| if v.len() == 1 { v[0] } else { v[l] };
    (0..width).map(|l| f(lane(a, l), lane(b, l))).collect()
}

/// The factors of a product: `(* (* a b) c)` has factors a, b, c.
fn factors(graph: &Graph, id: NodeId, into: &mut Vec<NodeId>) {
    let node = graph.node(id);
    if let Op::Binary(BinaryOp::Mul) = node.op {
        factors(graph, node.args[0], into);
        factors(graph, node.args[1], into);
    } else {
        into.push(id);
    }
}

/// τ and K if `id` is `(op (* τ K))`.
fn time_coefficient(graph: &Graph, id: NodeId, op: UnaryOp) -> Option<(NodeId, Vec<f64>)> {
    let node = graph.node(id);
    match node.op {
        Op::Unary(u) if u == op => linear_in_time(graph, node.args[0]),
        _ => None,
    }
}

fn damped_sine(graph: &Graph, out: &mut Graph, map: &[NodeId], id: NodeId) -> Option<NodeId> {
    let node = graph.node(id);
    let mut parts = vec![];
    match node.op {
        Op::Binary(BinaryOp::Mul) => factors(graph, id, &mut parts),
        Op::Unary(UnaryOp::Sine) => parts.push(id),
        _ => return None,
    }
    let sine = parts
        .iter()
        .position(|f| time_coefficient(graph, *f, UnaryOp::Sine).is_some())?;
    let (time, freq) = time_coefficient(graph, parts.remove(sine), UnaryOp::Sine)?;
    // A damping factor of the same time, if there is one.
    let same_time =
        |f: &NodeId| time_coefficient(graph, *f, UnaryOp::Damp).is_some_and(|(t, _)| t == time);
    let damping = match parts.iter().position(same_time) {
        Some(i) => time_coefficient(graph, parts.remove(i), UnaryOp::Damp)?.1,
        None => vec![0.0],
    };
    let freq = out.add(Op::Const(Arc::from(freq)), vec![]);
    let damping = out.add(Op::Const(Arc::from(damping)), vec![]);
    let damped_sine = Op::Stateful(Arc::new(DampedSine));
    let mut product = out.add(damped_sine, vec![map[time.index()], freq, damping]);
    for factor in parts {
        product = out.add(
            Op::Binary(BinaryOp::Mul),
            vec![product, map[factor.index()]],
        );
    }
    Some(product)
}
