//! The node catalogue: every built-in node, declared once.
//!
//! An entry gives the node's name, its parameters (with defaults, which are also
//! its keyword names), whether it takes `:seed`, its width rule, whether it is pure
//! or stateful, the `lang-spec/nodes.md` section that defines it, and how it is
//! built. Everything that lists nodes derives from [`NODES`]: lowering, "did you
//! mean", reserved names, the REPL's completion, the fuzzer's arities, and the tidy
//! tests that hold every entry to a spec section, a conformance case and a place in
//! the random-tree generator.
//!
//! A pure element-wise node is a formula in [`crate::op`] plus an entry here; a
//! stateful node is a [`crate::kernel::StatefulKernel`] in its own file plus an
//! entry here. See "Adding a built-in node" in `docs/architecture.md`.

use std::sync::Arc;

use crate::dsp::blep::{BandLimited, Wave};
use crate::dsp::control::{Lag, Latch};
use crate::dsp::delay::{Allpass, Comb, Delay};
use crate::dsp::envelope::AdsrEnvelope;
use crate::dsp::filter::{Biquad, BiquadKind, OnePoleLowpass, Resonator};
use crate::dsp::noise::{hash2, MarkovNoise, PinkNoise};
use crate::error::Diag;
use crate::graph::NodeId;
use crate::lower::{Bound, Call, Lowerer, Origin, Scope, MAX_BUFFER_SECONDS, MAX_LANES};
use crate::op::{BinaryOp, Op, TernaryOp, UnaryOp};

pub use crate::lower::FORMS;

/// One parameter of a node: its keyword name and its default, if it has one.
#[derive(Clone, Copy, Debug)]
pub struct Param<'n> {
    pub name: &'n str,
    pub default: Option<f64>,
}

/// A required parameter.
pub const fn p(name: &'static str) -> Param<'static> {
    Param {
        name,
        default: None,
    }
}

/// An optional parameter with its default.
pub const fn opt(name: &'static str, default: f64) -> Param<'static> {
    Param {
        name,
        default: Some(default),
    }
}

/// What evaluating the node involves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A function of its arguments at the same sample (folded when they are constant).
    Pure,
    /// Keeps state from sample to sample.
    Stateful,
    /// Computed while lowering: its value is a constant.
    Constant,
}

/// How the output width follows from the arguments'.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Width {
    /// Arguments are one lane or all one width W (checked while lowering); the
    /// output is W lanes.
    Broadcast,
    /// The node's builder checks its arguments itself (see its section in nodes.md).
    Own,
}

/// How lowering makes the node from its bound arguments.
#[derive(Clone, Copy)]
pub(crate) enum Build {
    Unary(UnaryOp),
    Binary(BinaryOp),
    Ternary(TernaryOp),
    /// A left fold of a binary operation over one or more arguments.
    Fold(BinaryOp),
    /// Anything else, from arguments bound to the parameters.
    Args(fn(&mut Lowerer<'_>, &Bound<'_>) -> Result<NodeId, Diag>),
    /// A node that binds its own arguments (its first one is a file name).
    Form(fn(&mut Lowerer<'_>, &Call<'_>, &Origin, &mut Scope) -> Result<NodeId, Diag>),
}

/// One built-in node.
pub struct NodeSpec {
    pub name: &'static str,
    pub params: &'static [Param<'static>],
    /// The last parameter takes one or more arguments.
    pub variadic: bool,
    /// Takes `:seed K` for an independent copy.
    pub random: bool,
    pub kind: Kind,
    pub width: Width,
    /// The heading of the `lang-spec/nodes.md` section that defines it.
    pub section: &'static str,
    pub(crate) build: Build,
}

impl NodeSpec {
    const fn new(
        name: &'static str,
        params: &'static [Param<'static>],
        section: &'static str,
        build: Build,
    ) -> Self {
        NodeSpec {
            name,
            params,
            variadic: false,
            random: false,
            kind: Kind::Pure,
            width: Width::Broadcast,
            section,
            build,
        }
    }

    const fn variadic(mut self) -> Self {
        self.variadic = true;
        self
    }

    const fn random(mut self) -> Self {
        self.random = true;
        self
    }

    const fn stateful(mut self) -> Self {
        self.kind = Kind::Stateful;
        self
    }

    const fn constant(mut self) -> Self {
        self.kind = Kind::Constant;
        self
    }

    const fn own_width(mut self) -> Self {
        self.width = Width::Own;
        self
    }

    /// Arguments it takes at least, and at most (None: any number).
    pub fn arity(&self) -> (usize, Option<usize>) {
        let required = self.params.iter().filter(|p| p.default.is_none()).count();
        let max = (!self.variadic).then_some(self.params.len());
        (required, max)
    }
}

