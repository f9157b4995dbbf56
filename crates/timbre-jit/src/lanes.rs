//! Instances as lanes: the active instances of one class, the paper's swarm, computed
//! as the lanes of one kernel call rather than one voice each.
//!
//! An instance qualifies when its tree is one lane throughout and computed wholly
//! inline under its timer: constants, `t`, the element-wise functions the JIT has
//! inline code for (all but `tan`), `phasor`, `noise` and `white` (a bee, a tone, an
//! FM voice; not a modal bank, a filter or anything else the interpreter computes). Instances of one shape differ only in their
//! constants, seeds and timers, so a [`LaneBatch`] runs them as the lanes of one
//! kernel compiled for the shape widened to [`BATCH_LANES`] lanes: their constants
//! are per-lane buffers, their seeds per-lane state, and each lane's local time and
//! sample index count from its own start (`KernelBuilder::lane_starts`). Compiling
//! happens once per shape (the widened schedule is cached like any other); adding an
//! instance writes its lane's constants and initial state.
//!
//! A lane starts at its instance's first sample, whatever the block: a block is cut
//! at the starts of the lanes that begin in it, and the lanes are set to their initial
//! state (phase 0, no noise cell) right there. Every lane's samples are therefore
//! those it would have alone, whatever the block size and whatever else is in the
//! batch. Each lane's timer is applied afterwards, per lane, with
//! `timbre_ir::op::timer_gain` as the interpreter applies it, its fade-in decided at
//! the lane's first sample.

use std::sync::Arc;

use timbre_ir::op::{sample_time, FadeIn, Op};
use timbre_ir::{Graph, NodeId, RenderConfig, Step};

use crate::codegen::{NOISE_SEED, NOISE_SLOTS};
use crate::shape::{Kind, Shape};
use crate::timer;
use crate::{kernel_params, Jit, JitError, Kernel};

/// Lanes of a batch: instances of one shape beyond this start another batch. A
/// batch computes only up to its highest lane in use, so a large capacity costs
/// memory (mostly untouched), not time.
pub const BATCH_LANES: usize = 32;

/// What an instance brings to a batch: its shape, and what differs between the
/// instances of a shape.
#[derive(Clone, Debug)]
pub struct InstanceLanes {
    /// The instance's sound (its tree under the timer), one lane, as steps.
    steps: Vec<Step>,
    shape: Shape,
    /// The timer's length (if it stops), fade-in and fade-out (in seconds).
    timer: (Option<f64>, FadeIn, f64),
}

impl InstanceLanes {
    /// The instance `root` of `graph` (its timer at the root), after the rewrites of
    /// `timbre_ir::optimise`, if it can be a lane of a batch.
    pub fn of(graph: &Graph, root: NodeId, block_size: usize) -> Option<InstanceLanes> {
        // Most instances that do not qualify (modes in lanes, a filter) are told at
        // their first such node, before the optimiser's pass over the graph.
        if !may_qualify(graph, root) {
            return None;
        }
        let (graph, root) = timbre_ir::optimise::optimise(graph, root);
        let steps = timbre_ir::steps(&graph, root);
        let timer_step = steps.last()?;
        let Op::Timer {
            length,
            fade_in,
            fade_out,
        } = timer_step.op
        else {
            return None;
        };
        let [sound, time] = timer_step.args[..] else {
            return None;
        };
        if !matches!(steps[time].op, Op::Time) {
            return None;
        }
        // The steps the sound depends on, children before parents, in the order of a
        // depth-first walk from the sound (not of node ids, which differ between
        // instances as hash-consing shares their constants with other trees), so that
        // instances of one class have one shape.
        let mut order = vec![];
        let mut index = vec![usize::MAX; steps.len()];
        let mut stack = vec![(sound, 0)];
        while let Some((i, next)) = stack.pop() {
            if index[i] != usize::MAX {
                continue;
            }
            if let Some(&a) = steps[i].args.get(next) {
                stack.push((i, next + 1));
                stack.push((a, 0));
                continue;
            }
            index[i] = order.len();
            order.push(i);
        }
        let mut sound_steps = vec![];
        for &i in &order {
            let step = &steps[i];
            if !lane_op(&step.op) || step.width != 1 {
                return None;
            }
            sound_steps.push(Step {
                op: step.op.clone(),
                args: step.args.iter().map(|a| index[*a]).collect(),
                width: 1,
                constant: step.constant,
            });
        }
        // A sound that is a constant has nothing to compute.
        if sound_steps.last()?.constant {
            return None;
        }
        let block_size = even_block(block_size);
        Some(InstanceLanes {
            shape: Shape::of(&widen(&sound_steps), block_size),
            steps: sound_steps,
            timer: (length, fade_in, fade_out),
        })
    }
}

