//! The node catalogue: what each kind of timbre-tree node computes.
//!
//! Pure element-wise operations are evaluated by [`UnaryOp::apply`],
//! [`BinaryOp::apply`] and [`TernaryOp::apply`]; constant folding and the interpreter
//! both call these, so a folded constant is bit-identical to what the interpreter would
//! have computed at run time.

use std::f64::consts::TAU;
use std::fmt;
use std::sync::Arc;

use crate::custom::CustomNode;
use crate::dsp::envelope;
use crate::dsp::filter::BiquadKind;
use crate::dsp::noise::gradient_noise;
use crate::dsp::wav::SampleData;
use crate::keyframes::KeyframeTrack;

/// One node's operation. Arguments are the node's children, in order.
#[derive(Clone, Debug)]
pub enum Op {
    /// A constant vector; its length is the node's width.
    Const(Arc<[f64]>),
    /// `t`: the instance's local time in seconds, from a 64-bit sample counter.
    Time,
    Unary(UnaryOp),
    Binary(BinaryOp),
    Ternary(TernaryOp),
    /// Smooth gradient noise of the argument, seeded.
    Noise {
        seed: u64,
    },
    /// `(env x attack decay :hold h :attack-curve c :decay-curve c)`: six arguments.
    Env,
    /// Sum of all lanes of the argument.
    Combine,
    /// Lane `floor(i)` of the first argument (clamped to the lanes that exist).
    Index,
    /// Lanes of all arguments, one after the other.
    Concat,
    /// Per-sample uniform white noise in [-1, 1): a function of the sample index.
    White {
        seed: u64,
    },
    /// 1/f noise.
    Pink {
        seed: u64,
    },
    /// Second-order Markov low-frequency noise; argument: rate in Hz.
    Markov {
        seed: u64,
    },
    /// Integrated frequency in cycles, wrapped to [0, 1); arguments: frequency, start phase.
    Phasor,
    /// RBJ biquad; arguments: input, frequency, q.
    Biquad(BiquadKind),
    /// One-pole low-pass; arguments: input, cutoff.
    OnePole,
    /// Two-pole resonator with unit peak gain; arguments: input, frequency, bandwidth.
    Resonator,
    /// Variable fractional delay; arguments: input, delay time in seconds.
    Delay {
        max_seconds: f64,
    },
    /// FFT convolution of the argument with an impulse response.
    Conv(ImpulseResponse),
    /// A sampled sound; argument: playback rate (1 = original pitch).
    Sample(SamplePlayback),
    /// Gate-driven ADSR; arguments: gate, attack, decay, sustain, release.
    Adsr,
    /// sin(2π·F·τ)·e^(−D·τ); arguments τ (a time, one lane), constant F and D. A
    /// complex rotator, re-anchored exactly wherever τ jumps and every 512 samples.
    /// Made by [`crate::optimise`], never by lowering: it is a faster form of
    /// `(* (sine (* τ F)) (damp (* τ D)))`.
    DampedSine,
    /// A value the host sets while rendering, read at the start of each block.
    Variable(crate::lower::Variable),
    /// A keyframed variable: the track's value at the argument (scene time).
    Keyframe(Arc<KeyframeTrack>),
    /// An instance's timer: arguments the sound and its local time t; the sound times
    /// a gain that rises over `fade_in` from t = 0 and, if the instance has a length,
    /// falls over `fade_out` from t = length (silent after).
    Timer {
        length: Option<f64>,
        fade_in: f64,
        fade_out: f64,
    },
    /// A node implemented in Rust by the host.
    Custom(Arc<dyn CustomNode>),
}

/// Where a convolution's impulse response comes from.
#[derive(Clone, Debug)]
pub enum ImpulseResponse {
    /// Decoded from a WAV file (mono, at the file's own rate).
    Wav { path: String, data: Arc<SampleData> },
    /// A sub-tree rendered from t = 0 for `seconds` when the render starts.
    Tree { root: crate::NodeId, seconds: f64 },
}

