//! Stateful built-in nodes: each implements [`StatefulKernel`] in its own file under
//! `dsp/`, and its catalogue entry makes the op. The interpreter creates the state
//! and calls the kernel a block at a time; nothing else names it (compiled engines
//! call back into the interpreter for it), so a new stateful node touches no engine.
//! (One exception: the JIT compiles the optimiser's modal bank itself.)

use std::any::Any;
use std::fmt;

use crate::interp::RenderConfig;
use crate::op::Description;

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

    /// The node's name in the catalogue (and in pictures).
    fn name(&self) -> &'static str;

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
    /// `timbre_ir::limits`). Kernels whose state grows with a time or a length
    /// (delay lines, replays) say how much; the small ones keep the default.
    fn memory(&self, ctx: &StateContext) -> u64 {
        64 * ctx.width as u64
    }

    /// Computes the next `inputs.n` samples of every lane.
    fn process(&self, state: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>);
}

/// [`StatefulKernel`] with its state type erased, as ops hold it.
pub trait DynKernel: fmt::Debug + Send + Sync + 'static {
    fn name(&self) -> &'static str;
    fn describe(&self, d: &mut Description);
    fn detail(&self) -> String;
    fn width(&self, args: &[usize]) -> usize;
    fn new_state(&self, ctx: &StateContext) -> Box<dyn Any + Send>;
    fn memory(&self, ctx: &StateContext) -> u64;
    fn process(&self, state: &mut (dyn Any + Send), inputs: &Inputs<'_>, out: &mut Outputs<'_>);
    /// The kernel itself, for an engine that compiles some kernels of its own (the
    /// JIT's modal bank) to recognise them.
    fn as_any(&self) -> &dyn Any;
}

impl<K: StatefulKernel> DynKernel for K {
    fn name(&self) -> &'static str {
        StatefulKernel::name(self)
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
