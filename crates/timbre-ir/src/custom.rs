//! Nodes written in Rust by the host, callable from the language by name.
//!
//! Register an implementation of [`CustomNode`] in a `Registry` (`timbre_lang`);
//! lowering looks names up there after the built-in catalogue, so no parser change is
//! needed. `CustomNode` is the host's convenient face of a stateful kernel: a name
//! chosen at run time, an arity, a width rule that may refuse with a message, and
//! whole blocks of tightly packed lanes. Lowering wraps it in a [`HostKernel`], a
//! [`StatefulKernel`] like every built-in stateful node, so the interpreter, the JIT
//! (which calls back into the interpreter) and the render-cost check see one kind of
//! stateful node.

use std::any::Any;
use std::fmt;
use std::ops::RangeInclusive;
use std::sync::Arc;

use crate::kernel::{Inputs, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// One block of a node's argument: `width` lanes of `len` samples, lane after lane.
#[derive(Clone, Copy, Debug)]
pub struct Lanes<'a> {
    data: &'a [f64],
    width: usize,
    len: usize,
}

impl<'a> Lanes<'a> {
    pub fn new(data: &'a [f64], width: usize, len: usize) -> Self {
        debug_assert!(data.len() >= width * len);
        Lanes { data, width, len }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    /// Samples of lane `lane`; a one-lane argument broadcasts to every lane.
    pub fn lane(&self, lane: usize) -> &'a [f64] {
        let lane = if self.width == 1 { 0 } else { lane };
        &self.data[lane * self.len..(lane + 1) * self.len]
    }
}

/// What a node sees of the render while it fills a block.
#[derive(Clone, Copy, Debug)]
pub struct BlockContext {
    pub sample_rate: f64,
    /// Index of the block's first sample since the start of the instance.
    pub first_sample: u64,
    /// Samples in this block.
    pub len: usize,
    /// Lanes of this node's output.
    pub width: usize,
}

/// A node implemented in Rust. Implementations must be deterministic: the same
/// arguments and state give the same output, whatever the block size.
pub trait CustomNode: Send + Sync + 'static {
    /// The name the language calls it by.
    fn name(&self) -> &str;

    /// How many arguments it takes.
    fn arity(&self) -> RangeInclusive<usize>;

    /// Output lanes for the given argument widths; the default broadcasts (all
    /// arguments one lane or the same width). An `Err` message becomes a diagnostic.
    fn output_width(&self, arg_widths: &[usize]) -> Result<usize, String> {
        let width = arg_widths.iter().copied().max().unwrap_or(1);
        match arg_widths.iter().find(|w| **w != 1 && **w != width) {
            Some(other) => Err(format!("arguments of {width} and {other} lanes")),
            None => Ok(width),
        }
    }

    /// Fresh per-instance state; the default is stateless.
    fn new_state(&self, _width: usize, _sample_rate: f64) -> Box<dyn Any + Send> {
        Box::new(())
    }

    /// Bytes its state will need for `width` lanes at `sample_rate`, counted by the
    /// render-cost check (`timbre_ir::limits`). A node whose state grows with a time
    /// or a length (a delay line, a recording) should say how much; the default
    /// counts nothing.
    fn memory(&self, _width: usize, _sample_rate: f64) -> u64 {
        0
    }

    /// Fills `out` (`ctx.width` lanes of `ctx.len` samples, lane after lane).
    fn eval_block(
        &self,
        ctx: &BlockContext,
        args: &[Lanes<'_>],
        out: &mut [f64],
        state: &mut (dyn Any + Send),
    );
}

impl fmt::Debug for dyn CustomNode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CustomNode({})", self.name())
    }
}

/// A host's node as the interpreter runs it: a [`StatefulKernel`] that hands each
/// block to the node with its lanes packed.
#[derive(Debug)]
pub struct HostKernel(pub Arc<dyn CustomNode>);

impl StatefulKernel for HostKernel {
    type State = Box<dyn Any + Send>;

    fn name(&self) -> &'static str {
        "custom"
    }

    fn call_name(&self) -> &str {
        self.0.name()
    }

    /// A host node by its registered name.
    fn describe(&self, d: &mut Description) {
        d.str(self.0.name());
    }

    fn detail(&self) -> String {
        self.0.name().into()
    }

    /// Lowering has already turned a refused width into a diagnostic.
    fn width(&self, args: &[usize]) -> usize {
        self.0.output_width(args).unwrap_or(1)
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        self.0.new_state(ctx.width, ctx.config.sample_rate)
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        self.0.memory(ctx.width, ctx.config.sample_rate)
    }

    fn process(&self, state: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let bs = inputs.stride;
        let args: Vec<Lanes<'_>> = inputs
            .args
            .iter()
            .map(|&a| Lanes::new(&inputs.buffers[a], inputs.widths[a], bs))
            .collect();
        let ctx = BlockContext {
            sample_rate: inputs.sample_rate,
            first_sample: inputs.first_sample,
            len: inputs.n,
            width: out.width,
        };
        eval_custom(
            self.0.as_ref(),
            &ctx,
            &args,
            out.samples,
            bs,
            state.as_mut(),
        );
    }
}

/// Calls a custom node with a tightly packed output (`width × n`) and spreads the
/// lanes back to the block stride.
fn eval_custom(
    node: &dyn CustomNode,
    ctx: &BlockContext,
    args: &[Lanes<'_>],
    out: &mut [f64],
    bs: usize,
    state: &mut (dyn Any + Send),
) {
    let (n, width) = (ctx.len, ctx.width);
    if n == bs {
        node.eval_block(ctx, args, &mut out[..width * bs], state);
        return;
    }
    // A short final block: arguments are still laid out with the block stride, so
    // present them and the output packed to `n`.
    let packed_args: Vec<Vec<f64>> = args
        .iter()
        .map(|a| {
            (0..a.width())
                .flat_map(|l| a.lane(l)[..n].to_vec())
                .collect()
        })
        .collect();
    let lanes: Vec<Lanes<'_>> = packed_args
        .iter()
        .zip(args)
        .map(|(data, a)| Lanes::new(data, a.width(), n))
        .collect();
    let mut packed = vec![0.0; width * n];
    node.eval_block(ctx, &lanes, &mut packed, state);
    for l in 0..width {
        out[l * bs..l * bs + n].copy_from_slice(&packed[l * n..(l + 1) * n]);
    }
}
