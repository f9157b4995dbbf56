//! Stateful nodes: each built-in one implements [`StatefulKernel`] in its own file
//! under `dsp/`, and its catalogue entry makes the op; a host's node
//! ([`crate::custom::CustomNode`]) runs as one through [`crate::custom::HostKernel`].
//! The interpreter creates the state and calls the kernel a block at a time; nothing
//! else names it (compiled engines call back into the interpreter for it), so a new
//! stateful node touches no engine. (One exception: the JIT compiles the optimiser's
//! modal bank itself.) A kernel also says how much memory its state takes (for the
//! render-cost check) and how a call writes it back as source ([`KernelOption`]).

use std::any::Any;
use std::fmt;

use crate::graph::{Graph, NodeId};
use crate::interp::RenderConfig;
use crate::op::Description;

/// One piece of a kernel's constant configuration, as its call in the language
/// writes it (see `timbre_lang::print`). A kernel lists them in call order.
#[derive(Clone, Copy, Debug)]
pub enum KernelOption<'a> {
    /// A keyword argument after the positional ones: `:max 0.5`.
    Number(&'static str, f64),
    /// The file the node reads, written as a string before the positional arguments:
    /// `(sample "kick.wav" …)`.
    File(&'a str),
    /// The seed of each output lane: `:lanes` where there are more lanes than the
    /// first argument's (or than one, with `lanes_follow_arg` false), then the first
    /// lane's seed as `:seed-bits`.
    Seeds {
        seeds: &'a [u64],
        lanes_follow_arg: bool,
    },
    /// A tree of another graph the node replays, written after the positional
    /// arguments as an expression.
    Source(&'a Graph, NodeId),
    /// The whole call as the language wrote it, for a node that names things outside
    /// the tree (a glTF node, a keyframed vector), with the top-level forms it needs
    /// (each written once, before the tree). Its one argument, the scene time it
    /// reads, is written as `:time` where it is not `t`.
    Written { call: &'a str, forms: &'a [String] },
}

/// The bytes of a kernel whose state is a few numbers per lane (filters,
/// oscillators, envelopes): what the render-cost check counts for it.
pub fn small_state_bytes(ctx: &StateContext) -> u64 {
    64 * ctx.width as u64
}

/// What a kernel may use to build its state.
pub struct StateContext {
    /// Lanes of the node's output.
    pub width: usize,
    pub config: RenderConfig,
}

/// The node's arguments for one block: `n` samples per lane, read-only.
#[derive(Clone, Copy)]
pub struct Inputs<'a> {
    pub(crate) buffers: &'a [Vec<f64>],
    pub(crate) widths: &'a [usize],
    pub(crate) args: &'a [usize],
    pub(crate) stride: usize,
    /// Samples in this block.
    pub n: usize,
    pub sample_rate: f64,
    /// Index of the block's first sample since the start of the instance.
    pub first_sample: u64,
}

impl<'a> Inputs<'a> {
    /// Samples of lane `lane` of argument `arg`; a one-lane argument broadcasts.
    pub fn lane(&self, arg: usize, lane: usize) -> &'a [f64] {
        let step = self.args[arg];
        let lane = if self.widths[step] == 1 { 0 } else { lane };
        &self.buffers[step][lane * self.stride..lane * self.stride + self.n]
    }

    /// Lanes of argument `arg`.
    pub fn width(&self, arg: usize) -> usize {
        self.widths[self.args[arg]]
    }
}

/// The node's output for one block: `width` lanes of `n` samples.
pub struct Outputs<'a> {
    pub(crate) samples: &'a mut [f64],
    pub(crate) stride: usize,
    pub n: usize,
    pub width: usize,
}

impl Outputs<'_> {
    pub fn lane(&mut self, lane: usize) -> &mut [f64] {
        &mut self.samples[lane * self.stride..lane * self.stride + self.n]
    }

    /// All lanes at once, lane `l` at `l · stride` (for kernels that interleave lanes).
    pub fn strided(&mut self) -> (&mut [f64], usize) {
        (self.samples, self.stride)
    }
}

