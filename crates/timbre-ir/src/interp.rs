//! The reference interpreter: post-order evaluation of a tree, a block at a time.
//!
//! Each scheduled node owns a buffer of `width × block_size` samples (lane after lane)
//! and, if it is stateful, an explicit state. A block is rendered by filling the
//! buffers in schedule order, so every node reads finished buffers of its children.
//! Output depends only on the tree, the sample rate and the number of samples
//! rendered so far, never on the block size or on how a render is split into calls.

use std::any::Any;

use crate::dsp::conv::Convolver;
use crate::dsp::noise::white;
use crate::dsp::wav::resample;
use crate::graph::{index_lane, Graph, NodeId};
use crate::kernel::{Inputs, Outputs, StateContext};
use crate::op::{env, frac, noise, timer_gain, ImpulseResponse, Op};

/// Partition size of the FFT convolution (independent of the block size, so output
/// does not depend on it).
const CONV_PARTITION: usize = 256;

/// How to render: the sample rate and the number of samples per block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderConfig {
    pub sample_rate: f64,
    pub block_size: usize,
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            sample_rate: 48_000.0,
            block_size: 256,
        }
    }
}

/// One scheduled node, as a compiled engine sees it.
#[derive(Clone, Debug)]
pub struct Step {
    pub op: Op,
    /// Step indices of the arguments.
    pub args: Vec<usize>,
    pub width: usize,
    /// Constants are filled once and never recomputed.
    pub constant: bool,
}

/// The schedule of `root` as steps: children before parents, the root last.
pub fn steps(graph: &Graph, root: NodeId) -> Vec<Step> {
    let schedule = graph.schedule(root);
    // The step of each argument, found in the schedule (sorted by id).
    let step_of = |id: &NodeId| schedule.binary_search(id).unwrap_or(usize::MAX);
    let mut steps = Vec::with_capacity(schedule.len());
    for id in &schedule {
        let node = graph.node(*id);
        steps.push(Step {
            op: node.op.clone(),
            args: node.args.iter().map(step_of).collect(),
            width: node.width,
            constant: matches!(node.op, Op::Const(_)),
        });
    }
    steps
}

/// An instance of a tree being rendered: its buffers, states and position.
pub struct Interpreter {
    steps: Vec<Step>,
    /// Lanes of each step (for kernels' arguments).
    widths: Vec<usize>,
    buffers: Vec<Vec<f64>>,
    states: Vec<State>,
    config: RenderConfig,
    /// Samples rendered so far: the instance's local sample counter.
    position: u64,
}

/// Per-node state of stateful nodes (and a combine's scratch), made by [`new_state`].
enum State {
    None,
    Phase(Vec<f64>),
    Conv(Vec<Convolver>),
    /// A combine's sum of its odd lanes, beside the even ones in its output.
    OddSum(Vec<f64>),
    /// A timer's fade-in per lane, in seconds, decided at its first sample (NaN
    /// before).
    FadeIn(Vec<f64>),
    /// A stateful kernel's own state, or a host node's.
    Kernel(Box<dyn Any + Send>),
}

impl Interpreter {
    /// Prepares `root` of `graph` for rendering from t = 0. Impulse-response trees of
    /// convolutions are rendered here.
    pub fn new(graph: &Graph, root: NodeId, config: RenderConfig) -> Self {
        let config = RenderConfig {
            sample_rate: config.sample_rate,
            block_size: config.block_size.max(1),
        };
        let steps = steps(graph, root);
        let bs = config.block_size;
        let buffers = steps
            .iter()
            .map(|step| match &step.op {
                Op::Const(values) => {
                    // Lane by lane, each value a block long.
                    let mut buffer = Vec::with_capacity(values.len() * bs);
                    for &v in values.iter() {
                        buffer.resize(buffer.len() + bs, v);
                    }
                    buffer
                }
                _ => vec![0.0; step.width * bs],
            })
            .collect();
        let states = steps
            .iter()
            .map(|step| new_state(graph, step, config))
            .collect();
        let widths = steps.iter().map(|s| s.width).collect();
        Interpreter {
            steps,
            widths,
            buffers,
            states,
            config,
            position: 0,
        }
    }

    pub fn config(&self) -> RenderConfig {
        self.config
    }

    /// Samples rendered so far.
    pub fn position(&self) -> u64 {
        self.position
    }

    /// Renders the next `out.len()` samples of the root (which must be one lane).
    pub fn render(&mut self, out: &mut [f64]) {
        for chunk in out.chunks_mut(self.config.block_size) {
            self.render_block(chunk.len());
            chunk.copy_from_slice(self.root_output(chunk.len()));
        }
    }

