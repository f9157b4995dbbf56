//! Limits on what a script may ask for, set by the host (or the command line's
//! defaults), each answered with a diagnostic before anything is allocated.
//!
//! Lowering counts nodes, lanes, named-tree expansions and include depth as it goes.
//! The cost of rendering is known before the first sample: [`check_render`] sums, over
//! the sounds to render, the memory their states need (delay lines, convolutions,
//! buffers: [`state_bytes`]) and their lane-samples (lanes × samples), and refuses a
//! render beyond the limits with the node that needs the most, deterministically.

use std::time::Duration;

use crate::graph::{Graph, NodeId};
use crate::interp::RenderConfig;
use crate::kernel::StateContext;
use crate::op::{ImpulseResponse, Op};
use timbre_diag::{Diag, Diagnostics};

/// The most bytes a script may have read from one file (256 MiB): a 23-minute stereo
/// 48 kHz 32-bit sound. Checked before reading, so `(include "/dev/zero")` or a huge
/// file is an error, not a render that runs out of memory.
pub const MAX_FILE_BYTES: u64 = 256 << 20;

/// What a script may ask for. [`Limits::default`] suits a host running untrusted
/// scripts and the command line; [`Limits::none`] lifts them all.
#[derive(Clone, Debug, PartialEq)]
pub struct Limits {
    /// Bytes of one script file (a scene, a library, an include): parsing takes about
    /// 200 bytes of memory per byte of a file of numbers. Never more than
    /// [`MAX_FILE_BYTES`].
    pub source_bytes: u64,
    /// Nodes of the lowered graph, after named trees are expanded.
    pub nodes: usize,
    /// Expansions of named trees while lowering.
    pub expansions: usize,
    /// Lanes of one node (never more than 2¹⁶).
    pub lanes: usize,
    /// Lanes of all nodes together.
    pub total_lanes: usize,
    /// Files included within files included within … the first.
    pub include_depth: usize,
    /// Bytes of state for the sounds playing at once (delay lines, convolutions,
    /// buffers), estimated before rendering.
    pub memory: u64,
    /// Degrees of freedom of one modal analysis (a `modal` node, an object of a
    /// `contacts` form's `:modal`): a solid cube of 150 000 takes about two minutes
    /// and 2 GiB to solve. A shape the default voxel would take past it is solved on
    /// a coarser grid; one whose given voxel would, is refused before anything is
    /// allocated.
    pub modal_dofs: usize,
    /// Instances of a scene.
    pub instances: usize,
    /// Seconds rendered.
    pub duration: f64,
    /// Samples per second.
    pub sample_rate: f64,
    /// Lane-samples rendered: for each sound, its lanes (all its nodes' together)
    /// times the samples it plays. About a second's work per 10⁹ in compiled code.
    pub lane_samples: f64,
    /// Wall-clock time one render call may take (none by default).
    pub render_time: Option<Duration>,
    /// Wall-clock time loading a script may take: reading and lowering its forms,
    /// expanding named trees, making a score's notes, reading frames and tables
    /// (none by default). Checked at each expression, form, frame, table row and
    /// every few thousand beats, so a load stops soon after it.
    pub load_time: Option<Duration>,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            source_bytes: 8 << 20,
            nodes: 1 << 22,
            expansions: 1 << 18,
            lanes: crate::program::MAX_LANES,
            total_lanes: 1 << 24,
            include_depth: 64,
            memory: 2 << 30,
            modal_dofs: 150_000,
            instances: 100_000,
            duration: 24.0 * 3600.0,
            sample_rate: 768_000.0,
            lane_samples: 1e12,
            render_time: None,
            load_time: None,
        }
    }
}

impl Limits {
    /// Bytes a script file may have: [`Limits::source_bytes`], at most
    /// [`MAX_FILE_BYTES`].
    pub fn script_bytes(&self) -> u64 {
        self.source_bytes.min(MAX_FILE_BYTES)
    }

    /// No limit but the hard ones (2¹⁶ lanes per node, the parser's nesting depth).
    pub fn none() -> Self {
        Limits {
            source_bytes: MAX_FILE_BYTES,
            nodes: usize::MAX,
            expansions: usize::MAX,
            lanes: crate::program::MAX_LANES,
            total_lanes: usize::MAX,
            include_depth: usize::MAX,
            memory: u64::MAX,
            modal_dofs: usize::MAX,
            instances: usize::MAX,
            duration: f64::INFINITY,
            sample_rate: f64::INFINITY,
            lane_samples: f64::INFINITY,
            render_time: None,
            load_time: None,
        }
    }
}