/// The built-in node called `name`.
pub fn lookup(name: &str) -> Option<&'static NodeSpec> {
    NODES.iter().find(|n| n.name == name)
}

/// Every built-in node's name, in catalogue order.
pub fn names() -> impl Iterator<Item = &'static str> {
    NODES.iter().map(|n| n.name)
}

const MATHS: &str = "Arithmetic and maths";
const LOGIC: &str = "Comparisons and logic";
const WAVES: &str = "Waveforms";
const BAND_LIMITED: &str = "Band-limited waveforms";
const LEVELS: &str = "Levels and pitches";
const NOISES: &str = "Noises";
const VECTORS: &str = "Vector nodes";
const FILTERS: &str = "Filters";
const DELAYS: &str = "Delays";
const CONTROL: &str = "Control";
const ENVELOPES: &str = "Envelopes";

const X: &[Param<'static>] = &[p("x")];
const AB: &[Param<'static>] = &[p("a"), p("b")];
const BIQUAD: &[Param<'static>] = &[p("x"), p("freq"), opt("q", std::f64::consts::FRAC_1_SQRT_2)];

/// Every built-in node. (`let` and the top-level forms are not nodes: see
/// `lower::forms`.)
pub static NODES: &[NodeSpec] = &[
    // Arithmetic and maths.
    NodeSpec::new("+", X, MATHS, Build::Fold(BinaryOp::Add)).variadic(),
    NodeSpec::new("*", X, MATHS, Build::Fold(BinaryOp::Mul)).variadic(),
    NodeSpec::new("-", X, MATHS, Build::Args(minus)).variadic(),
    NodeSpec::new("/", X, MATHS, Build::Args(divide)).variadic(),
    NodeSpec::new("min", X, MATHS, Build::Fold(BinaryOp::Min)).variadic(),
    NodeSpec::new("max", X, MATHS, Build::Fold(BinaryOp::Max)).variadic(),
    NodeSpec::new(
        "pow",
        &[p("base"), p("exponent")],
        MATHS,
        Build::Binary(BinaryOp::Pow),
    ),
    NodeSpec::new(
        "mod",
        &[p("x"), p("divisor")],
        MATHS,
        Build::Binary(BinaryOp::Mod),
    ),
    NodeSpec::new("exp", X, MATHS, Build::Unary(UnaryOp::Exp)),
    NodeSpec::new("log", X, MATHS, Build::Unary(UnaryOp::Log)),
    NodeSpec::new("sqrt", X, MATHS, Build::Unary(UnaryOp::Sqrt)),
    NodeSpec::new("abs", X, MATHS, Build::Unary(UnaryOp::Abs)),
    NodeSpec::new("sin", X, MATHS, Build::Unary(UnaryOp::Sin)),
    NodeSpec::new("cos", X, MATHS, Build::Unary(UnaryOp::Cos)),
    NodeSpec::new("tan", X, MATHS, Build::Unary(UnaryOp::Tan)),
    NodeSpec::new("tanh", X, MATHS, Build::Unary(UnaryOp::Tanh)),
    NodeSpec::new("floor", X, MATHS, Build::Unary(UnaryOp::Floor)),
    NodeSpec::new("frac", X, MATHS, Build::Unary(UnaryOp::Frac)),
    NodeSpec::new(
        "clamp",
        &[p("x"), p("lo"), p("hi")],
        MATHS,
        Build::Ternary(TernaryOp::Clamp),
    ),
    // Comparisons and logic.
    NodeSpec::new("<", AB, LOGIC, Build::Binary(BinaryOp::Lt)),
    NodeSpec::new(">", AB, LOGIC, Build::Binary(BinaryOp::Gt)),
    NodeSpec::new("<=", AB, LOGIC, Build::Binary(BinaryOp::Le)),
    NodeSpec::new(">=", AB, LOGIC, Build::Binary(BinaryOp::Ge)),
    NodeSpec::new("=", AB, LOGIC, Build::Binary(BinaryOp::Eq)),
    NodeSpec::new("!=", AB, LOGIC, Build::Binary(BinaryOp::Ne)),
    NodeSpec::new("and", X, LOGIC, Build::Fold(BinaryOp::And)).variadic(),
    NodeSpec::new("or", X, LOGIC, Build::Fold(BinaryOp::Or)).variadic(),
    NodeSpec::new("not", X, LOGIC, Build::Unary(UnaryOp::Not)),
    NodeSpec::new(
        "if",
        &[p("condition"), p("then"), p("else")],
        LOGIC,
        Build::Ternary(TernaryOp::If),
    ),
    // Waveforms.
    NodeSpec::new("sine", X, WAVES, Build::Unary(UnaryOp::Sine)),
    NodeSpec::new("sawtooth", X, WAVES, Build::Unary(UnaryOp::Sawtooth)),
    NodeSpec::new("square", X, WAVES, Build::Unary(UnaryOp::Square)),
    NodeSpec::new("triangle", X, WAVES, Build::Unary(UnaryOp::Triangle)),
    NodeSpec::new(
        "pulse",
        &[p("x"), opt("width", 0.5)],
        WAVES,
        Build::Binary(BinaryOp::Pulse),
    ),
    NodeSpec::new("damp", X, "`damp`", Build::Unary(UnaryOp::Damp)),
    NodeSpec::new("saw-bl", X, BAND_LIMITED, Build::Args(saw_bl)).stateful(),
    NodeSpec::new("square-bl", X, BAND_LIMITED, Build::Args(square_bl)).stateful(),
    NodeSpec::new("triangle-bl", X, BAND_LIMITED, Build::Args(triangle_bl)).stateful(),
    // Levels and pitches.
    NodeSpec::new("dbamp", &[p("db")], LEVELS, Build::Unary(UnaryOp::DbAmp)),
    NodeSpec::new("ampdb", &[p("amp")], LEVELS, Build::Unary(UnaryOp::AmpDb)),
    NodeSpec::new(
        "midihz",
        &[p("note")],
        LEVELS,
        Build::Unary(UnaryOp::MidiHz),
    ),
    NodeSpec::new("hzmidi", &[p("hz")], LEVELS, Build::Unary(UnaryOp::HzMidi)),
    // Noises.
    NodeSpec::new("noise", X, NOISES, Build::Args(noise)).random(),
    NodeSpec::new("white", &[], NOISES, Build::Args(white)).random(),
    NodeSpec::new("pink", &[], NOISES, Build::Args(pink))
        .random()
        .stateful(),
    NodeSpec::new("markov", &[p("rate")], NOISES, Build::Args(markov))
        .random()
        .stateful(),
    // Vector nodes.
    NodeSpec::new(
        "rvector",
        &[p("n"), p("lo"), p("hi")],
        VECTORS,
        Build::Args(rvector),
    )
    .random()
    .own_width(),
    NodeSpec::new("iota", &[p("n")], VECTORS, Build::Args(iota))
        .constant()
        .own_width(),
    NodeSpec::new("vector", X, VECTORS, Build::Args(vector))
        .variadic()
        .own_width(),
    NodeSpec::new("combine", X, VECTORS, Build::Args(combine)).own_width(),
    NodeSpec::new("lanes", X, VECTORS, Build::Args(lanes))
        .constant()
        .own_width(),
    NodeSpec::new("index", &[p("x"), p("i")], VECTORS, Build::Args(index)).own_width(),
    // Phase.
    NodeSpec::new(
        "phasor",
        &[p("freq"), opt("phase", 0.0)],
        "`phasor`",
        Build::Args(phasor),
    )
    .stateful(),
    // Filters.
    NodeSpec::new("lowpass", BIQUAD, FILTERS, Build::Args(lowpass)).stateful(),
    NodeSpec::new("highpass", BIQUAD, FILTERS, Build::Args(highpass)).stateful(),
    NodeSpec::new(
        "bandpass",
        &[p("x"), p("freq"), opt("q", 1.0)],
        FILTERS,
        Build::Args(bandpass),
    )
    .stateful(),
    NodeSpec::new(
        "onepole",
        &[p("x"), p("freq")],
        FILTERS,
        Build::Args(onepole),
    )
    .stateful(),
    NodeSpec::new(
        "resonator",
        &[p("x"), p("freq"), p("bandwidth")],
        FILTERS,
        Build::Args(resonator),
    )
    .stateful(),
    // Delays.
    NodeSpec::new(
        "delay",
        &[p("x"), p("time"), opt("max", 0.0)],
        DELAYS,
        Build::Args(delay),
    )
    .stateful(),
    NodeSpec::new(
        "comb",
        &[
            p("x"),
            p("delay"),
            p("feedback"),
            opt("damp", 0.0),
            opt("max", 0.0),
        ],
        DELAYS,
        Build::Args(comb),
    )
    .stateful(),
    NodeSpec::new(
        "allpass",
        &[p("x"), p("delay"), p("gain"), opt("max", 0.0)],
        DELAYS,
        Build::Args(allpass),
    )
    .stateful(),
    // Convolution and sampled sound (their first or second argument is a file).
    NodeSpec::new(
        "conv",
        &[p("input"), p("response"), opt("length", 1.0)],
        "`conv`",
        Build::Form(|l, call, origin, scope| l.lower_conv(call, origin, scope)),
    )
    .stateful()
    .own_width(),
    NodeSpec::new(
        "sample",
        &[
            p("file"),
            opt("rate", 1.0),
            opt("start", 0.0),
            opt("loop", 0.0),
        ],
        "`sample`",
        Build::Form(|l, call, origin, scope| l.lower_sample(call, origin, scope)),
    )
    .stateful()
    .own_width(),
    // Control.
    NodeSpec::new(
        "latch",
        &[p("x"), p("trigger")],
        CONTROL,
        Build::Args(latch),
    )
    .stateful(),
    NodeSpec::new("lag", &[p("x"), p("seconds")], CONTROL, Build::Args(lag)).stateful(),
    // Envelopes.
    NodeSpec::new(
        "env",
        &[
            p("x"),
            p("attack"),
            p("decay"),
            opt("hold", 0.0),
            opt("attack-curve", 0.0),
            opt("decay-curve", 0.0),
        ],
        ENVELOPES,
        Build::Args(env),
    ),
    NodeSpec::new(
        "adsr",
        &[
            p("gate"),
            p("attack"),
            p("decay"),
            p("sustain"),
            p("release"),
        ],
        ENVELOPES,
        Build::Args(adsr),
    )
    .stateful(),
];

// ------------------------------------------------------------------ builders
// Each receives its arguments bound and, for `Width::Broadcast`, width-checked.

fn minus(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let nodes = b.nodes();
    if let [x] = nodes[..] {
        return Ok(l.graph.add(Op::Unary(UnaryOp::Neg), vec![x]));
    }
    Ok(l.fold(BinaryOp::Sub, &nodes))
}

fn divide(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let nodes = b.nodes();
    if let [x] = nodes[..] {
        let one = l.graph.constant(1.0);
        return Ok(l.graph.add(Op::Binary(BinaryOp::Div), vec![one, x]));
    }
    Ok(l.fold(BinaryOp::Div, &nodes))
}

fn noise(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let seed = l.random_seed("noise", b.seed, &b.nodes());
    Ok(l.graph.add(Op::Noise { seed }, b.nodes()))
}

fn white(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let seed = l.random_seed("white", b.seed, &[]);
    Ok(l.graph.add(Op::White { seed }, vec![]))
}

fn pink(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let seed = l.random_seed("pink", b.seed, &[]);
    Ok(l.stateful(PinkNoise { seed }, vec![]))
}

fn markov(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let seed = l.random_seed("markov", b.seed, &b.nodes());
    Ok(l.stateful(MarkovNoise { seed }, b.nodes()))
}

fn rvector(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let all = &b.args;
    let n = l.const_count(&all[0], "the number of lanes", b.origin)?;
    let bounds_width = l.check_widths(b.call, &all[1..], b.origin)?;
    if bounds_width != 1 && bounds_width != n {
        let wide = all[1..]
            .iter()
            .find(|a| l.graph.width(a.node) != 1)
            .unwrap_or(&all[1]);
        return Err(l
            .diag(
                "timbre::width-mismatch",
                format!("`rvector` of {n} lanes with bounds of {bounds_width} lanes"),
                b.origin,
            )
            .label(wide.span, format!("{bounds_width} lanes"))
            .label(all[0].span, format!("{n} lanes"))
            .help("the bounds must be one lane, or one per lane of the vector"));
    }
    let seed = l.random_seed("rvector", b.seed, &b.nodes());
    let unit: Vec<f64> = (0..n as u64)
        .map(|i| (hash2(seed, i) >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
        .collect();
    // lo + (hi − lo)·u: folds to a constant vector when lo and hi are constants.
    let unit = l.graph.const_vector(unit);
    let (lo, hi) = (all[1].node, all[2].node);
    let range = l.graph.add(Op::Binary(BinaryOp::Sub), vec![hi, lo]);
    let scaled = l.graph.add(Op::Binary(BinaryOp::Mul), vec![range, unit]);
    Ok(l.graph.add(Op::Binary(BinaryOp::Add), vec![lo, scaled]))
}

fn iota(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let n = l.const_count(&b.args[0], "the number of lanes", b.origin)?;
    Ok(l.graph.const_vector((0..n).map(|i| i as f64).collect()))
}

fn vector(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let nodes = b.nodes();
    let total: usize = nodes.iter().map(|n| l.graph.width(*n)).sum();
    if total > MAX_LANES {
        return Err(l.too_wide(b.call.span, total, b.origin));
    }
    Ok(l.graph.add(Op::Concat, nodes))
}

fn combine(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.graph.add(Op::Combine, b.nodes()))
}

fn lanes(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let w = l.graph.width(b.args[0].node);
    Ok(l.graph.constant(w as f64))
}

fn index(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    l.check_one_lane(&b.args[1], "the lane index", b.origin)?;
    Ok(l.graph.add(Op::Index, b.nodes()))
}

fn phasor(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.graph.add(Op::Phasor, b.nodes()))
}

fn env(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.graph.add(Op::Env, b.nodes()))
}

fn lowpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let kind = BiquadKind::Lowpass;
    Ok(l.stateful(Biquad { kind }, b.nodes()))
}

fn highpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let kind = BiquadKind::Highpass;
    Ok(l.stateful(Biquad { kind }, b.nodes()))
}