#[derive(Clone, Debug)]
pub struct SamplePlayback {
    pub path: String,
    pub data: Arc<SampleData>,
    /// Where playback starts, in seconds of the file.
    pub start_seconds: f64,
    pub looping: bool,
}

impl Op {
    /// Whether the node keeps state from block to block (and so is never folded).
    pub fn is_stateful(&self) -> bool {
        matches!(
            self,
            Op::Pink { .. }
                | Op::Markov { .. }
                | Op::Phasor
                | Op::Biquad(_)
                | Op::OnePole
                | Op::Resonator
                | Op::Delay { .. }
                | Op::Conv(_)
                | Op::Sample(_)
                | Op::Adsr
                | Op::DampedSine
                | Op::Custom(_)
        )
    }

    /// A short name for pictures and debugging.
    pub fn name(&self) -> String {
        match self {
            Op::Const(values) if values.len() == 1 => format!("{}", values[0]),
            Op::Const(values) => format!("[{} lanes]", values.len()),
            Op::Time => "t".into(),
            Op::Unary(op) => op.name().into(),
            Op::Binary(op) => op.name().into(),
            Op::Ternary(op) => op.name().into(),
            Op::Noise { .. } => "noise".into(),
            Op::Env => "env".into(),
            Op::Combine => "combine".into(),
            Op::Index => "index".into(),
            Op::Concat => "vector".into(),
            Op::White { .. } => "white".into(),
            Op::Pink { .. } => "pink".into(),
            Op::Markov { .. } => "markov".into(),
            Op::Phasor => "phasor".into(),
            Op::Biquad(BiquadKind::Lowpass) => "lowpass".into(),
            Op::Biquad(BiquadKind::Highpass) => "highpass".into(),
            Op::Biquad(BiquadKind::Bandpass) => "bandpass".into(),
            Op::OnePole => "onepole".into(),
            Op::Resonator => "resonator".into(),
            Op::Delay { .. } => "delay".into(),
            Op::Conv(_) => "conv".into(),
            Op::Sample(s) => format!("sample {:?}", s.path),
            Op::Adsr => "adsr".into(),
            Op::DampedSine => "damped-sine".into(),
            Op::Keyframe(_) => "keyframe".into(),
            Op::Variable(_) => "variable".into(),
            Op::Timer { .. } => "timer".into(),
            Op::Custom(node) => node.name().into(),
        }
    }

    /// Feeds everything that distinguishes this op from another into `h`: two nodes
    /// with equal fingerprints and equal children are the same node.
    pub(crate) fn fingerprint(&self, h: &mut crate::graph::StableHasher) {
        let tag = |h: &mut crate::graph::StableHasher, t: u64| h.write_u64(t);
        match self {
            Op::Const(values) => {
                tag(h, 1);
                h.write_u64(values.len() as u64);
                for v in values.iter() {
                    h.write_u64(canonical_bits(*v));
                }
            }
            Op::Time => tag(h, 2),
            Op::Unary(op) => {
                tag(h, 3);
                h.write_u64(*op as u64);
            }
            Op::Binary(op) => {
                tag(h, 4);
                h.write_u64(*op as u64);
            }
            Op::Ternary(op) => {
                tag(h, 5);
                h.write_u64(*op as u64);
            }
            Op::Noise { seed } => {
                tag(h, 6);
                h.write_u64(*seed);
            }
            Op::Env => tag(h, 7),
            Op::Combine => tag(h, 8),
            Op::Index => tag(h, 9),
            Op::Concat => tag(h, 10),
            Op::White { seed } => {
                tag(h, 11);
                h.write_u64(*seed);
            }
            Op::Pink { seed } => {
                tag(h, 12);
                h.write_u64(*seed);
            }
            Op::Markov { seed } => {
                tag(h, 13);
                h.write_u64(*seed);
            }
            Op::Phasor => tag(h, 14),
            Op::Biquad(kind) => {
                tag(h, 15);
                h.write_u64(*kind as u64);
            }
            Op::OnePole => tag(h, 16),
            Op::Resonator => tag(h, 17),
            Op::Delay { max_seconds } => {
                tag(h, 18);
                h.write_u64(canonical_bits(*max_seconds));
            }
            Op::Conv(ImpulseResponse::Wav { path, .. }) => {
                tag(h, 19);
                h.write_str(path);
            }
            Op::Conv(ImpulseResponse::Tree { root, seconds }) => {
                tag(h, 20);
                h.write_u64(root.0 as u64);
                h.write_u64(canonical_bits(*seconds));
            }
            Op::Sample(s) => {
                tag(h, 21);
                h.write_str(&s.path);
                h.write_u64(canonical_bits(s.start_seconds));
                h.write_u64(s.looping as u64);
            }
            Op::Adsr => tag(h, 22),
            Op::DampedSine => tag(h, 24),
            Op::Variable(v) => {
                tag(h, 27);
                h.write_u64(v.address());
            }
            Op::Keyframe(track) => {
                tag(h, 25);
                h.write_u64(Arc::as_ptr(track) as usize as u64);
            }
            Op::Timer {
                length,
                fade_in,
                fade_out,
            } => {
                tag(h, 26);
                h.write_u64(length.map_or(u64::MAX, canonical_bits));
                h.write_u64(canonical_bits(*fade_in));
                h.write_u64(canonical_bits(*fade_out));
            }
            Op::Custom(node) => {
                tag(h, 23);
                h.write_str(node.name());
                h.write_u64(Arc::as_ptr(node) as *const () as usize as u64);
            }
        }
    }