/// Estimated bytes per lane per impulse-response sample of a partitioned
/// convolution: the response's spectra and the input's, complex, with padding.
const CONV_BYTES_PER_SAMPLE: u64 = 64;

/// What rendering `root` costs: the bytes of its state and output buffers, its lanes
/// (all its nodes' together), and the node whose state is largest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cost {
    pub bytes: u64,
    pub lanes: u64,
    pub largest: Option<(NodeId, u64)>,
}

/// The state a node's kernel needs at `config`, in bytes (an estimate from its
/// configuration, made without allocating it).
fn node_bytes(graph: &Graph, id: NodeId, config: RenderConfig) -> u64 {
    let node = graph.node(id);
    let lanes = node.width as u64;
    let sr = config.sample_rate;
    let samples = |seconds: f64| (seconds.max(0.0) * sr).ceil().min(1e18) as u64;
    match &node.op {
        Op::Stateful(kernel) => kernel.memory(&StateContext {
            width: node.width,
            config,
        }),
        Op::Conv(response) => {
            let length = match response {
                ImpulseResponse::Wav { data, .. } => {
                    samples(data.frames.len() as f64 / data.sample_rate)
                }
                ImpulseResponse::Tree { seconds, .. } => samples(*seconds),
            };
            length
                .saturating_mul(8)
                .saturating_add(length.saturating_mul(lanes * CONV_BYTES_PER_SAMPLE))
        }
        _ => 0,
    }
}

/// The cost of rendering `root` of `graph` (see [`Cost`]).
pub fn state_bytes(graph: &Graph, root: NodeId, config: RenderConfig) -> Cost {
    let mut cost = Cost {
        bytes: 0,
        lanes: 0,
        largest: None,
    };
    let block = config.block_size.max(1) as u64;
    for id in graph.schedule(root) {
        let lanes = graph.width(id) as u64;
        let state = node_bytes(graph, id, config);
        cost.lanes = cost.lanes.saturating_add(lanes);
        // Its output buffer, and its state.
        cost.bytes = (cost.bytes)
            .saturating_add(lanes.saturating_mul(block * 8))
            .saturating_add(state);
        if state > 0 && cost.largest.is_none_or(|(_, b)| state > b) {
            cost.largest = Some((id, state));
        }
    }
    cost
}

/// A sound to render: its root, and the samples it plays from its first.
#[derive(Clone, Copy, Debug)]
pub struct Playing {
    pub root: NodeId,
    /// Scene sample of its first sample.
    pub start: u64,
    /// Samples it plays (to the scene's end if it has no stop).
    pub samples: u64,
}

