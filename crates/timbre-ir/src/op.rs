//! What each kind of timbre-tree node computes (the names that call them are in
//! `timbre-lang`'s catalogue).
//!
//! Pure element-wise operations are evaluated by [`UnaryOp::apply`],
//! [`BinaryOp::apply`] and [`TernaryOp::apply`]; constant folding and the interpreter
//! both call these, so a folded constant is bit-identical to what the interpreter would
//! have computed at run time.

use std::f64::consts::TAU;
use std::fmt;
use std::sync::Arc;

use crate::custom::{CustomNode, HostKernel};
use crate::dsp::envelope;
use crate::dsp::noise::gradient_noise;
use crate::dsp::wav::SampleData;
use crate::kernel::DynKernel;
use crate::keyframes::KeyframeTrack;

/// One node's operation. Arguments are the node's children, in order.
///
/// The callable nodes are listed once, in `timbre-lang`'s catalogue; this enum is what
/// they lower to. Pure element-wise functions are [`UnaryOp`], [`BinaryOp`] and
/// [`TernaryOp`]; stateful nodes are [`Op::Stateful`] kernels, each in its own file
/// under `dsp/`. The other variants are the nodes engines treat specially.
#[derive(Clone, Debug)]
pub enum Op {
    /// A constant vector; its length is the node's width.
    Const(Arc<[f64]>),
    /// `t`: the instance's local time in seconds, from a 64-bit sample counter.
    Time,
    Unary(UnaryOp),
    Binary(BinaryOp),
    Ternary(TernaryOp),
    /// Smooth gradient noise of the argument: lane k with `seeds[k]` (consecutive:
    /// `(noise x :lanes n)` has seeds s, s + 1, …); the argument is one lane or as
    /// many as there are seeds.
    Noise {
        seeds: Arc<[u64]>,
    },
    /// `(env x attack decay :hold h :attack-curve c :decay-curve c)`: six arguments.
    Env,
    /// Sum of all lanes of the argument.
    Combine,
    /// Lane `floor(i)` of the first argument (clamped to the lanes that exist).
    Index,
    /// Lanes of all arguments, one after the other.
    Concat,
    /// Per-sample uniform white noise in [-1, 1): a function of the sample index;
    /// lane k hashes with `seeds[k]` (`(white :lanes n)` has seeds s, s + 1, …).
    White {
        seeds: Arc<[u64]>,
    },
    /// Integrated frequency in cycles, wrapped to [0, 1); arguments: frequency, start phase.
    Phasor,
    /// FFT convolution of the argument with an impulse response.
    Conv(ImpulseResponse),
    /// A stateful node: its kernel, and the configuration it was made with.
    Stateful(Arc<dyn DynKernel>),
    /// A value the host sets while rendering, read at the start of each block.
    Variable(crate::program::Variable),
    /// A keyframed variable: the track's value at the argument (scene time).
    Keyframe(Arc<KeyframeTrack>),
    /// An instance's timer: arguments the sound and its local time t; the sound times
    /// a gain that rises from t = 0 as `fade_in` says (decided per lane at the timer's
    /// first sample, see [`FadeIn::seconds`]) and, if the instance has a length,
    /// falls over `fade_out` from t = length (silent after).
    Timer {
        length: Option<f64>,
        fade_in: FadeIn,
        fade_out: f64,
    },
}

/// Where a convolution's impulse response comes from.
#[derive(Clone, Debug)]
pub enum ImpulseResponse {
    /// Decoded from a WAV file (mono, at the file's own rate).
    Wav { path: String, data: Arc<SampleData> },
    /// A sub-tree rendered from t = 0 for `seconds` when the render starts.
    Tree { root: crate::NodeId, seconds: f64 },
}

/// The canonical description of an op: a sequence of words that two ops share
/// exactly when they are the same node (given the same children). Node identity
/// (hash-consing) and the structural hash random seeds come from are both made of
/// it, so it never holds an address or anything else that changes between runs.
///
/// A description either keeps its words (to compare two ops) or only hashes them
/// (to fingerprint one, without allocating).
#[derive(Clone, Debug)]
pub struct Description(Words);

#[derive(Clone, Debug)]
enum Words {
    Kept(Vec<u64>),
    Hashed(crate::graph::StableHasher),
}

impl Default for Description {
    fn default() -> Self {
        Description(Words::Kept(Vec::new()))
    }
}

impl PartialEq for Description {
    fn eq(&self, other: &Self) -> bool {
        self.words() == other.words()
    }
}

impl Description {
    pub fn new() -> Self {
        Self::default()
    }

    /// A description that only feeds its words to `hasher`.
    pub(crate) fn hashing(hasher: crate::graph::StableHasher) -> Self {
        Description(Words::Hashed(hasher))
    }

