//! The render half of a program: the graph of its trees, the roots of its sounds, its
//! instances and settings, and the variables a host sets while it plays. The language
//! (`timbre-lang`) makes a [`Program`]; engines render one.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use crate::graph::{Graph, NodeId};
use crate::op::Op;
use crate::space::LateBus;

/// Most lanes one node may have.
pub const MAX_LANES: usize = 1 << 16;
/// Fade-in at an instance's start (where its first sample is not zero) and fade-out
/// at its stop, in seconds.
pub const DECLICK_IN: f64 = 0.001;
pub const DECLICK_OUT: f64 = 0.005;

/// Render settings a file may give with `(scene :sample-rate … :duration … :seed …)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Settings {
    pub sample_rate: Option<f64>,
    pub duration: Option<f64>,
    pub seed: u64,
    /// Output channels of a scene (`:channels`); None means mono.
    pub channels: Option<usize>,
    /// What the channels are, for a file's header.
    pub layout: ChannelLayout,
}

/// What a scene's output channels carry, declared in the files it is written to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ChannelLayout {
    /// Channels without a declared meaning: mono, a microphone pair, microphones.
    #[default]
    Plain,
    /// AmbiX of this order: (order + 1)² channels in ACN order, SN3D normalised.
    Ambisonics(usize),
    /// Loudspeaker feeds, in the WAV standard's channel order.
    Speakers(crate::space::layouts::Layout),
}

impl ChannelLayout {
    /// The channel mask of a WAVE_FORMAT_EXTENSIBLE header, if the layout needs one:
    /// 0 for Ambisonics (channels that feed no loudspeaker, as AmbiX files declare).
    pub fn wav_channel_mask(self) -> Option<u32> {
        match self {
            ChannelLayout::Plain => None,
            ChannelLayout::Ambisonics(_) => Some(0),
            ChannelLayout::Speakers(layout) => Some(layout.wav_channel_mask()),
        }
    }
}

/// What there is to render: the trees, the file's sound or its scene's instances, and
/// the render settings.
#[derive(Clone, Debug)]
pub struct Program {
    pub graph: Graph,
    /// The file's sound, if it has one (a library of definitions has none).
    pub root: Option<NodeId>,
    pub settings: Settings,
    /// The scene's instances, in the order written (empty unless it is a scene).
    pub instances: Vec<Instance>,
    /// The late parts of the scene's rooms, each run once over what its instances
    /// send it (see [`Instance::send`]).
    pub buses: Vec<LateBus>,
}

impl Program {
    /// The roots of its sounds: the file's sound, or each instance of a scene.
    pub fn sound_roots(&self) -> impl Iterator<Item = NodeId> + '_ {
        self.root
            .into_iter()
            .chain(self.instances.iter().map(|i| i.root))
    }
}

/// One instance of a sound class in a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    pub name: String,
    /// The sound class it plays.
    pub class: String,
    /// The class tree with its parameters bound, gain applied, under its timer.
    pub root: NodeId,
    /// Scene time of its first sample, in seconds.
    pub start: f64,
    /// Scene time at which it is switched off (after the fade-out), if given.
    pub stop: Option<f64>,
    /// Seconds it may still be heard after its stop: the sound's longest way from
    /// its source to a receiver (its room's late part rings on in its bus, for
    /// [`LateBus::tail`] more).
    pub tail: f64,
    /// The bus (an index into [`Program::buses`]) its lanes after the channels'
    /// are sent to: one per receiver of its room's late part.
    pub send: Option<usize>,
    /// The stems it is heard in (`timbre render --stems`).
    pub stem: Stem,
}

/// Which stems an instance is heard in: the object that sounds and the kind of sound
/// (`"impacts"`, `"sliding"`, `"rolling"` for contacts), each `None` when unlabelled.
/// Whoever makes an instance sets it; it changes nothing that is rendered.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Stem {
    pub object: Option<Arc<str>>,
    pub kind: Option<Arc<str>>,
}

impl Instance {
    /// Its sound: the class tree with its parameters bound, as its timer lets it
    /// out (below the gain, routing and propagation the scene adds). Lowering puts
    /// every instance under a timer; an instance made otherwise, without one, is its
    /// root.
    pub fn sound(&self, graph: &Graph) -> NodeId {
        let mut pending = vec![self.root];
        while let Some(id) = pending.pop() {
            let node = graph.node(id);
            if matches!(node.op, Op::Timer { .. }) {
                return node.args[0];
            }
            pending.extend(node.args.iter().copied());
        }
        self.root
    }
}

/// A value the host sets while a sound plays, read by its voice at the start of each
/// block (so it changes on block boundaries, unless smoothed: see
/// [`Variable::with_lag`]). Setting it takes no lock, from any thread.
///
/// In a tree, a variable is known by the name of the parameter it is bound to, never
/// by its address, so random nodes that read it are seeded the same on every run.
#[derive(Clone, Debug)]
pub struct Variable {
    cell: Arc<AtomicU64>,
    name: Arc<str>,
    /// Smoothing time constant in seconds (0: none).
    lag: f64,
}

impl Variable {
    pub fn new(value: f64) -> Self {
        Variable {
            cell: Arc::new(AtomicU64::new(value.to_bits())),
            name: Arc::from(""),
            lag: 0.0,
        }
    }

    /// The same variable, read through exponential smoothing with time constant
    /// `seconds` (the `lag` node) by the instances it is bound to from now on, so a
    /// change glides over a few time constants instead of stepping at a block
    /// boundary (a step zippers). 0 turns smoothing off.
    pub fn with_lag(mut self, seconds: f64) -> Self {
        self.lag = if seconds.is_finite() {
            seconds.max(0.0)
        } else {
            0.0
        };
        self
    }

    /// The smoothing time constant, in seconds (0: none).
    pub fn lag(&self) -> f64 {
        self.lag
    }

    pub fn set(&self, value: f64) {
        self.cell.store(value.to_bits(), Ordering::Relaxed);
    }

    pub fn get(&self) -> f64 {
        f64::from_bits(self.cell.load(Ordering::Relaxed))
    }

    /// The name it is known by in a tree (the parameter it is bound to).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The same variable, known by `name`.
    pub fn named(&self, name: &str) -> Variable {
        Variable {
            cell: self.cell.clone(),
            name: Arc::from(name),
            lag: self.lag,
        }
    }
}