/// Whether an op can be in a lane's tree: a constant, or computed inline in a region
/// (see `plan`), one lane.
fn lane_op(op: &Op) -> bool {
    match Kind::of(op) {
        Kind::Const => true,
        Kind::White => matches!(op, Op::White { seeds } if seeds.len() == 1),
        kind => kind.is_inline(),
    }
}

/// Whether every node of the instance `root` (a timer over its sound) is one lane and
/// of an op a lane can compute, as written: a walk that stops at the first that is
/// not. (The optimiser may still make one of them a rotator, which is not.)
fn may_qualify(graph: &Graph, root: NodeId) -> bool {
    if !matches!(graph.node(root).op, Op::Timer { .. }) {
        return false;
    }
    let mut seen = std::collections::HashSet::new();
    let mut stack: Vec<NodeId> = graph.node(root).args.clone();
    while let Some(id) = stack.pop() {
        if !seen.insert(id) {
            continue;
        }
        let node = graph.node(id);
        if node.width != 1 || !lane_op(&node.op) {
            return false;
        }
        stack.extend(node.args.iter().copied());
    }
    true
}

/// The block size kernels are compiled for: whole pairs of samples.
fn even_block(block_size: usize) -> usize {
    block_size.max(2).div_ceil(2) * 2
}

/// A schedule of one lane widened to [`BATCH_LANES`] lanes (constant values and seeds
/// are the first instance's; the batch sets each lane's).
fn widen(steps: &[Step]) -> Vec<Step> {
    steps
        .iter()
        .map(|step| Step {
            op: match &step.op {
                Op::White { seeds } => Op::White {
                    seeds: vec![seeds[0]; BATCH_LANES].into(),
                },
                Op::Noise { seeds } => Op::Noise {
                    seeds: vec![seeds[0]; BATCH_LANES].into(),
                },
                op => op.clone(),
            },
            width: BATCH_LANES,
            ..step.clone()
        })
        .collect()
}

/// One lane of a batch: its instance's start and timer, whether its state is set
/// yet (it is, at its first sample), and its fade-in in seconds once decided (at
/// its first sample, as the timer of its own voice decides it).
#[derive(Clone, Copy, Debug)]
struct Lane {
    start: u64,
    timer: (Option<f64>, FadeIn, f64),
    begun: bool,
    fade_in: Option<f64>,
}

/// Instances of one shape, each a lane of one kernel call.
pub struct LaneBatch {
    kernel: Arc<Kernel>,
    shape: Shape,
    /// The widened schedule.
    steps: Vec<Step>,
    block_size: usize,
    sample_rate: f64,
    /// Per step, `BATCH_LANES × block_size` samples (lane after lane), and the
    /// pointers the kernel reads.
    buffers: Vec<Vec<f64>>,
    buffer_pointers: Vec<*mut f64>,
    /// Per step, the state of inline nodes (phases, noise cells and seeds, white
    /// noises' seeds), as a voice has it; then one empty entry per step (a batch has no
    /// splatted copies).
    states: Vec<Vec<f64>>,
    state_pointers: Vec<*mut f64>,
    /// Per lane, the scene sample its local time counts from.
    lane_starts: Vec<i64>,
    /// Per lane, its instance if it has one.
    lanes: Vec<Option<Lane>>,
    /// Each lane's samples of the block last rendered, after its timer.
    output: Vec<f64>,
    /// Scene sample of the first sample of `output`.
    position: u64,
}