    pub fn u64(&mut self, x: u64) -> &mut Self {
        match &mut self.0 {
            Words::Kept(words) => words.push(x),
            Words::Hashed(hasher) => hasher.write_u64(x),
        }
        self
    }

    /// A number, with -0.0 and every NaN made one value each.
    pub fn f64(&mut self, x: f64) -> &mut Self {
        self.u64(canonical_bits(x))
    }

    pub fn f64s(&mut self, xs: &[f64]) -> &mut Self {
        self.u64(xs.len() as u64);
        for x in xs {
            self.f64(*x);
        }
        self
    }

    pub fn str(&mut self, s: &str) -> &mut Self {
        self.u64(s.len() as u64);
        for chunk in s.as_bytes().chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.u64(u64::from_le_bytes(word));
        }
        self
    }

    /// The words kept (none for a hashing description).
    pub fn words(&self) -> &[u64] {
        match &self.0 {
            Words::Kept(words) => words,
            Words::Hashed(_) => &[],
        }
    }

    /// The hasher of a hashing description.
    pub(crate) fn into_hasher(self) -> Option<crate::graph::StableHasher> {
        match self.0 {
            Words::Hashed(hasher) => Some(hasher),
            Words::Kept(_) => None,
        }
    }
}

impl Op {
    /// A node implemented in Rust by the host: a stateful kernel like the built-in
    /// ones.
    pub fn custom(node: Arc<dyn CustomNode>) -> Op {
        Op::Stateful(Arc::new(HostKernel(node)))
    }

    /// Whether the node keeps state from block to block (and so is never folded).
    pub fn is_stateful(&self) -> bool {
        match self {
            Op::Phasor | Op::Conv(_) | Op::Stateful(_) => true,
            Op::Const(_)
            | Op::Time
            | Op::Unary(_)
            | Op::Binary(_)
            | Op::Ternary(_)
            | Op::Noise { .. }
            | Op::Env
            | Op::Combine
            | Op::Index
            | Op::Concat
            | Op::White { .. }
            | Op::Variable(_)
            | Op::Keyframe(_)
            | Op::Timer { .. } => false,
        }
    }

    /// A short name for pictures and debugging.
    pub fn name(&self) -> String {
        match self {
            Op::Const(values) if values.len() == 1 => format!("{}", values[0]),
            Op::Const(values) => format!("[{} lanes]", values.len()),
            Op::Stateful(kernel) => kernel.call_name().into(),
            _ => self.kind().into(),
        }
    }

    /// The op's kind: its catalogue name where it has one.
    pub fn kind(&self) -> &'static str {
        match self {
            Op::Const(_) => "const",
            Op::Time => "t",
            Op::Unary(op) => op.name(),
            Op::Binary(op) => op.name(),
            Op::Ternary(op) => op.name(),
            Op::Noise { .. } => "noise",
            Op::Env => "env",
            Op::Combine => "combine",
            Op::Index => "index",
            Op::Concat => "vector",
            Op::White { .. } => "white",
            Op::Phasor => "phasor",
            Op::Conv(_) => "conv",
            Op::Stateful(kernel) => kernel.name(),
            Op::Variable(_) => "variable",
            Op::Keyframe(_) => "keyframe",
            Op::Timer { .. } => "timer",
        }
    }

    /// Writes the op's canonical description (see [`Description`]).
    pub fn describe(&self, d: &mut Description) {
        d.str(self.kind());
        match self {
            Op::Const(values) => {
                d.f64s(values);
            }
            // One seed alone, as before noises had lanes (see `dsp::noise`).
            Op::Noise { seeds } => {
                for seed in seeds.iter() {
                    d.u64(*seed);
                }
                if seeds.len() > 1 {
                    d.u64(seeds.len() as u64);
                }
            }
            Op::White { seeds } => {
                for seed in seeds.iter() {
                    d.u64(*seed);
                }
                d.u64(seeds.len() as u64);
            }
            Op::Conv(ImpulseResponse::Wav { data, .. }) => {
                d.str("wav").u64(data.content_hash);
            }
            Op::Conv(ImpulseResponse::Tree { root, seconds }) => {
                d.str("tree").u64(root.0 as u64).f64(*seconds);
            }
            Op::Stateful(kernel) => kernel.describe(d),
            // A variable by the name of what it is bound to, never by its address.
            Op::Variable(variable) => {
                d.str(variable.name());
            }
            // A track by its content.
            Op::Keyframe(track) => {
                d.str(track.interpolation().name())
                    .f64s(track.times())
                    .f64s(track.values());
            }
            Op::Timer {
                length,
                fade_in,
                fade_out,
            } => {
                let (always, seconds) = match fade_in {
                    FadeIn::IfNotZero(s) => (0, s),
                    FadeIn::Always(s) => (1, s),
                };
                d.u64(length.is_some() as u64)
                    .f64(length.unwrap_or(0.0))
                    .u64(always)
                    .f64(*seconds)
                    .f64(*fade_out);
            }
            // The kind (an element-wise op by its name) says it all.
            Op::Time
            | Op::Unary(_)
            | Op::Binary(_)
            | Op::Ternary(_)
            | Op::Env
            | Op::Combine
            | Op::Index
            | Op::Concat
            | Op::Phasor => {}
        }
    }

    /// The op's canonical description.
    pub fn description(&self) -> Description {
        let mut d = Description::new();
        self.describe(&mut d);
        d
    }

    /// Feeds everything that distinguishes this op from another into `h`: two nodes
    /// with equal fingerprints and equal children are the same node.
    pub(crate) fn fingerprint(&self, h: &mut crate::graph::StableHasher) {
        let mut d = Description::hashing(std::mem::take(h));
        self.describe(&mut d);
        if let Some(hasher) = d.into_hasher() {
            *h = hasher;
        }
    }

    /// Structural equality of the op itself (children are compared separately).
    pub fn same_as(&self, other: &Op) -> bool {
        self.description() == other.description()
    }
}