    /// Lanes of the root: the frames [`Interpreter::render_frames`] writes.
    pub fn root_width(&self) -> usize {
        self.steps.last().map_or(1, |s| s.width)
    }

    /// Renders the next `out.len() / root_width` samples of every lane of the root,
    /// interleaved (frame after frame).
    pub fn render_frames(&mut self, out: &mut [f64]) {
        let width = self.root_width();
        for chunk in out.chunks_mut(self.config.block_size * width) {
            let n = chunk.len() / width;
            self.render_block(n);
            self.interleave_root(n, chunk);
        }
    }

    /// The root's first `n` samples of the current block, frame after frame.
    pub fn interleave_root(&self, n: usize, out: &mut [f64]) {
        let width = self.root_width();
        let bs = self.config.block_size;
        let root = &self.buffers[self.buffers.len() - 1];
        for lane in 0..width {
            for (k, x) in root[lane * bs..lane * bs + n].iter().enumerate() {
                out[k * width + lane] = *x;
            }
        }
    }

    /// Renders `n ≤ block_size` samples into the node buffers.
    fn render_block(&mut self, n: usize) {
        for i in 0..self.steps.len() {
            if !self.steps[i].constant {
                self.eval_step(i, n);
            }
        }
        self.position += n as u64;
    }

    // ------------------------------------------------------------------------
    // Support for compiled engines. An engine may compute some steps itself
    // (writing their buffers through `buffer_pointers`) and have the interpreter
    // compute the others with `eval_step`, so every node has one definition.

    /// The schedule: step `i`'s arguments are earlier steps; the last step is the root.
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// Where each step's buffer starts: `width × block_size` samples, lane after lane.
    /// The pointers stay valid for the interpreter's lifetime (buffers never move).
    pub fn buffer_pointers(&mut self) -> Vec<*mut f64> {
        self.buffers.iter_mut().map(|b| b.as_mut_ptr()).collect()
    }

    /// Computes the next `n ≤ block_size` samples of step `i` from its arguments'
    /// buffers. The caller ends the block with [`Interpreter::advance`].
    pub fn eval_step(&mut self, i: usize, n: usize) {
        // Take the output buffer out so the children's buffers can be borrowed; the
        // heap allocation itself does not move.
        let mut out = std::mem::take(&mut self.buffers[i]);
        let mut state = std::mem::replace(&mut self.states[i], State::None);
        self.eval(i, n, &mut out, &mut state);
        self.buffers[i] = out;
        self.states[i] = state;
    }

    /// Ends a block of `n` samples computed step by step.
    pub fn advance(&mut self, n: usize) {
        self.position += n as u64;
    }

    /// The root's first `n` samples of the current block.
    pub fn root_output(&self, n: usize) -> &[f64] {
        &self.buffers[self.buffers.len() - 1][..n]
    }

    /// Lane `lane` of argument `arg` of step `i`, broadcasting one-lane arguments.
    fn arg(&self, i: usize, arg: usize, lane: usize, n: usize) -> &[f64] {
        let step = self.steps[i].args[arg];
        let lane = if self.steps[step].width == 1 { 0 } else { lane };
        let bs = self.config.block_size;
        &self.buffers[step][lane * bs..lane * bs + n]
    }