    /// Structural equality of the op itself (children are compared separately).
    pub(crate) fn same_as(&self, other: &Op) -> bool {
        match (self, other) {
            (Op::Const(a), Op::Const(b)) => {
                a.len() == b.len()
                    && a.iter()
                        .zip(b.iter())
                        .all(|(x, y)| canonical_bits(*x) == canonical_bits(*y))
            }
            (Op::Time, Op::Time)
            | (Op::Env, Op::Env)
            | (Op::Combine, Op::Combine)
            | (Op::Index, Op::Index)
            | (Op::Concat, Op::Concat)
            | (Op::Phasor, Op::Phasor)
            | (Op::OnePole, Op::OnePole)
            | (Op::Resonator, Op::Resonator)
            | (Op::Adsr, Op::Adsr)
            | (Op::DampedSine, Op::DampedSine) => true,
            (Op::Unary(a), Op::Unary(b)) => a == b,
            (Op::Binary(a), Op::Binary(b)) => a == b,
            (Op::Ternary(a), Op::Ternary(b)) => a == b,
            (Op::Noise { seed: a }, Op::Noise { seed: b })
            | (Op::White { seed: a }, Op::White { seed: b })
            | (Op::Pink { seed: a }, Op::Pink { seed: b })
            | (Op::Markov { seed: a }, Op::Markov { seed: b }) => a == b,
            (Op::Biquad(a), Op::Biquad(b)) => a == b,
            (Op::Delay { max_seconds: a }, Op::Delay { max_seconds: b }) => {
                canonical_bits(*a) == canonical_bits(*b)
            }
            (
                Op::Conv(ImpulseResponse::Wav { data: a, .. }),
                Op::Conv(ImpulseResponse::Wav { data: b, .. }),
            ) => Arc::ptr_eq(a, b),
            (
                Op::Conv(ImpulseResponse::Tree {
                    root: a,
                    seconds: sa,
                }),
                Op::Conv(ImpulseResponse::Tree {
                    root: b,
                    seconds: sb,
                }),
            ) => a == b && canonical_bits(*sa) == canonical_bits(*sb),
            (Op::Sample(a), Op::Sample(b)) => {
                Arc::ptr_eq(&a.data, &b.data)
                    && canonical_bits(a.start_seconds) == canonical_bits(b.start_seconds)
                    && a.looping == b.looping
            }
            (Op::Custom(a), Op::Custom(b)) => Arc::ptr_eq(a, b),
            (Op::Keyframe(a), Op::Keyframe(b)) => Arc::ptr_eq(a, b),
            (Op::Variable(a), Op::Variable(b)) => a.same(b),
            (
                Op::Timer {
                    length: a,
                    fade_in: ai,
                    fade_out: ao,
                },
                Op::Timer {
                    length: b,
                    fade_in: bi,
                    fade_out: bo,
                },
            ) => {
                a.map(canonical_bits) == b.map(canonical_bits)
                    && canonical_bits(*ai) == canonical_bits(*bi)
                    && canonical_bits(*ao) == canonical_bits(*bo)
            }
            _ => false,
        }
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

/// Element-wise functions of one argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnaryOp {
    Neg,
    Exp,
    Log,
    Sqrt,
    Abs,
    Sin,
    Cos,
    Tan,
    Tanh,
    Floor,
    Frac,
    Not,
    /// sin(2πx): phase in cycles.
    Sine,
    Sawtooth,
    Square,
    Triangle,
    /// e^(-x).
    Damp,
}

impl UnaryOp {
    /// Every variant, in declaration order: `ALL[op as usize] == op`.
    pub const ALL: &[UnaryOp] = &[
        UnaryOp::Neg,
        UnaryOp::Exp,
        UnaryOp::Log,
        UnaryOp::Sqrt,
        UnaryOp::Abs,
        UnaryOp::Sin,
        UnaryOp::Cos,
        UnaryOp::Tan,
        UnaryOp::Tanh,
        UnaryOp::Floor,
        UnaryOp::Frac,
        UnaryOp::Not,
        UnaryOp::Sine,
        UnaryOp::Sawtooth,
        UnaryOp::Square,
        UnaryOp::Triangle,
        UnaryOp::Damp,
    ];

