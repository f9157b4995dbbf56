//! Timbre trees as a hash-consed DAG in an arena.
//!
//! Invariants:
//! - A node's children have smaller ids than the node, so arena order is a valid
//!   post-order for evaluation.
//! - Structurally identical nodes are stored once: [`Graph::add`] returns the existing
//!   id when the same op with the same children was added before.
//! - Pure nodes whose children are all constants are folded into constants as they
//!   are added, using the same functions the interpreter calls.
//! - Widths are checked by lowering before [`Graph::add`] is called; `add` computes
//!   the width but trusts the arguments to be compatible.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use crate::op::{BinaryOp, ImpulseResponse, Op, TernaryOp, UnaryOp};
use timbre_diag::SourceFile;
use timbre_diag::Span;

/// Index of a node in its [`Graph`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

impl NodeId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

#[derive(Clone, Debug)]
pub struct Node {
    pub op: Op,
    pub args: Vec<NodeId>,
    /// Number of lanes.
    pub width: usize,
    /// Structural hash: equal for structurally equal subtrees, stable across runs.
    /// Random nodes derive their seeds from it.
    pub hash: u64,
}

impl Node {
    pub fn as_const(&self) -> Option<&[f64]> {
        match &self.op {
            Op::Const(values) => Some(values),
            _ => None,
        }
    }
}

/// A deterministic 64-bit hasher (FNV-1a over words, finalised with a mixer). Seeds of
/// random nodes come from it, so it must never depend on the process or platform.
#[derive(Clone, Debug)]
pub struct StableHasher(u64);

impl StableHasher {
    pub fn new() -> Self {
        StableHasher(0xcbf2_9ce4_8422_2325)
    }