fn bandpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let kind = BiquadKind::Bandpass;
    Ok(l.stateful(Biquad { kind }, b.nodes()))
}

fn onepole(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(OnePoleLowpass, b.nodes()))
}

fn resonator(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Resonator, b.nodes()))
}

fn adsr(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(AdsrEnvelope, b.nodes()))
}

fn latch(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Latch, b.nodes()))
}

fn lag(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(Lag, b.nodes()))
}

fn saw_bl(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(BandLimited { wave: Wave::Saw }, b.nodes()))
}

fn square_bl(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    Ok(l.stateful(BandLimited { wave: Wave::Square }, b.nodes()))
}

fn triangle_bl(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let wave = Wave::Triangle;
    Ok(l.stateful(BandLimited { wave }, b.nodes()))
}

fn delay(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let max_seconds = max_delay(l, b, 1, 2)?;
    Ok(l.stateful(Delay { max_seconds }, b.nodes()[..2].to_vec()))
}

fn comb(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let max_seconds = max_delay(l, b, 1, 4)?;
    Ok(l.stateful(Comb { max_seconds }, b.nodes()[..4].to_vec()))
}

fn allpass(l: &mut Lowerer<'_>, b: &Bound<'_>) -> Result<NodeId, Diag> {
    let max_seconds = max_delay(l, b, 1, 3)?;
    Ok(l.stateful(Allpass { max_seconds }, b.nodes()[..3].to_vec()))
}