    pub fn name(self) -> &'static str {
        match self {
            UnaryOp::Neg => "-",
            UnaryOp::Exp => "exp",
            UnaryOp::Log => "log",
            UnaryOp::Sqrt => "sqrt",
            UnaryOp::Abs => "abs",
            UnaryOp::Sin => "sin",
            UnaryOp::Cos => "cos",
            UnaryOp::Tan => "tan",
            UnaryOp::Tanh => "tanh",
            UnaryOp::Floor => "floor",
            UnaryOp::Frac => "frac",
            UnaryOp::Not => "not",
            UnaryOp::Sine => "sine",
            UnaryOp::Sawtooth => "sawtooth",
            UnaryOp::Square => "square",
            UnaryOp::Triangle => "triangle",
            UnaryOp::Damp => "damp",
        }
    }

    #[inline]
    pub fn apply(self, x: f64) -> f64 {
        match self {
            UnaryOp::Neg => -x,
            UnaryOp::Exp => x.exp(),
            UnaryOp::Log => x.ln(),
            UnaryOp::Sqrt => x.sqrt(),
            UnaryOp::Abs => x.abs(),
            UnaryOp::Sin => x.sin(),
            UnaryOp::Cos => x.cos(),
            UnaryOp::Tan => x.tan(),
            UnaryOp::Tanh => x.tanh(),
            UnaryOp::Floor => x.floor(),
            UnaryOp::Frac => frac(x),
            UnaryOp::Not => truth(x == 0.0),
            // The fractional part is taken before scaling by 2π, so a phase of millions
            // of cycles keeps its full precision.
            UnaryOp::Sine => (TAU * frac(x)).sin(),
            UnaryOp::Sawtooth => 2.0 * frac(x) - 1.0,
            UnaryOp::Square => {
                if frac(x) < 0.5 {
                    1.0
                } else {
                    -1.0
                }
            }
            UnaryOp::Triangle => 4.0 * (frac(x + 0.75) - 0.5).abs() - 1.0,
            UnaryOp::Damp => (-x).exp(),
        }
    }
}