fn bytes_text(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// A diagnostic about node `id`, labelled at its call when the graph knows it.
fn at_node(graph: &Graph, id: Option<NodeId>, diag: Diag, label: &str) -> Diag {
    match id.and_then(|id| graph.origin(id)) {
        Some(origin) => diag.label(origin.span, label).in_source(&origin.source),
        None => diag,
    }
}

/// Checks, before rendering, that the sounds `playing` of `graph` at `config` stay
/// within `limits`: their number, the memory of those playing at once (the most at
/// any sample, counting each from its start for its samples), and the lane-samples of
/// all of them.
///
/// Returns the most memory held at once, in bytes, having checked that the system
/// can give that much (see [`can_allocate`]).
pub fn check_render(
    graph: &Graph,
    playing: &[Playing],
    config: RenderConfig,
    limits: &Limits,
) -> Result<u64, Diagnostics> {
    if playing.len() > limits.instances {
        return Err(Diagnostics::one(
            Diag::new(
                "timbre::too-many-instances",
                format!(
                    "the scene has {} instances, more than the limit of {}",
                    playing.len(),
                    limits.instances
                ),
            )
            .help("render fewer instances, or relax the limit (--no-limits)"),
        ));
    }
    let costs: Vec<Cost> = playing
        .iter()
        .map(|p| state_bytes(graph, p.root, config))
        .collect();
    // Memory: the most held at once, from a sweep over starts and ends.
    let mut events: Vec<(u64, bool, usize)> = Vec::with_capacity(2 * playing.len());
    for (k, p) in playing.iter().enumerate() {
        events.push((p.start, true, k));
        events.push((p.start.saturating_add(p.samples.max(1)), false, k));
    }
    // Ends before starts at the same sample.
    events.sort_by_key(|&(at, starts, k)| (at, starts, k));
    let (mut held, mut most, mut most_at) = (0u64, 0u64, None);
    for &(_, starts, k) in &events {
        if starts {
            held = held.saturating_add(costs[k].bytes);
            if held > most {
                (most, most_at) = (held, Some(k));
            }
        } else {
            held = held.saturating_sub(costs[k].bytes);
        }
    }
    if most > limits.memory {
        let k = most_at.unwrap_or(0);
        let largest = costs[k].largest;
        let mut message = format!(
            "rendering needs about {} of memory at once, more than the limit of {}",
            bytes_text(most),
            bytes_text(limits.memory)
        );
        if let Some((_, bytes)) = largest {
            message.push_str(&format!("; this node alone needs {}", bytes_text(bytes)));
        }
        let diag = Diag::new("timbre::too-much-memory", message).help(
            "shorten the longest delay (:max) or impulse response, use fewer lanes, \
             or relax the limit (--no-limits)",
        );
        let label = "needs the most";
        return Err(Diagnostics::one(at_node(
            graph,
            largest.map(|(id, _)| id),
            diag,
            label,
        )));
    }
    let work: f64 = (playing.iter().zip(&costs))
        .map(|(p, c)| c.lanes as f64 * p.samples as f64)
        .sum();
    if work > limits.lane_samples {
        let widest = (playing.iter().zip(&costs))
            .max_by(|a, b| {
                let w = |(p, c): &(&Playing, &Cost)| c.lanes as f64 * p.samples as f64;
                w(a).total_cmp(&w(b))
            })
            .map(|(p, _)| p.root);
        let diag = Diag::new(
            "timbre::too-much-work",
            format!(
                "rendering would compute {work:.2e} lane-samples (lanes × samples), more than \
                 the limit of {:.2e}",
                limits.lane_samples
            ),
        )
        .help("render fewer seconds or fewer lanes, or relax the limit (--no-limits)");
        return Err(Diagnostics::one(at_node(
            graph,
            widest,
            diag,
            "the most work",
        )));
    }
    can_allocate(most)?;
    Ok(most)
}

/// Whether the system can give `bytes` now: asks for them without touching them
/// (zeroed memory is mapped lazily) and gives them back, so that a render the limits
/// allow but the machine cannot hold is a diagnostic rather than an abort in the
/// middle of making its states.
pub fn can_allocate(bytes: u64) -> Result<(), Diagnostics> {
    let refused = || {
        Diagnostics::one(
            Diag::new(
                "timbre::out-of-memory",
                format!(
                    "rendering needs about {} of memory, which the system cannot give",
                    bytes_text(bytes)
                ),
            )
            .help("shorten the longest delay or impulse response, or use fewer lanes"),
        )
    };
    let bytes = usize::try_from(bytes).map_err(|_| refused())?;
    let mut probe: Vec<u8> = Vec::new();
    probe.try_reserve_exact(bytes).map_err(|_| refused())?;
    Ok(())
}

/// Checks a render's length and rate against `limits`.
pub fn check_length(seconds: f64, sample_rate: f64, limits: &Limits) -> Result<(), Diagnostics> {
    // NaN is refused too.
    let within = |x: f64, limit: f64| x <= limit;
    if !within(sample_rate, limits.sample_rate) {
        return Err(Diagnostics::one(
            Diag::new(
                "timbre::rate-too-high",
                format!(
                    "a sample rate of {sample_rate} Hz is above the limit of {} Hz",
                    limits.sample_rate
                ),
            )
            .help("use a rate such as 48000 or 96000, or relax the limit (--no-limits)"),
        ));
    }
    if !within(seconds, limits.duration) {
        return Err(Diagnostics::one(
            Diag::new(
                "timbre::too-long",
                format!(
                    "a render of {seconds} s is longer than the limit of {} s",
                    limits.duration
                ),
            )
            .help("render a shorter :duration, or relax the limit (--no-limits)"),
        ));
    }
    Ok(())
}