    pub fn write_u64(&mut self, x: u64) {
        for byte in x.to_le_bytes() {
            self.0 ^= byte as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    pub fn write_str(&mut self, s: &str) {
        self.write_u64(s.len() as u64);
        for byte in s.bytes() {
            self.0 ^= byte as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    pub fn finish(&self) -> u64 {
        crate::dsp::noise::mix64(self.0)
    }
}

impl Default for StableHasher {
    fn default() -> Self {
        Self::new()
    }
}

/// An arena of nodes; see the module documentation for its invariants.
#[derive(Clone, Debug, Default)]
pub struct Graph {
    nodes: Vec<Node>,
    /// Structural hash → ids with that hash (collisions are resolved by comparison).
    interned: HashMap<u64, Vec<NodeId>>,
    /// Where each node was first written, when lowering said (see
    /// [`Graph::set_origin`]): for diagnostics about a node after lowering.
    origins: Vec<Option<NodeOrigin>>,
    /// The origin given to the nodes added now.
    origin: Option<NodeOrigin>,
    /// Lanes of every node together.
    lanes: usize,
}

/// The call a node was written as: its file and span.
#[derive(Clone, Debug)]
pub struct NodeOrigin {
    pub source: Arc<SourceFile>,
    pub span: Span,
}

impl Graph {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Lanes of all its nodes together.
    pub fn lanes(&self) -> usize {
        self.lanes
    }

    /// Gives the nodes added from now on `origin` (lowering sets it around each call
    /// it builds); a node keeps the origin of its first writing.
    pub fn set_origin(&mut self, origin: Option<NodeOrigin>) -> Option<NodeOrigin> {
        std::mem::replace(&mut self.origin, origin)
    }

    /// Where node `id` was written, if known.
    pub fn origin(&self, id: NodeId) -> Option<&NodeOrigin> {
        self.origins.get(id.index()).and_then(Option::as_ref)
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    pub fn node(&self, id: NodeId) -> &Node {
        &self.nodes[id.index()]
    }

    pub fn nodes(&self) -> impl Iterator<Item = (NodeId, &Node)> {
        self.nodes
            .iter()
            .enumerate()
            .map(|(i, node)| (NodeId(i as u32), node))
    }

    pub fn width(&self, id: NodeId) -> usize {
        self.node(id).width
    }

    pub fn constant(&mut self, value: f64) -> NodeId {
        self.add(Op::Const(Arc::from([value])), vec![])
    }

    pub fn const_vector(&mut self, values: Vec<f64>) -> NodeId {
        self.add(Op::Const(Arc::from(values)), vec![])
    }

    /// The node's constant lanes, if it is a constant.
    pub fn const_value(&self, id: NodeId) -> Option<&[f64]> {
        self.node(id).as_const()
    }

    /// The node's value if it is a one-lane constant.
    pub fn scalar(&self, id: NodeId) -> Option<f64> {
        match self.const_value(id) {
            Some([x]) => Some(*x),
            _ => None,
        }
    }

    /// Adds a node (or finds the identical one), folding it if it is pure and all its
    /// children are constants.
    pub fn add(&mut self, op: Op, args: Vec<NodeId>) -> NodeId {
        if let Some(folded) = self.fold(&op, &args) {
            return self.add_unfolded(Op::Const(Arc::from(folded)), vec![]);
        }
        if let Some(simpler) = self.simplify(&op, &args) {
            return simpler;
        }
        self.add_unfolded(op, args)
    }

    fn add_unfolded(&mut self, op: Op, args: Vec<NodeId>) -> NodeId {
        let mut hasher = StableHasher::new();
        op.fingerprint(&mut hasher);
        for arg in &args {
            hasher.write_u64(self.node(*arg).hash);
        }
        let hash = hasher.finish();
        if let Some(candidates) = self.interned.get(&hash) {
            for &id in candidates {
                let node = &self.nodes[id.index()];
                if node.args == args && node.op.same_as(&op) {
                    return id;
                }
            }
        }
        let width = self.infer_width(&op, &args);
        let id = NodeId(self.nodes.len() as u32);
        self.nodes.push(Node {
            op,
            args,
            width,
            hash,
        });
        self.origins.push(self.origin.clone());
        self.lanes = self.lanes.saturating_add(width);
        self.interned.entry(hash).or_default().push(id);
        id
    }

    /// The width of a node with this op and these (already compatible) children.
    fn infer_width(&self, op: &Op, args: &[NodeId]) -> usize {
        let widths = args.iter().map(|a| self.width(*a));
        match op {
            Op::Const(values) => values.len(),
            Op::White { seeds } | Op::Noise { seeds } => seeds.len(),
            Op::Time | Op::Variable(_) => 1,
            Op::Combine | Op::Index => 1,
            Op::Concat => widths.sum(),
            Op::Conv(_) | Op::Timer { .. } => self.width(args[0]),
            Op::Stateful(kernel) => {
                let widths: Vec<usize> = widths.collect();
                kernel.width(&widths)
            }
            _ => widths.max().unwrap_or(1),
        }
    }

    /// Evaluates a pure node whose children are all constants.
    fn fold(&self, op: &Op, args: &[NodeId]) -> Option<Vec<f64>> {
        let consts: Vec<&[f64]> = args
            .iter()
            .map(|a| self.const_value(*a))
            .collect::<Option<_>>()?;
        evaluate_pure(op, &consts)
    }

    /// Exact algebraic identities: x+0, x*1, x-0, x/1, --x, (combine x) of one lane.
    fn simplify(&mut self, op: &Op, args: &[NodeId]) -> Option<NodeId> {
        let is = |g: &Graph, id: NodeId, v: f64| g.scalar(id) == Some(v);
        // Only when the result keeps the other argument's width.
        let keeps_width = |g: &Graph, keep: NodeId, drop: NodeId| g.width(keep) >= g.width(drop);
        match op {
            Op::Binary(BinaryOp::Add) => {
                if is(self, args[1], 0.0) && keeps_width(self, args[0], args[1]) {
                    return Some(args[0]);
                }
                if is(self, args[0], 0.0) && keeps_width(self, args[1], args[0]) {
                    return Some(args[1]);
                }
            }
            Op::Binary(BinaryOp::Sub | BinaryOp::Div)
                if is(
                    self,
                    args[1],
                    if matches!(op, Op::Binary(BinaryOp::Sub)) {
                        0.0
                    } else {
                        1.0
                    },
                ) && keeps_width(self, args[0], args[1]) =>
            {
                return Some(args[0]);
            }
            Op::Binary(BinaryOp::Mul) => {
                if is(self, args[1], 1.0) && keeps_width(self, args[0], args[1]) {
                    return Some(args[0]);
                }
                if is(self, args[0], 1.0) && keeps_width(self, args[1], args[0]) {
                    return Some(args[1]);
                }
            }
            Op::Unary(UnaryOp::Neg) => {
                let inner = self.node(args[0]);
                if matches!(inner.op, Op::Unary(UnaryOp::Neg)) {
                    return Some(inner.args[0]);
                }
            }
            Op::Combine if self.width(args[0]) == 1 => return Some(args[0]),
            // A zero phase offset is left out: `(phasor f)` outputs its accumulator
            // itself, which the engines compute without an add and a frac.
            Op::Phasor
                if args.len() == 2
                    && self
                        .const_value(args[1])
                        .is_some_and(|v| v.iter().all(|x| *x == 0.0))
                    && keeps_width(self, args[0], args[1]) =>
            {
                return Some(self.add_unfolded(Op::Phasor, vec![args[0]]));
            }
            Op::Ternary(TernaryOp::If) => {
                if let Some(c) = self.scalar(args[0]) {
                    let (chosen, other) = if c != 0.0 {
                        (args[1], args[2])
                    } else {
                        (args[2], args[1])
                    };
                    if keeps_width(self, chosen, other) && keeps_width(self, chosen, args[0]) {
                        return Some(chosen);
                    }
                }
            }
            _ => {}
        }
        None
    }

    /// A graph of its own holding a copy of what `root` needs (through arguments and
    /// impulse-response trees), and where `root` is in it: for nodes that render a
    /// sub-tree on a clock of their own (`energetic`), so that no later pass over this
    /// graph (optimising, dumping, copying) has to know about the sub-tree.
    pub fn subgraph(&self, root: NodeId) -> (Graph, NodeId) {
        let needed = self.needed(root);
        let mut out = Graph::new();
        let mut map = HashMap::with_capacity(needed.len());
        for id in needed {
            let copy = out.copy_node(&self.nodes[id.index()], |a| map[&a]);
            map.insert(id, copy);
        }
        (out, map[&root])
    }

    /// The nodes `root` needs (through arguments and impulse-response trees), in id
    /// order: a walk over them alone, so that an instance's start does not cost the
    /// size of a scene's whole graph.
    pub fn needed(&self, root: NodeId) -> Vec<NodeId> {
        self.walk(root, true)
    }

    /// The nodes reached from `root` through arguments (and impulse-response trees,
    /// if `trees`), in id order, found by a walk over them alone.
    fn walk(&self, root: NodeId, trees: bool) -> Vec<NodeId> {
        let mut seen = HashSet::from([root]);
        let mut stack = vec![root];
        while let Some(id) = stack.pop() {
            let node = &self.nodes[id.index()];
            let tree = match &node.op {
                Op::Conv(ImpulseResponse::Tree { root, .. }) if trees => Some(*root),
                _ => None,
            };
            for arg in node.args.iter().copied().chain(tree) {
                if seen.insert(arg) {
                    stack.push(arg);
                }
            }
        }
        let mut order: Vec<NodeId> = seen.into_iter().collect();
        order.sort_unstable();
        order
    }

    /// Which nodes `roots` depend on, through arguments and impulse-response trees.
    pub fn reachable(&self, roots: &[NodeId]) -> Vec<bool> {
        let mut needed = vec![false; self.nodes.len()];
        for root in roots {
            needed[root.index()] = true;
        }
        // Children have smaller ids: one backwards sweep from the last root.
        let Some(last) = roots.iter().map(|r| r.index()).max() else {
            return needed;
        };
        for i in (0..=last).rev() {
            if !needed[i] {
                continue;
            }
            let node = &self.nodes[i];
            for arg in &node.args {
                needed[arg.index()] = true;
            }
            if let Op::Conv(ImpulseResponse::Tree { root, .. }) = &node.op {
                needed[root.index()] = true;
            }
        }
        needed
    }

    /// Adds a copy of `node` (of another graph), its arguments and impulse-response
    /// root renamed by `map` (old id → id here).
    pub(crate) fn copy_node(&mut self, node: &Node, map: impl Fn(NodeId) -> NodeId) -> NodeId {
        let args = node.args.iter().map(|a| map(*a)).collect();
        let op = match &node.op {
            Op::Conv(ImpulseResponse::Tree { root, seconds }) => Op::Conv(ImpulseResponse::Tree {
                root: map(*root),
                seconds: *seconds,
            }),
            op => op.clone(),
        };
        self.add(op, args)
    }

    /// Ids of the nodes the evaluation of `root` needs, in evaluation order. A
    /// convolution's impulse-response tree is not included: it is rendered on its own.
    pub fn schedule(&self, root: NodeId) -> Vec<NodeId> {
        // Children have smaller ids, so the reached nodes in id order are an order
        // of evaluation.
        self.walk(root, false)
    }
}

/// The lanes of a pure node from its arguments' lanes (one number broadcasting), as
/// constant folding computes them and as the interpreter does sample by sample;
/// `None` for a node with state or one that reads the time, the sample index or the
/// host.
pub fn evaluate_pure(op: &Op, consts: &[&[f64]]) -> Option<Vec<f64>> {
    let width = consts.iter().map(|c| c.len()).max().unwrap_or(1);
    let lane = |c: &[f64], l: usize| if c.len() == 1 { c[0] } else { c[l] };
    let values = match op {
        Op::Unary(u) => consts[0].iter().map(|x| u.apply(*x)).collect(),
        Op::Binary(b) => (0..width)
            .map(|l| b.apply(lane(consts[0], l), lane(consts[1], l)))
            .collect(),
        Op::Ternary(t) => (0..width)
            .map(|l| t.apply(lane(consts[0], l), lane(consts[1], l), lane(consts[2], l)))
            .collect(),
        Op::Noise { seeds } => (0..seeds.len())
            .map(|l| crate::op::noise(seeds[l], lane(consts[0], l)))
            .collect(),
        Op::Env => (0..width)
            .map(|l| crate::op::env(std::array::from_fn(|i| lane(consts[i], l))))
            .collect(),
        Op::Combine => vec![crate::op::combine(consts[0])],
        Op::Index => {
            let i = index_lane(consts[1][0], consts[0].len());
            vec![consts[0][i]]
        }
        Op::Concat => consts.concat(),
        Op::Keyframe(track) => consts[0].iter().map(|x| track.value(*x)).collect(),
        Op::Timer {
            length,
            fade_in,
            fade_out,
        } => (0..width)
            .map(|l| {
                // A constant sound's first sample is the constant.
                let x = lane(consts[0], l);
                let fade_in = fade_in.seconds(x);
                x * crate::op::timer_gain(lane(consts[1], l), *length, fade_in, *fade_out)
            })
            .collect(),
        _ => return None,
    };
    Some(values)
}

/// The lane selected by an `index` argument: floor(i), clamped to the lanes that exist.
#[inline]
pub fn index_lane(i: f64, width: usize) -> usize {
    if i.is_nan() || i < 0.0 {
        0
    } else {
        (i.floor() as usize).min(width - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_subtrees_are_one_node() {
        let mut g = Graph::new();
        let t1 = g.add(Op::Time, vec![]);
        let t2 = g.add(Op::Time, vec![]);
        assert_eq!(t1, t2);
        let k = g.constant(440.0);
        let a = g.add(Op::Binary(BinaryOp::Mul), vec![t1, k]);
        let b = g.add(Op::Binary(BinaryOp::Mul), vec![t2, k]);
        assert_eq!(a, b);
        assert_eq!(g.len(), 3);
    }

    #[test]
    fn constants_fold_with_the_interpreters_functions() {
        let mut g = Graph::new();
        let a = g.const_vector(vec![1.0, 2.0, 3.0]);
        let b = g.constant(0.25);
        let p = g.add(Op::Binary(BinaryOp::Mul), vec![a, b]);
        let s = g.add(Op::Unary(UnaryOp::Sine), vec![p]);
        let expected: Vec<f64> = [0.25f64, 0.5, 0.75]
            .iter()
            .map(|x| UnaryOp::Sine.apply(*x))
            .collect();
        assert_eq!(g.const_value(s).unwrap(), &expected[..]);
        let c = g.add(Op::Combine, vec![s]);
        // Even lanes, then odd lanes (`op::combine`).
        let sum = (0.0 + expected[0] + expected[2]) + (0.0 + expected[1]);
        assert_eq!(g.scalar(c), Some(sum));
    }

    #[test]
    fn identities_keep_width() {
        let mut g = Graph::new();
        let t = g.add(Op::Time, vec![]);
        let zero = g.constant(0.0);
        assert_eq!(g.add(Op::Binary(BinaryOp::Add), vec![t, zero]), t);
        let zeros = g.const_vector(vec![0.0, 0.0]);
        let widened = g.add(Op::Binary(BinaryOp::Add), vec![t, zeros]);
        assert_ne!(widened, t);
        assert_eq!(g.width(widened), 2);
    }

    #[test]
    fn a_zero_phase_offset_is_left_out_unless_it_widens() {
        let mut g = Graph::new();
        let t = g.add(Op::Time, vec![]);
        let zero = g.constant(0.0);
        let plain = g.add(Op::Phasor, vec![t, zero]);
        assert_eq!(g.node(plain).args, vec![t]);
        let quarter = g.constant(0.25);
        let offset = g.add(Op::Phasor, vec![t, quarter]);
        assert_eq!(g.node(offset).args, vec![t, quarter]);
        let zeros = g.const_vector(vec![0.0, 0.0]);
        let widened = g.add(Op::Phasor, vec![t, zeros]);
        assert_eq!(g.width(widened), 2);
    }

    #[test]
    fn schedule_is_post_order_of_reachable_nodes() {
        let mut g = Graph::new();
        let unused = g.add(
            Op::White {
                seeds: Arc::from([1]),
            },
            vec![],
        );
        let t = g.add(Op::Time, vec![]);
        let s = g.add(Op::Unary(UnaryOp::Sine), vec![t]);
        assert_eq!(g.schedule(s), vec![t, s]);
        assert!(!g.schedule(s).contains(&unused));
    }
}