/// Element-wise functions of two arguments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinaryOp {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Min,
    Max,
    /// Floored modulo: the result has the sign of the divisor.
    Mod,
    Lt,
    Gt,
    Le,
    Ge,
    Eq,
    Ne,
    And,
    Or,
    /// `(pulse x width)`: 1 while frac(x) < width, else -1.
    Pulse,
}

impl BinaryOp {
    /// Every variant, in declaration order: `ALL[op as usize] == op`.
    pub const ALL: &[BinaryOp] = &[
        BinaryOp::Add,
        BinaryOp::Sub,
        BinaryOp::Mul,
        BinaryOp::Div,
        BinaryOp::Pow,
        BinaryOp::Min,
        BinaryOp::Max,
        BinaryOp::Mod,
        BinaryOp::Lt,
        BinaryOp::Gt,
        BinaryOp::Le,
        BinaryOp::Ge,
        BinaryOp::Eq,
        BinaryOp::Ne,
        BinaryOp::And,
        BinaryOp::Or,
        BinaryOp::Pulse,
    ];

    pub fn name(self) -> &'static str {
        match self {
            BinaryOp::Add => "+",
            BinaryOp::Sub => "-",
            BinaryOp::Mul => "*",
            BinaryOp::Div => "/",
            BinaryOp::Pow => "pow",
            BinaryOp::Min => "min",
            BinaryOp::Max => "max",
            BinaryOp::Mod => "mod",
            BinaryOp::Lt => "<",
            BinaryOp::Gt => ">",
            BinaryOp::Le => "<=",
            BinaryOp::Ge => ">=",
            BinaryOp::Eq => "=",
            BinaryOp::Ne => "!=",
            BinaryOp::And => "and",
            BinaryOp::Or => "or",
            BinaryOp::Pulse => "pulse",
        }
    }

    #[inline]
    pub fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            BinaryOp::Add => a + b,
            BinaryOp::Sub => a - b,
            BinaryOp::Mul => a * b,
            BinaryOp::Div => a / b,
            BinaryOp::Pow => a.powf(b),
            BinaryOp::Min => a.min(b),
            BinaryOp::Max => a.max(b),
            BinaryOp::Mod => a - b * (a / b).floor(),
            BinaryOp::Lt => truth(a < b),
            BinaryOp::Gt => truth(a > b),
            BinaryOp::Le => truth(a <= b),
            BinaryOp::Ge => truth(a >= b),
            BinaryOp::Eq => truth(a == b),
            BinaryOp::Ne => truth(a != b),
            BinaryOp::And => truth(a != 0.0 && b != 0.0),
            BinaryOp::Or => truth(a != 0.0 || b != 0.0),
            BinaryOp::Pulse => {
                if frac(a) < b {
                    1.0
                } else {
                    -1.0
                }
            }
        }
    }
}

/// Element-wise functions of three arguments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TernaryOp {
    /// `(clamp x lo hi)`.
    Clamp,
    /// `(if c a b)`: a where c ≠ 0, else b. Both branches are evaluated.
    If,
}

impl TernaryOp {
    pub fn name(self) -> &'static str {
        match self {
            TernaryOp::Clamp => "clamp",
            TernaryOp::If => "if",
        }
    }

    #[inline]
    pub fn apply(self, a: f64, b: f64, c: f64) -> f64 {
        match self {
            TernaryOp::Clamp => a.max(b).min(c),
            TernaryOp::If => {
                if a != 0.0 {
                    b
                } else {
                    c
                }
            }
        }
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

/// The gain of a timer at local time `t` (see [`Op::Timer`]).
#[inline]
pub fn timer_gain(t: f64, length: Option<f64>, fade_in: f64, fade_out: f64) -> f64 {
    if t < 0.0 {
        return 0.0;
    }
    let mut gain = if fade_in > 0.0 {
        (t / fade_in).min(1.0)
    } else {
        1.0
    };
    if let Some(length) = length {
        if t >= length + fade_out {
            return 0.0;
        }
        if t >= length {
            gain = gain.min(if fade_out > 0.0 {
                (length + fade_out - t) / fade_out
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
