//! Nodes written in Rust by the host, callable from the language by name.
//!
//! Register an implementation of [`CustomNode`] in a [`crate::Registry`]; lowering
//! looks names up there after the built-in catalogue, so no parser change is needed.

use std::any::Any;
use std::fmt;
use std::ops::RangeInclusive;

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