/// The bits of a float with -0.0 and all NaNs made one value each, so hash-consing
/// treats equal numbers as equal.
fn canonical_bits(x: f64) -> u64 {
    if x == 0.0 {
        0
    } else if x.is_nan() {
        f64::NAN.to_bits()
    } else {
        x.to_bits()
    }
}

/// Declares an enum of element-wise functions: for each, its variant, its name in
/// the language and its formula, in one line. `ALL` lists the variants in order, so
/// `ALL[op as usize] == op`.
macro_rules! elementwise {
    (
        $(#[$meta:meta])*
        $enum:ident ($($x:ident),+) {
            $($(#[$doc:meta])* $variant:ident $name:literal => $formula:expr;)*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum $enum {
            $($(#[$doc])* $variant,)*
        }

        impl $enum {
            /// Every variant, in declaration order.
            pub const ALL: &'static [$enum] = &[$($enum::$variant),*];

            pub fn name(self) -> &'static str {
                match self {
                    $($enum::$variant => $name,)*
                }
            }

            #[inline]
            pub fn apply(self, $($x: f64),+) -> f64 {
                match self {
                    $($enum::$variant => $formula,)*
                }
            }
        }
    };
}

elementwise! {
    /// Element-wise functions of one argument.
    UnaryOp(x) {
        Neg "-" => -x;
        Exp "exp" => x.exp();
        Log "log" => x.ln();
        Sqrt "sqrt" => x.sqrt();
        Abs "abs" => x.abs();
        Sin "sin" => x.sin();
        Cos "cos" => x.cos();
        Tan "tan" => x.tan();
        Tanh "tanh" => x.tanh();
        Floor "floor" => x.floor();
        Frac "frac" => frac(x);
        Not "not" => truth(x == 0.0);
        /// sin(2πx): phase in cycles. The fractional part is taken before scaling
        /// by 2π, so a phase of millions of cycles keeps its full precision.
        Sine "sine" => (TAU * frac(x)).sin();
        Sawtooth "sawtooth" => 2.0 * frac(x) - 1.0;
        Square "square" => if frac(x) < 0.5 { 1.0 } else { -1.0 };
        Triangle "triangle" => 4.0 * (frac(x + 0.75) - 0.5).abs() - 1.0;
        /// e^(-x).
        Damp "damp" => (-x).exp();
        /// Decibels to amplitude: 10^(x/20).
        DbAmp "dbamp" => (x * (std::f64::consts::LN_10 / 20.0)).exp();
        /// Amplitude to decibels: 20·log10|x| (−∞ for 0).
        AmpDb "ampdb" => 20.0 * x.abs().log10();
        /// MIDI note number to Hz: 440·2^((x − 69)/12).
        MidiHz "midihz" => 440.0 * ((x - 69.0) / 12.0).exp2();
        /// Hz to MIDI note number: 69 + 12·log2(x/440).
        HzMidi "hzmidi" => 69.0 + 12.0 * (x / 440.0).log2();
    }
}

elementwise! {
    /// Element-wise functions of two arguments.
    BinaryOp(a, b) {
        Add "+" => a + b;
        Sub "-" => a - b;
        Mul "*" => a * b;
        Div "/" => a / b;
        Pow "pow" => a.powf(b);
        Min "min" => a.min(b);
        Max "max" => a.max(b);
        /// Floored modulo: the result has the sign of the divisor.
        Mod "mod" => a - b * (a / b).floor();
        Lt "<" => truth(a < b);
        Gt ">" => truth(a > b);
        Le "<=" => truth(a <= b);
        Ge ">=" => truth(a >= b);
        Eq "=" => truth(a == b);
        Ne "!=" => truth(a != b);
        And "and" => truth(a != 0.0 && b != 0.0);
        Or "or" => truth(a != 0.0 || b != 0.0);
        /// `(pulse x width)`: 1 while frac(x) < width, else -1.
        Pulse "pulse" => if frac(a) < b { 1.0 } else { -1.0 };
    }
}

elementwise! {
    /// Element-wise functions of three arguments.
    TernaryOp(a, b, c) {
        /// `(clamp x lo hi)`.
        Clamp "clamp" => a.max(b).min(c);
        /// `(if c a b)`: a where c ≠ 0, else b. Both branches are evaluated.
        If "if" => if a != 0.0 { b } else { c };
    }
}

/// x − floor(x), in [0, 1).
#[inline]
pub fn frac(x: f64) -> f64 {
    let f = x - x.floor();
    // x − floor(x) rounds up to exactly 1.0 for tiny negative x.
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

#[inline]
fn truth(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

/// The `combine` node: the sum of the even lanes plus the sum of the odd lanes, each
/// from 0 in lane order. (Two lanes side by side in a vector are summed this way.)
#[inline]
pub fn combine(lanes: &[f64]) -> f64 {
    let mut sums = [0.0; 2];
    for (l, x) in lanes.iter().enumerate() {
        sums[l % 2] += x;
    }
    sums[0] + sums[1]
}

/// Smooth noise as the `noise` node computes it.
#[inline]
pub fn noise(seed: u64, x: f64) -> f64 {
    gradient_noise(seed, x)
}

/// The `env` node: arguments x, attack, decay, hold, attack curve, decay curve.
#[inline]
pub fn env(args: [f64; 6]) -> f64 {
    let [x, attack, decay, hold, attack_curve, decay_curve] = args;
    envelope::env(x, attack, hold, decay, attack_curve, decay_curve)
}

impl fmt::Display for Op {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

/// `t` at sample `index` of a sound (counted from its first sample) at `rate`: the
/// one definition both engines use, wherever they compute it.
#[inline]
pub fn sample_time(index: u64, rate: f64) -> f64 {
    index as f64 / rate
}

/// A first sample below this (in magnitude) counts as zero for the default declick:
/// −80 dBFS, a step a few 16-bit quantisation steps high and inaudible, and far above
/// the rounding of a sine that should start at 0 (`sin π` is 1.2e-16).
pub const DECLICK_THRESHOLD: f64 = 1e-4;

/// How an instance's timer fades its sound in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FadeIn {
    /// Over these seconds in each lane whose first sample is not zero (at least
    /// [`DECLICK_THRESHOLD`]): a lane that starts at zero, as a strike does, needs no
    /// declick and plays from its first sample. The default, with `DECLICK_IN`.
    IfNotZero(f64),
    /// Over these seconds whatever the first sample; 0 is no fade at all.
    Always(f64),
}

impl FadeIn {
    /// The fade-in of a lane whose first sample is `first`, in seconds (0: none).
    /// Decided once, at the timer's first sample, by both engines.
    #[inline]
    pub fn seconds(self, first: f64) -> f64 {
        match self {
            FadeIn::IfNotZero(s) if first.abs() >= DECLICK_THRESHOLD => s,
            FadeIn::IfNotZero(_) => 0.0,
            FadeIn::Always(s) => s,
        }
    }
}

impl fmt::Display for FadeIn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FadeIn::IfNotZero(s) => write!(f, "{s:?} s unless it starts at 0"),
            FadeIn::Always(s) if *s == 0.0 => write!(f, "off"),
            FadeIn::Always(s) => write!(f, "{s:?} s"),
        }
    }
}

/// The gain of a timer at local time `t`, its fade-in decided (see [`Op::Timer`]).
#[inline]
pub fn timer_gain(t: f64, length: Option<f64>, fade_in: f64, fade_out: f64) -> f64 {
    if t < 0.0 {
        return 0.0;
    }
    // The fades as rates (1 / duration): a multiplication per sample, not a division.
    let mut gain = if fade_in > 0.0 {
        (t * (1.0 / fade_in)).min(1.0)
    } else {
        1.0
    };
    if let Some(length) = length {
        let end = length + fade_out;
        if t >= end {
            return 0.0;
        }
        if t >= length {
            gain = gain.min(if fade_out > 0.0 {
                (end - t) * (1.0 / fade_out)
            } else {
                0.0
            });
        }
    }
    gain
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_lists_every_op_at_its_discriminant() {
        for (i, op) in UnaryOp::ALL.iter().enumerate() {
            assert_eq!(*op as usize, i, "{op:?}");
        }
        for (i, op) in BinaryOp::ALL.iter().enumerate() {
            assert_eq!(*op as usize, i, "{op:?}");
        }
    }
}