// SAFETY: the raw pointers point into buffers owned by this batch and are used only
// by it.
unsafe impl Send for LaneBatch {}

impl LaneBatch {
    /// A batch for instances of `first`'s shape (none in it yet). Compiles the widened
    /// kernel unless `jit` has it already. `None` if that kernel is not wholly inline
    /// after all (its instances are then voices).
    pub fn new(
        jit: &mut Jit,
        first: &InstanceLanes,
        config: RenderConfig,
    ) -> Result<Option<LaneBatch>, JitError> {
        let block_size = even_block(config.block_size);
        let steps = widen(&first.steps);
        let kernel = jit.compile(&steps, block_size)?;
        if kernel.callback_nodes != 0 || !kernel.splatted.is_empty() {
            return Ok(None);
        }
        let mut buffers: Vec<Vec<f64>> = steps
            .iter()
            .map(|_| vec![0.0; BATCH_LANES * block_size])
            .collect();
        let buffer_pointers = buffers.iter_mut().map(|b| b.as_mut_ptr()).collect();
        let mut states: Vec<Vec<f64>> = steps
            .iter()
            .map(|s| match s.op {
                Op::Phasor => vec![0.0; BATCH_LANES],
                Op::Noise { .. } => vec![f64::NAN; NOISE_SLOTS * BATCH_LANES],
                Op::White { .. } => vec![0.0; BATCH_LANES],
                _ => vec![],
            })
            .collect();
        states.extend(steps.iter().map(|_| vec![]));
        let state_pointers = states.iter_mut().map(|s| s.as_mut_ptr()).collect();
        Ok(Some(LaneBatch {
            kernel,
            shape: first.shape.clone(),
            steps,
            block_size,
            sample_rate: config.sample_rate,
            buffers,
            buffer_pointers,
            states,
            state_pointers,
            lane_starts: vec![0; BATCH_LANES],
            lanes: vec![None; BATCH_LANES],
            output: vec![0.0; BATCH_LANES * block_size],
            position: 0,
        }))
    }

    /// Whether `instance` has this batch's shape.
    pub fn fits(&self, instance: &InstanceLanes) -> bool {
        self.shape == instance.shape
    }

    /// Lanes with an instance.
    pub fn lanes_in_use(&self) -> usize {
        self.lanes.iter().filter(|l| l.is_some()).count()
    }

    /// Gives `instance` (of this batch's shape) a free lane, its first sample at
    /// scene sample `start` (not before the next block); `None` if the batch is full.
    /// Its constants are written now; its state is set at its first sample.
    pub fn add(&mut self, instance: &InstanceLanes, start: u64) -> Option<usize> {
        debug_assert!(self.fits(instance));
        let lane = self.lanes.iter().position(Option::is_none)?;
        for (step, buffer) in instance.steps.iter().zip(&mut self.buffers) {
            if let Op::Const(values) = &step.op {
                let row = &mut buffer[lane * self.block_size..(lane + 1) * self.block_size];
                row.fill(values[0]);
            }
        }
        // Seeds now (the lane's state is reset at its first sample).
        for (i, step) in instance.steps.iter().enumerate() {
            match &step.op {
                Op::Noise { seeds } => {
                    let mixed = f64::from_bits(timbre_ir::dsp::noise::mix64(seeds[0]));
                    self.states[i][NOISE_SEED * BATCH_LANES + lane] = mixed;
                }
                Op::White { seeds } => {
                    let mixed = f64::from_bits(timbre_ir::dsp::noise::mix64(seeds[0]));
                    self.states[i][lane] = mixed;
                }
                _ => {}
            }
        }
        self.lanes[lane] = Some(Lane {
            start,
            timer: instance.timer,
            begun: false,
            fade_in: None,
        });
        Some(lane)
    }