    fn eval(&self, i: usize, n: usize, out: &mut [f64], state: &mut State) {
        let step = &self.steps[i];
        let bs = self.config.block_size;
        let sr = self.config.sample_rate;
        let n0 = self.position;
        let width = step.width;
        for lane in 0..width {
            let o = &mut out[lane * bs..lane * bs + n];
            match (&step.op, &mut *state) {
                (Op::Const(_), _) => unreachable!("constants are filled once"),
                (Op::Time, _) => {
                    for (k, y) in o.iter_mut().enumerate() {
                        *y = crate::op::sample_time(n0 + k as u64, sr);
                    }
                }
                (Op::Unary(op), _) => {
                    for (y, x) in o.iter_mut().zip(self.arg(i, 0, lane, n)) {
                        *y = op.apply(*x);
                    }
                }
                (Op::Binary(op), _) => {
                    let (a, b) = (self.arg(i, 0, lane, n), self.arg(i, 1, lane, n));
                    for k in 0..n {
                        o[k] = op.apply(a[k], b[k]);
                    }
                }
                (Op::Ternary(op), _) => {
                    let (a, b, c) = (
                        self.arg(i, 0, lane, n),
                        self.arg(i, 1, lane, n),
                        self.arg(i, 2, lane, n),
                    );
                    for k in 0..n {
                        o[k] = op.apply(a[k], b[k], c[k]);
                    }
                }
                (Op::Noise { seeds }, _) => {
                    let seed = seeds[lane];
                    for (y, x) in o.iter_mut().zip(self.arg(i, 0, lane, n)) {
                        *y = noise(seed, *x);
                    }
                }
                (Op::Variable(variable), _) => o.fill(variable.get()),
                (Op::Keyframe(track), _) => {
                    for (y, x) in o.iter_mut().zip(self.arg(i, 0, lane, n)) {
                        *y = track.value(*x);
                    }
                }
                (
                    Op::Timer {
                        length,
                        fade_in,
                        fade_out,
                    },
                    State::FadeIn(decided),
                ) => {
                    let (x, t) = (self.arg(i, 0, lane, n), self.arg(i, 1, lane, n));
                    if n > 0 && decided[lane].is_nan() {
                        decided[lane] = fade_in.seconds(x[0]);
                    }
                    for k in 0..n {
                        o[k] = x[k] * timer_gain(t[k], *length, decided[lane], *fade_out);
                    }
                }
                (Op::Env, _) => {
                    let args: [&[f64]; 6] = std::array::from_fn(|a| self.arg(i, a, lane, n));
                    for k in 0..n {
                        o[k] = env(std::array::from_fn(|a| args[a][k]));
                    }
                }
                (Op::Combine, State::OddSum(odd)) => {
                    // Even and odd lanes summed apart, then added (`op::combine`).
                    let odd = &mut odd[..n];
                    o.fill(0.0);
                    odd.fill(0.0);
                    let src = step.args[0];
                    for l in 0..self.steps[src].width {
                        let sum: &mut [f64] = if l % 2 == 0 { o } else { odd };
                        for (y, x) in sum.iter_mut().zip(&self.buffers[src][l * bs..l * bs + n]) {
                            *y += x;
                        }
                    }
                    for (y, x) in o.iter_mut().zip(odd.iter()) {
                        *y += x;
                    }
                }
                (Op::Index, _) => {
                    let src = step.args[0];
                    let w = self.steps[src].width;
                    let idx = self.arg(i, 1, 0, n);
                    for k in 0..n {
                        o[k] = self.buffers[src][index_lane(idx[k], w) * bs + k];
                    }
                }
                (Op::Concat, _) => {
                    // Find which argument holds output lane `lane`.
                    let mut first = 0;
                    for &src in &step.args {
                        let w = self.steps[src].width;
                        if lane < first + w {
                            let l = lane - first;
                            o.copy_from_slice(&self.buffers[src][l * bs..l * bs + n]);
                            break;
                        }
                        first += w;
                    }
                }
                (Op::White { seeds }, _) => {
                    let seed = seeds[lane];
                    for (k, y) in o.iter_mut().enumerate() {
                        *y = white(seed, n0 + k as u64);
                    }
                }
                (Op::Phasor, State::Phase(phases)) => {
                    let freq = self.arg(i, 0, lane, n);
                    let phase = &mut phases[lane];
                    // A multiplication by the sample period, not a division by the
                    // rate: it is on the phase's critical path in compiled code.
                    let period = 1.0 / sr;
                    // A frequency that is not finite gives NaN at its sample and
                    // leaves the phase where it was, so the phasor recovers at once.
                    if step.args.len() == 1 {
                        // No offset: frac(φ + 0) is φ itself, as φ is in [0, 1).
                        for k in 0..n {
                            let advance = freq[k] * period;
                            o[k] = *phase + zero_or_nan(advance);
                            let advance = if advance.is_finite() { advance } else { 0.0 };
                            *phase = frac(*phase + advance);
                        }
                    } else {
                        let offset = self.arg(i, 1, lane, n);
                        for k in 0..n {
                            let advance = freq[k] * period;
                            o[k] = frac(*phase + offset[k]) + zero_or_nan(advance);
                            let advance = if advance.is_finite() { advance } else { 0.0 };
                            *phase = frac(*phase + advance);
                        }
                    }
                }
                (Op::Conv(_), State::Conv(convolvers)) => {
                    convolvers[lane].process(self.arg(i, 0, lane, n), o);
                }
                (Op::Stateful(kernel), State::Kernel(kernel_state)) => {
                    // Kernels fill all lanes at once.
                    let inputs = Inputs {
                        buffers: &self.buffers,
                        widths: &self.widths,
                        args: &step.args,
                        stride: bs,
                        n,
                        sample_rate: sr,
                        first_sample: n0,
                    };
                    let mut outputs = Outputs {
                        samples: out,
                        stride: bs,
                        n,
                        width,
                    };
                    kernel.process(kernel_state.as_mut(), &inputs, &mut outputs);
                    return;
                }
                // `new_state` makes the state of every op above, so a node
                // added later cannot reach this: it is a kernel.
                (op, _) => unreachable!("state of `{op}` was not prepared"),
            }
        }
    }
}