/// A stateful node. Implementations must be deterministic and independent of the
/// block size: the same arguments from the same sample on give the same output.
pub trait StatefulKernel: fmt::Debug + Send + Sync + 'static {
    type State: Send + 'static;

    /// The node's name in the catalogue (and in pictures): its kind. Every host's
    /// node is of the kind `custom`.
    fn name(&self) -> &'static str;

    /// The name its call is written with: [`name`](Self::name), but for a host's
    /// node, which goes by the name it was registered under.
    fn call_name(&self) -> &str {
        self.name()
    }

    /// Everything besides the name that tells this node from another (its constant
    /// configuration: a seed, a filter kind, a maximum delay …), for node identity.
    fn describe(&self, _d: &mut Description) {}

    /// Its configuration for people (`timbre check --ir`, pictures), e.g.
    /// `max=0.5 s`; empty if the name says it all.
    fn detail(&self) -> String {
        String::new()
    }

    /// Output lanes for these argument widths (already checked to broadcast).
    fn width(&self, args: &[usize]) -> usize {
        args.iter().copied().max().unwrap_or(1)
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State;

    /// Bytes its state will need at `ctx`, estimated without making it, so that a
    /// render beyond the host's memory limit is refused before it starts (see
    /// `timbre_ir::limits`). Every kernel says it (no default, so a delay line or a
    /// replay cannot be forgotten); small ones use [`small_state_bytes`].
    fn memory(&self, ctx: &StateContext) -> u64;

    /// Its configuration as its call writes it (after the name and the positional
    /// arguments), or `None` for a kernel no call makes (the scene's and the
    /// optimiser's). The default: the name says it all, as for `lowpass`.
    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(Vec::new())
    }

    /// Computes the next `inputs.n` samples of every lane.
    fn process(&self, state: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>);
}

/// [`StatefulKernel`] with its state type erased, as ops hold it.
pub trait DynKernel: fmt::Debug + Send + Sync + 'static {
    fn name(&self) -> &'static str;
    fn call_name(&self) -> &str;
    fn describe(&self, d: &mut Description);
    fn detail(&self) -> String;
    fn width(&self, args: &[usize]) -> usize;
    fn new_state(&self, ctx: &StateContext) -> Box<dyn Any + Send>;
    fn memory(&self, ctx: &StateContext) -> u64;
    fn options(&self) -> Option<Vec<KernelOption<'_>>>;
    fn process(&self, state: &mut (dyn Any + Send), inputs: &Inputs<'_>, out: &mut Outputs<'_>);
    /// The kernel itself, for an engine that compiles some kernels of its own (the
    /// JIT's modal bank) to recognise them.
    fn as_any(&self) -> &dyn Any;
}

impl<K: StatefulKernel> DynKernel for K {
    fn name(&self) -> &'static str {
        StatefulKernel::name(self)
    }

    fn call_name(&self) -> &str {
        StatefulKernel::call_name(self)
    }

    fn describe(&self, d: &mut Description) {
        StatefulKernel::describe(self, d)
    }

    fn detail(&self) -> String {
        StatefulKernel::detail(self)
    }

    fn width(&self, args: &[usize]) -> usize {
        StatefulKernel::width(self, args)
    }

    fn new_state(&self, ctx: &StateContext) -> Box<dyn Any + Send> {
        Box::new(StatefulKernel::new_state(self, ctx))
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        StatefulKernel::memory(self, ctx)
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        StatefulKernel::options(self)
    }

    fn process(&self, state: &mut (dyn Any + Send), inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        // The state was made by `new_state` of this same kernel, so it always has
        // this type.
        if let Some(state) = state.downcast_mut::<K::State>() {
            StatefulKernel::process(self, state, inputs, out);
        }
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
