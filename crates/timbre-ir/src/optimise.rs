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
//! - **Modal banks.** `(combine P)` where P is such a product whose other factors are
//!   constants or one-lane values is rewritten to `ModalBank(τ, F, D, A)` times the
//!   one-lane factors, A the product of the constants: the sum Σ A·sin(2π·F·τ)·e^(−D·τ)
//!   as one node, which the JIT compiles to a kernel of its own (the one-lane factors
//!   are the same for every mode, so they multiply the sum).
//! - **Vectors of white noises.** `(vector (white :seed 1) (white :seed 2) …)` is one
//!   white noise of n lanes, each hashing its own seed: one node, which the JIT
//!   computes inline across lanes, instead of n one-lane noises gathered by a vector.
//!
//! Every analysis is a single pass in id order (a node's arguments have smaller ids),
//! each node's facts computed from its arguments' facts, so the passes use no
//! recursion, whatever the graph's depth (a 1 KB file can build a chain of millions of
//! nodes). A product is split into its factors only if it has at most
//! [`MAX_FACTORS`] of them (a product of shared products has exponentially many);
//! larger products are kept as written, so the time taken is at most linear in the
//! graph's size times [`MAX_FACTORS`].

use std::sync::Arc;

use crate::dsp::rotator::{DampedSine, ModalBank};
use crate::graph::{Graph, NodeId};
use crate::op::{BinaryOp, Op, UnaryOp};

/// Products with more factors than this (counting a shared factor each time it occurs)
/// are not rewritten: flattening them would copy the shared parts.
pub const MAX_FACTORS: usize = 64;

/// An optimised copy of what `root` needs of `graph`, and where `root` is in it.
pub fn optimise(graph: &Graph, root: NodeId) -> (Graph, NodeId) {
    // What `root` needs first, on its own: the passes below go over every node of
    // the graph they are given, and a scene's holds every instance.
    let (graph, root) = &graph.subgraph(root);
    let facts = Facts::new(graph);
    let mut out = Graph::new();
    let mut map: Vec<NodeId> = vec![NodeId(0); graph.len()];
    let mut parts = vec![];
    for (id, node) in graph.nodes() {
        let rewritten = match node.op {
            Op::Combine => facts.modal_bank(graph, &mut out, &map, node.args[0], &mut parts),
            Op::Concat => white_lanes(graph, &node.args).map(|op| out.add(op, vec![])),
            _ => facts.damped_sine(graph, &mut out, &map, id, &mut parts),
        };
        let new = rewritten.unwrap_or_else(|| out.copy_node(node, |a| map[a.index()]));
        map[id.index()] = new;
    }
    (out, map[root.index()])
}

/// What the rewrites need to know of each node, computed in one pass in id
/// order from the facts of its arguments.
struct Facts {
    /// Whether the node is a time: a one-lane value that advances by one sample period
    /// per sample except at occasional jumps (`t`, `(mod t 1)`, `(- t 0.5)`,
    /// `(frac t)` …).
    time_like: Vec<bool>,
    /// If the node is `τ·K` with τ time-like and K constant: an index into `linear`.
    linear_of: Vec<Option<u32>>,
    /// τ and K (lane by lane) of the nodes that are linear in time.
    linear: Vec<(NodeId, Vec<f64>)>,
    /// Factors of the node as a product (1 if it is not a multiplication), counted up
    /// to `MAX_FACTORS + 1`.
    factor_count: Vec<u32>,
    /// Whether the node is a product with a factor `(sine (* τ F))` (or is one).
    has_sine: Vec<bool>,
}