    /// Frees a lane whose instance has ended.
    pub fn release(&mut self, lane: usize) {
        self.lanes[lane] = None;
    }

    /// Sets a lane's state as a new voice has it, at its first sample.
    fn begin(&mut self, lane: usize) {
        for (step, state) in self.steps.iter().zip(&mut self.states) {
            match step.op {
                Op::Phasor => state[lane] = 0.0,
                // No lattice cell yet (NaN equals nothing).
                Op::Noise { .. } => state[lane] = f64::NAN,
                _ => {}
            }
        }
        if let Some(l) = &mut self.lanes[lane] {
            l.begun = true;
            self.lane_starts[lane] = l.start as i64;
        }
    }

    /// Renders scene samples `position..position + n` (`n` at most the block size) of
    /// every lane in use: lanes that start in them begin at their first sample.
    pub fn render(&mut self, position: u64, n: usize) {
        debug_assert!(n <= self.block_size);
        self.position = position;
        let end = position + n as u64;
        let mut cursor = position;
        loop {
            // The next start of a lane in this block, if any.
            let next = self
                .lanes
                .iter()
                .flatten()
                .filter(|l| !l.begun && l.start < end)
                .map(|l| l.start.max(cursor))
                .min();
            let until = next.unwrap_or(end);
            if until > cursor {
                self.run(cursor, until);
                cursor = until;
            }
            let Some(start) = next else { break };
            for lane in 0..BATCH_LANES {
                if self.lanes[lane].is_some_and(|l| !l.begun && l.start.max(cursor) == start) {
                    self.begin(lane);
                }
            }
        }
    }

    /// Runs the kernel over scene samples `from..until` of this block and writes the
    /// lanes that have begun into `output`, after their timers.
    fn run(&mut self, from: u64, until: u64) {
        let n = (until - from) as usize;
        let in_use = self
            .lanes
            .iter()
            .rposition(|l| l.is_some_and(|l| l.begun))
            .map_or(0, |last| last + 1);
        if in_use == 0 {
            return;
        }
        let params = kernel_params(self.sample_rate, &self.lane_starts, in_use);
        // SAFETY: the buffer table holds one buffer of `BATCH_LANES × block_size`
        // samples per step, the state table the states the kernel's inline nodes read
        // (and an empty entry per step for splatted copies, which it has none of), and
        // `params` the lane starts; the kernel makes no callbacks (checked in `new`),
        // so it never uses the interpreter pointer.
        unsafe {
            (self.kernel.entry)(
                std::ptr::null_mut(),
                self.buffer_pointers.as_ptr(),
                params.as_ptr(),
                n as u64,
                from,
                self.state_pointers.as_ptr(),
            );
        }
        let bs = self.block_size;
        let sound = &self.buffers[self.buffers.len() - 1];
        let at = (from - self.position) as usize;
        for (lane, l) in self.lanes.iter_mut().enumerate() {
            let Some(l) = l.as_mut().filter(|l| l.begun) else {
                continue;
            };
            let x = &sound[lane * bs..lane * bs + n];
            let y = &mut self.output[lane * bs + at..lane * bs + at + n];
            let (length, fade_in, fade_out) = l.timer;
            let fade_in = *l.fade_in.get_or_insert_with(|| fade_in.seconds(x[0]));
            // The instance's local time, as its own voice has it.
            let first = from - l.start;
            let time = |k: usize| sample_time(first + k as u64, self.sample_rate);
            timer::apply((length, fade_in, fade_out), time, true, x, y);
        }
    }

    /// Lane `lane`'s samples `from..until` of the block last rendered (offsets in the
    /// block).
    pub fn output(&self, lane: usize, from: usize, until: usize) -> &[f64] {
        let bs = self.block_size;
        &self.output[lane * bs + from..lane * bs + until]
    }
}