/// The state of a step: every op is listed, so a new op must say what it needs.
fn new_state(graph: &Graph, step: &Step, config: RenderConfig) -> State {
    let w = step.width;
    let sr = config.sample_rate;
    match &step.op {
        Op::Phasor => State::Phase(vec![0.0; w]),
        Op::Combine => State::OddSum(vec![0.0; config.block_size]),
        Op::Timer { .. } => State::FadeIn(vec![f64::NAN; w]),
        Op::Conv(response) => {
            let ir = match response {
                ImpulseResponse::Wav { data, .. } => resample(data, sr),
                ImpulseResponse::Tree { root, seconds } => {
                    render_impulse(graph, *root, *seconds, config)
                }
            };
            State::Conv(
                (0..w)
                    .map(|_| Convolver::new(&ir, CONV_PARTITION))
                    .collect(),
            )
        }
        Op::Stateful(kernel) => State::Kernel(kernel.new_state(&StateContext { width: w, config })),
        Op::Const(_)
        | Op::Time
        | Op::Unary(_)
        | Op::Binary(_)
        | Op::Ternary(_)
        | Op::Noise { .. }
        | Op::Env
        | Op::Index
        | Op::Concat
        | Op::White { .. }
        | Op::Variable(_)
        | Op::Keyframe(_) => State::None,
    }
}

/// Renders an impulse-response tree from t = 0 for `seconds`.
fn render_impulse(graph: &Graph, root: NodeId, seconds: f64, config: RenderConfig) -> Vec<f64> {
    let len = (seconds * config.sample_rate).round() as usize;
    let mut ir = vec![0.0; len];
    Interpreter::new(graph, root, config).render(&mut ir);
    ir
}

/// Where a sample that is not finite (±∞ or NaN) came from: the node that first
/// produced one from arguments that were all finite until then, and the instance's
/// sample where it did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NonFiniteOrigin {
    pub node: NodeId,
    /// Samples from the instance's first.
    pub sample: u64,
}

/// Finds where the first sample of `root` that is not finite, at or before the
/// instance's sample `until`, came from: renders `root` with the interpreter up to
/// there, noting each node's first sample that is not finite, then walks down from
/// the root through the arguments that went bad first (at or before their parent)
/// to a node whose arguments were all finite until it went bad. A harmless ∞ off
/// that path (in `(min 1 (/ 1 0))`, say) is not blamed. `None` if every sample up to
/// `until` is finite.
pub fn trace_non_finite(
    graph: &Graph,
    root: NodeId,
    config: RenderConfig,
    until: u64,
) -> Option<NonFiniteOrigin> {
    let schedule = graph.schedule(root);
    let mut interp = Interpreter::new(graph, root, config);
    let bs = interp.config.block_size;
    let mut first_bad: Vec<Option<u64>> = vec![None; interp.steps.len()];
    let root_step = interp.steps.len() - 1;
    while interp.position <= until && first_bad[root_step].is_none() {
        let start = interp.position;
        let n = bs.min((until - start + 1) as usize);
        // Constants are filled once, at construction: they are checked like the rest.
        interp.render_block(n);
        for (i, buffer) in interp.buffers.iter().enumerate() {
            if first_bad[i].is_some() {
                continue;
            }
            let width = interp.steps[i].width;
            let bad = (0..width)
                .filter_map(|lane| {
                    let lane = &buffer[lane * bs..lane * bs + n];
                    lane.iter().position(|x| !x.is_finite())
                })
                .min();
            first_bad[i] = bad.map(|k| start + k as u64);
        }
    }
    let mut at = root_step;
    let mut sample = first_bad[at]?;
    loop {
        let earliest = interp.steps[at]
            .args
            .iter()
            .filter_map(|&a| first_bad[a].filter(|s| *s <= sample).map(|s| (s, a)))
            .min();
        match earliest {
            Some((s, arg)) => (at, sample) = (arg, s),
            None => {
                return Some(NonFiniteOrigin {
                    node: schedule[at],
                    sample,
                })
            }
        }
    }
}

/// `x − x`: 0 where `x` is finite, NaN where it is not. Added to a phasor's output, it
/// marks the sample whose step was not finite (the compiled phasor does the same).
#[allow(clippy::eq_op)]
#[inline]
fn zero_or_nan(x: f64) -> f64 {
    x - x
}