impl Facts {
    fn new(graph: &Graph) -> Self {
        let n = graph.len();
        let mut facts = Facts {
            time_like: vec![false; n],
            linear_of: vec![None; n],
            linear: vec![],
            factor_count: vec![1; n],
            has_sine: vec![false; n],
        };
        let cap = MAX_FACTORS as u32 + 1;
        for (id, node) in graph.nodes() {
            let i = id.index();
            let arg = |k: usize| node.args[k].index();
            facts.time_like[i] = match node.op {
                Op::Time => true,
                Op::Binary(BinaryOp::Mod | BinaryOp::Add | BinaryOp::Sub) => {
                    facts.time_like[arg(0)] && graph.scalar(node.args[1]).is_some()
                }
                Op::Unary(UnaryOp::Frac) => facts.time_like[arg(0)],
                _ => false,
            };
            let linear = if facts.time_like[i] {
                Some((id, vec![1.0]))
            } else if let Op::Binary(BinaryOp::Mul) = node.op {
                let (a, b) = (node.args[0], node.args[1]);
                let found = match (facts.linear_in_time(a), graph.const_value(b)) {
                    (Some(lin), Some(c)) => Some((lin, c)),
                    _ => facts.linear_in_time(b).zip(graph.const_value(a)),
                };
                found.map(|((time, k), c)| (time, broadcast(k, c, |x, y| x * y)))
            } else {
                None
            };
            if let Some(linear) = linear {
                facts.linear_of[i] = Some(facts.linear.len() as u32);
                facts.linear.push(linear);
            }
            if let Op::Binary(BinaryOp::Mul) = node.op {
                facts.factor_count[i] =
                    (facts.factor_count[arg(0)] + facts.factor_count[arg(1)]).min(cap);
                facts.has_sine[i] = facts.has_sine[arg(0)] || facts.has_sine[arg(1)];
            } else {
                facts.has_sine[i] = facts.time_coefficient(graph, id, UnaryOp::Sine).is_some();
            }
        }
        facts
    }

    /// τ and K if `id` is `τ·K` with τ time-like and K constant.
    fn linear_in_time(&self, id: NodeId) -> Option<(NodeId, &[f64])> {
        let (time, k) = &self.linear[self.linear_of[id.index()]? as usize];
        Some((*time, k))
    }

    /// τ and K if `id` is `(op (* τ K))`.
    fn time_coefficient(&self, graph: &Graph, id: NodeId, op: UnaryOp) -> Option<(NodeId, &[f64])> {
        let node = graph.node(id);
        match node.op {
            Op::Unary(u) if u == op => self.linear_in_time(node.args[0]),
            _ => None,
        }
    }

    /// Takes the factor `(sine (* τ F))` out of a product's factors, and a factor
    /// `(damp (* τ D))` of the same τ if there is one: τ, F and D (0 if undamped).
    fn take_damped_sine(
        &self,
        graph: &Graph,
        parts: &mut Vec<NodeId>,
    ) -> Option<(NodeId, Vec<f64>, Vec<f64>)> {
        let sine = parts
            .iter()
            .position(|f| self.time_coefficient(graph, *f, UnaryOp::Sine).is_some())?;
        let (time, freq) = self.time_coefficient(graph, parts.remove(sine), UnaryOp::Sine)?;
        let same_time = |f: &NodeId| {
            self.time_coefficient(graph, *f, UnaryOp::Damp)
                .is_some_and(|(t, _)| t == time)
        };
        let damping = match parts.iter().position(same_time) {
            Some(i) => self
                .time_coefficient(graph, parts.remove(i), UnaryOp::Damp)?
                .1
                .to_vec(),
            None => vec![0.0],
        };
        Some((time, freq.to_vec(), damping))
    }

    /// The factors of `id` if it is a product with a factor `(sine (* τ F))` of at
    /// most [`MAX_FACTORS`] factors, or such a sine alone.
    fn damped_sine_factors(&self, graph: &Graph, id: NodeId, parts: &mut Vec<NodeId>) -> bool {
        if !self.has_sine[id.index()] || self.factor_count[id.index()] as usize > MAX_FACTORS {
            return false;
        }
        factors(graph, id, parts);
        true
    }