/// The longest delay of a delay line, in seconds: the `max` argument (at `max`) if
/// given, else the longest of a constant delay time (at `time`).
fn max_delay(l: &Lowerer<'_>, b: &Bound<'_>, time: usize, max: usize) -> Result<f64, Diag> {
    let (time, max) = (&b.args[time], &b.args[max]);
    let seconds = match (max.given, l.graph.const_value(time.node)) {
        (true, _) => l.const_number(max, "the maximum delay", b.origin)?,
        (false, Some(times)) => times.iter().copied().fold(0.0, f64::max),
        (false, None) => {
            return Err(l
                .diag(
                    "timbre::delay-needs-max",
                    "a varying delay time needs a maximum",
                    b.origin,
                )
                .label(time.span, "this delay time changes")
                .help(format!(
                    "give the longest delay in seconds: (… :max 0.5), e.g. ({} x time 0.5)",
                    b.call.name
                )))
        }
    };
    if !(0.0..=MAX_BUFFER_SECONDS).contains(&seconds) {
        let span = if max.given { max.span } else { time.span };
        return Err(l
            .diag(
                "timbre::bad-delay",
                format!("maximum delay {seconds} s is out of range"),
                b.origin,
            )
            .label(span, "out of range")
            .help(format!("delays may be 0 to {MAX_BUFFER_SECONDS} seconds")));
    }
    Ok(seconds)
}

impl Lowerer<'_> {
    /// A stateful kernel's node.
    fn stateful(
        &mut self,
        kernel: impl crate::kernel::StatefulKernel,
        args: Vec<NodeId>,
    ) -> NodeId {
        self.graph.add(Op::Stateful(Arc::new(kernel)), args)
    }

    fn fold(&mut self, op: BinaryOp, nodes: &[NodeId]) -> NodeId {
        let mut acc = nodes[0];
        for next in &nodes[1..] {
            acc = self.graph.add(Op::Binary(op), vec![acc, *next]);
        }
        acc
    }
}
