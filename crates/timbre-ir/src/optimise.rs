//! Rewrites a tree into a faster one that renders the same sound within the engines'
//! tolerance (1e-5 of full scale). The reference interpreter renders trees as
//! written; compiled engines render them optimised. Every rewrite has a test that
//! compares the two.
//!
//! Rewrites:
//! - **Damped sines as rotators.** A product with factors `(sine (* t F))` and
//!   optionally `(damp (* t D))`, F and D constants (one lane or one per lane), is
//!   rewritten to `DampedSine(F, D)` times the other factors: per lane a complex
//!   multiply per sample instead of a sine and an exponential. A lone
//!   `(sine (* t F))` becomes `DampedSine(F, 0)`. This is the modal tree's inner loop.

use std::sync::Arc;

use crate::graph::{Graph, NodeId};
use crate::op::{BinaryOp, ImpulseResponse, Op, UnaryOp};

/// An optimised copy of `graph`, and where `root` is in it.
pub fn optimise(graph: &Graph, root: NodeId) -> (Graph, NodeId) {
    let mut out = Graph::new();
    let mut map: Vec<NodeId> = Vec::with_capacity(graph.len());
    for (id, node) in graph.nodes() {
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
        map.push(new);
    }
    (out, map[root.index()])
}

/// If `id` is `t·K` with K constant, K (lane by lane).
fn linear_in_t(graph: &Graph, id: NodeId) -> Option<Vec<f64>> {
    let node = graph.node(id);
    match node.op {
        Op::Time => Some(vec![1.0]),
        Op::Binary(BinaryOp::Mul) => {
            let (a, b) = (node.args[0], node.args[1]);
            let (k, c) = match (linear_in_t(graph, a), graph.const_value(b)) {
                (Some(k), Some(c)) => (k, c.to_vec()),
                _ => (linear_in_t(graph, b)?, graph.const_value(a)?.to_vec()),
            };
            Some(broadcast(&k, &c, |x, y| x * y))
        }
        _ => None,
    }
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

/// The argument's t-coefficient if `id` is `(op (* t K))`.
fn coefficient_of(graph: &Graph, id: NodeId, op: UnaryOp) -> Option<Vec<f64>> {
    let node = graph.node(id);
    match node.op {
        Op::Unary(u) if u == op => linear_in_t(graph, node.args[0]),
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
        .position(|f| coefficient_of(graph, *f, UnaryOp::Sine).is_some())?;
    let freq = coefficient_of(graph, parts.remove(sine), UnaryOp::Sine)?;
    let damping = match parts
        .iter()
        .position(|f| coefficient_of(graph, *f, UnaryOp::Damp).is_some())
    {
        Some(i) => coefficient_of(graph, parts.remove(i), UnaryOp::Damp)?,
        None => vec![0.0],
    };
    let freq = out.add(Op::Const(Arc::from(freq)), vec![]);
    let damping = out.add(Op::Const(Arc::from(damping)), vec![]);
    let mut product = out.add(Op::DampedSine, vec![freq, damping]);
    for factor in parts {
        product = out.add(
            Op::Binary(BinaryOp::Mul),
            vec![product, map[factor.index()]],
        );
    }
    Some(product)
}