    /// `id` rewritten with a rotator, if it is a product with a factor
    /// `(sine (* τ F))` of at most [`MAX_FACTORS`] factors, or such a sine alone.
    fn damped_sine(
        &self,
        graph: &Graph,
        out: &mut Graph,
        map: &[NodeId],
        id: NodeId,
        parts: &mut Vec<NodeId>,
    ) -> Option<NodeId> {
        if !self.damped_sine_factors(graph, id, parts) {
            return None;
        }
        let (time, freq, damping) = self.take_damped_sine(graph, parts)?;
        let freq = out.add(Op::Const(Arc::from(freq)), vec![]);
        let damping = out.add(Op::Const(Arc::from(damping)), vec![]);
        let damped_sine = Op::Stateful(Arc::new(DampedSine));
        let product = out.add(damped_sine, vec![map[time.index()], freq, damping]);
        Some(times(out, map, product, parts.drain(..)))
    }

    /// `(combine summed)` rewritten as a modal bank, if `summed` is a damped-sine
    /// product whose other factors are constants or one lane wide.
    fn modal_bank(
        &self,
        graph: &Graph,
        out: &mut Graph,
        map: &[NodeId],
        summed: NodeId,
        parts: &mut Vec<NodeId>,
    ) -> Option<NodeId> {
        if !self.damped_sine_factors(graph, summed, parts) {
            return None;
        }
        let (time, freq, damping) = self.take_damped_sine(graph, parts)?;
        let mut amplitude = vec![1.0];
        let mut common = vec![];
        for &factor in parts.iter() {
            if let Some(c) = graph.const_value(factor) {
                amplitude = broadcast(&amplitude, c, |x, y| x * y);
            } else if graph.width(factor) == 1 {
                common.push(factor);
            } else {
                return None;
            }
        }
        let [freq, damping, amplitude] =
            [freq, damping, amplitude].map(|v| out.add(Op::Const(Arc::from(v)), vec![]));
        let bank = Op::Stateful(Arc::new(ModalBank));
        let product = out.add(bank, vec![map[time.index()], freq, damping, amplitude]);
        Some(times(out, map, product, common))
    }
}

/// `product` times each of `factors` (nodes of the original graph, mapped into `out`).
fn times(
    out: &mut Graph,
    map: &[NodeId],
    product: NodeId,
    factors: impl IntoIterator<Item = NodeId>,
) -> NodeId {
    factors.into_iter().fold(product, |product, factor| {
        out.add(
            Op::Binary(BinaryOp::Mul),
            vec![product, map[factor.index()]],
        )
    })
}

/// One white noise of many lanes, each with its own seed, if `args` are all white
/// noises.
fn white_lanes(graph: &Graph, args: &[NodeId]) -> Option<Op> {
    let mut seeds = vec![];
    for a in args {
        match &graph.node(*a).op {
            Op::White { seeds: more } => seeds.extend_from_slice(more),
            _ => return None,
        }
    }
    Some(Op::White {
        seeds: Arc::from(seeds),
    })
}

fn broadcast(a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    let width = a.len().max(b.len());
    let lane = |v: &[f64], l: usize| if v.len() == 1 { v[0] } else { v[l] };
    (0..width).map(|l| f(lane(a, l), lane(b, l))).collect()
}

/// The factors of a product, left to right, into `into` (cleared first): `(* (* a b)
/// c)` has factors a, b, c. Iterative; the caller bounds the count.
fn factors(graph: &Graph, id: NodeId, into: &mut Vec<NodeId>) {
    into.clear();
    let mut stack = vec![id];
    while let Some(id) = stack.pop() {
        let node = graph.node(id);
        if let Op::Binary(BinaryOp::Mul) = node.op {
            // The right factor after the left one.
            stack.push(node.args[1]);
            stack.push(node.args[0]);
        } else {
            into.push(id);
        }
    }
}
